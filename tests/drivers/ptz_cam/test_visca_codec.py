"""Golden bytes from the fact sheet (shared/protocols/visca_snc_rz50.md) and codec properties."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.ptz_cam import visca as v
from drivers.ptz_cam.errors import (
    BufferFullError,
    CommandCancelledError,
    MessageLengthError,
    NoSocketError,
    NotExecutableError,
    SyntaxReplyError,
    UnknownReplyError,
    ViscaConfigError,
    ViscaError,
    ViscaProtocolError,
)

H = bytes.fromhex

# (builder call, exact bytes) -- every row is a line of the fact sheet's tables 1.3, 1.5, 1.6
GOLDEN_REQUESTS = [
    (lambda: v.address_set(), "88 30 01 FF"),
    (lambda: v.if_clear_broadcast(), "88 01 00 01 FF"),
    (lambda: v.if_clear(), "81 01 00 01 FF"),
    (lambda: v.version_inquiry(), "81 09 00 02 FF"),
    (lambda: v.pan_tilt_drive(v.PanDirection.STOP, v.TiltDirection.UP, 0x18, 0x14), "81 01 06 01 18 14 03 01 FF"),
    (lambda: v.pan_tilt_drive(v.PanDirection.STOP, v.TiltDirection.DOWN, 1, 5), "81 01 06 01 01 05 03 02 FF"),
    (lambda: v.pan_tilt_drive(v.PanDirection.LEFT, v.TiltDirection.STOP, 7, 1), "81 01 06 01 07 01 01 03 FF"),
    (lambda: v.pan_tilt_drive(v.PanDirection.RIGHT, v.TiltDirection.STOP, 7, 1), "81 01 06 01 07 01 02 03 FF"),
    (lambda: v.pan_tilt_drive(v.PanDirection.LEFT, v.TiltDirection.UP, 2, 3), "81 01 06 01 02 03 01 01 FF"),
    (lambda: v.pan_tilt_drive(v.PanDirection.RIGHT, v.TiltDirection.UP, 2, 3), "81 01 06 01 02 03 02 01 FF"),
    (lambda: v.pan_tilt_drive(v.PanDirection.LEFT, v.TiltDirection.DOWN, 2, 3), "81 01 06 01 02 03 01 02 FF"),
    (lambda: v.pan_tilt_drive(v.PanDirection.RIGHT, v.TiltDirection.DOWN, 2, 3), "81 01 06 01 02 03 02 02 FF"),
    (lambda: v.pan_tilt_stop(), "81 01 06 01 01 01 03 03 FF"),
    # +90 deg at 14.4 counts/deg = 1296 = 0x0510; -30 deg = -432 = 0xFE50 (fact sheet 1.6)
    (lambda: v.pan_tilt_absolute(1296, -432, 0x18, 0x14), "81 01 06 02 18 14 00 05 01 00 0F 0E 05 00 FF"),
    (lambda: v.pan_tilt_relative(-432, 1296, 1, 1), "81 01 06 03 01 01 0F 0E 05 00 00 05 01 00 FF"),
    (lambda: v.pan_tilt_absolute(2448, -2448), "81 01 06 02 18 14 00 09 09 00 0F 06 07 00 FF"),
    (lambda: v.pan_tilt_home(), "81 01 06 04 FF"),
    (lambda: v.pan_tilt_reset(), "81 01 06 05 FF"),
    (lambda: v.auto_pan_tilt_speed(True), "81 01 06 24 02 FF"),
    (lambda: v.auto_pan_tilt_speed(False), "81 01 06 24 03 FF"),
    (lambda: v.zoom_stop(), "81 01 04 07 00 FF"),
    (lambda: v.zoom_tele(), "81 01 04 07 02 FF"),
    (lambda: v.zoom_wide(), "81 01 04 07 03 FF"),
    (lambda: v.zoom_tele(speed=0), "81 01 04 07 20 FF"),
    (lambda: v.zoom_tele(speed=7), "81 01 04 07 27 FF"),
    (lambda: v.zoom_wide(speed=4), "81 01 04 07 34 FF"),
    (lambda: v.zoom_direct(0x4000), "81 01 04 47 04 00 00 00 FF"),
    (lambda: v.zoom_direct(0x213B), "81 01 04 47 02 01 03 0B FF"),
    (lambda: v.digital_zoom(True), "81 01 04 06 02 FF"),
    (lambda: v.digital_zoom(False), "81 01 04 06 03 FF"),
    (lambda: v.focus_auto(), "81 01 04 38 02 FF"),
    (lambda: v.focus_manual(), "81 01 04 38 03 FF"),
    (lambda: v.focus_one_push(), "81 01 04 18 01 FF"),
    (lambda: v.power(True), "81 01 04 00 02 FF"),
    (lambda: v.power(False), "81 01 04 00 03 FF"),
    (lambda: v.command_cancel(1), "81 21 FF"),
    (lambda: v.command_cancel(2), "81 22 FF"),
    (lambda: v.pan_tilt_position_inquiry(), "81 09 06 12 FF"),
    (lambda: v.pan_tilt_max_speed_inquiry(), "81 09 06 11 FF"),
    (lambda: v.zoom_position_inquiry(), "81 09 04 47 FF"),
    (lambda: v.focus_mode_inquiry(), "81 09 04 38 FF"),
    (lambda: v.power_inquiry(), "81 09 04 00 FF"),
    (lambda: v.digital_zoom_inquiry(), "81 09 04 06 FF"),
]


@pytest.mark.parametrize(("build", "expected"), GOLDEN_REQUESTS)
def test_request_bytes_match_the_fact_sheet(build, expected: str) -> None:
    req = build()
    assert req.packet == H(expected)
    assert 3 <= len(req.packet) <= 16 and req.packet[-1] == 0xFF and 0xFF not in req.packet[:-1]


def test_position_examples_encode_and_decode() -> None:
    assert v.nibbles(1296, 4) == H("00 05 01 00")  # +90 deg
    assert v.nibbles(-432, 4) == H("0F 0E 05 00")  # -30 deg
    assert v.from_nibbles(H("00 05 01 00"), signed=True) == 1296
    assert v.from_nibbles(H("0F 0E 05 00"), signed=True) == -432
    ans = v.parse_packet(H("90 50 00 05 01 00 0F 0E 05 00 FF"))
    assert isinstance(ans, v.InquiryAnswer)
    pos = v.decode_pan_tilt_position(ans)
    assert (pos.pan_counts, pos.tilt_counts, pos.layout) == (1296, -432, v.PanTiltLayout.FOUR_FOUR)


def test_both_position_layouts_are_told_apart_by_length() -> None:
    # libvisca's bug: reading the 4+4 answer as 5+4 turns (800, -200) into (12815, -3185)
    four = v.parse_packet(H("90 50 00 03 02 00 0F 0F 03 08 FF"))
    five = v.parse_packet(H("90 50 00 00 03 02 00 0F 0F 03 08 FF"))
    assert isinstance(four, v.InquiryAnswer) and isinstance(five, v.InquiryAnswer)
    assert v.decode_pan_tilt_position(four) == v.PanTiltPosition(800, -200, v.PanTiltLayout.FOUR_FOUR)
    assert v.decode_pan_tilt_position(five) == v.PanTiltPosition(800, -200, v.PanTiltLayout.FIVE_FOUR)
    neg5 = v.parse_packet(H("90 50 0F 0F 0C 0E 00 00 00 0C 08 FF"))  # (-800, 200) in 5+4
    assert isinstance(neg5, v.InquiryAnswer)
    assert v.decode_pan_tilt_position(neg5) == v.PanTiltPosition(-800, 200, v.PanTiltLayout.FIVE_FOUR)


@pytest.mark.parametrize("bad", ["90 50 00 03 02 10 0F 0F 03 08 FF", "90 50 00 03 02 FF", "90 50 01 02 03 FF"])
def test_bad_position_answers_raise_protocol_errors(bad: str) -> None:
    events = v.ViscaParser().feed(H(bad))
    answers = [e for e in events if isinstance(e, v.InquiryAnswer)]
    for a in answers:
        with pytest.raises(ViscaProtocolError):
            v.decode_pan_tilt_position(a)


def test_other_inquiry_answers_decode() -> None:
    def ans(hexs: str) -> v.InquiryAnswer:
        a = v.parse_packet(H(hexs))
        assert isinstance(a, v.InquiryAnswer)
        return a

    assert v.decode_max_speed(ans("90 50 18 14 FF")) == v.MaxSpeed(0x18, 0x14)
    assert v.decode_zoom_position(ans("90 50 04 00 00 00 FF")) == 0x4000
    assert v.decode_focus_mode(ans("90 50 02 FF")) is v.FocusMode.AUTO
    assert v.decode_focus_mode(ans("90 50 03 FF")) is v.FocusMode.MANUAL
    assert v.decode_focus_mode(ans("90 50 07 FF")) is v.FocusMode.UNKNOWN
    assert v.decode_power(ans("90 50 02 FF")) is v.PowerState.ON
    assert v.decode_power(ans("90 50 03 FF")) is v.PowerState.OFF
    assert v.decode_power(ans("90 50 04 FF")) is v.PowerState.UNKNOWN
    assert v.decode_on_off(ans("90 50 03 FF")) is False
    assert v.decode_version(ans("90 50 00 20 05 10 01 00 02 FF")) == v.Version(0x0020, 0x0510, 0x0100, 2)
    with pytest.raises(ViscaProtocolError):
        v.decode_zoom_position(ans("90 50 02 FF"))  # a focus answer is not a zoom answer
    with pytest.raises(ViscaProtocolError):
        v.decode_version(ans("90 50 00 20 05 10 01 00 FF"))


REPLIES = [
    ("90 41 FF", v.Ack(1, 1, H("90 41 FF"))),
    ("90 42 FF", v.Ack(1, 2, H("90 42 FF"))),
    ("90 51 FF", v.Completion(1, 1, H("90 51 FF"))),
    ("90 52 FF", v.Completion(1, 2, H("90 52 FF"))),
    ("90 50 FF", v.Completion(1, 0, H("90 50 FF"))),  # addressed IF_Clear's reply
    ("88 30 02 FF", v.AddressSetReply(2, H("88 30 02 FF"))),
    ("88 01 00 01 FF", v.IfClearEcho(H("88 01 00 01 FF"))),
    ("90 38 FF", v.NetworkChange(1, H("90 38 FF"))),
]


@pytest.mark.parametrize(("hexs", "event"), REPLIES)
def test_reply_packets_parse(hexs: str, event: v.Event) -> None:
    assert v.ViscaParser().feed(H(hexs)) == [event]


ERRORS = [
    ("90 60 01 FF", 0, v.ErrorCode.MESSAGE_LENGTH, MessageLengthError),
    ("90 60 02 FF", 0, v.ErrorCode.SYNTAX, SyntaxReplyError),
    ("90 60 03 FF", 0, v.ErrorCode.BUFFER_FULL, BufferFullError),
    ("90 61 04 FF", 1, v.ErrorCode.CANCELLED, CommandCancelledError),
    ("90 62 04 FF", 2, v.ErrorCode.CANCELLED, CommandCancelledError),
    ("90 61 05 FF", 1, v.ErrorCode.NO_SOCKET, NoSocketError),
    ("90 62 41 FF", 2, v.ErrorCode.NOT_EXECUTABLE, NotExecutableError),
    ("90 61 41 FF", 1, v.ErrorCode.NOT_EXECUTABLE, NotExecutableError),
    ("90 61 77 FF", 1, v.ErrorCode.UNKNOWN, UnknownReplyError),
]


@pytest.mark.parametrize(("hexs", "socket", "code", "exc"), ERRORS)
def test_every_error_reply_keeps_its_socket(hexs: str, socket: int, code: v.ErrorCode, exc: type) -> None:
    (ev,) = v.ViscaParser().feed(H(hexs))
    assert isinstance(ev, v.ErrorReply)
    assert (ev.socket, ev.code) == (socket, code)
    err = ev.to_exception("x")
    assert isinstance(err, exc) and isinstance(err, ViscaError)
    assert err.socket == socket and err.raw == H(hexs) and err.code == hexs.split()[2]


def test_resync_after_garbage() -> None:
    p = v.ViscaParser()
    events = p.feed(H("12 34 90 41 FF 00 FF 90 51 FF"))
    kinds = [type(e).__name__ for e in events]
    assert kinds == ["Discarded", "Ack", "Discarded", "Completion"]
    # 20 bytes without a terminator, then a good reply
    events = p.feed(bytes(range(1, 21)) + H("90 42 FF"))
    assert isinstance(events[-1], v.Ack) and events[-1].socket == 2
    assert sum(len(e.raw) for e in events if isinstance(e, v.Discarded)) == 20
    assert p.pending == 0


def test_split_feeding_gives_the_same_events() -> None:
    stream = H("90 41 FF 90 50 00 05 01 00 0F 0E 05 00 FF 90 61 41 FF 88 30 02 FF")
    whole = v.ViscaParser().feed(stream)
    p = v.ViscaParser()
    pieces = [e for b in stream for e in p.feed(bytes([b]))]
    assert pieces == whole and len(whole) == 4


@pytest.mark.parametrize(
    "build",
    [
        lambda: v.pan_tilt_drive(v.PanDirection.STOP, v.TiltDirection.UP, 0, 5),  # speed 0 on the idle axis
        lambda: v.pan_tilt_stop(0, 0),
        lambda: v.pan_tilt_drive(v.PanDirection.LEFT, v.TiltDirection.STOP, 0x19, 1),
        lambda: v.pan_tilt_absolute(0, 0, 1, 0x15),
        lambda: v.pan_tilt_absolute(0x8000, 0),
        lambda: v.zoom_direct(-1),
        lambda: v.zoom_direct(0x10000),
        lambda: v.zoom_tele(speed=8),
        lambda: v.command_cancel(0),
        lambda: v.if_clear(8),
        lambda: v.pan_tilt_absolute(1.5, 0),  # type: ignore[arg-type]
    ],
)
def test_illegal_parameters_raise_before_sending(build) -> None:
    with pytest.raises(ViscaConfigError):
        build()


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=40), max_size=12))
def test_arbitrary_bytes_never_raise_and_decoders_raise_only_typed_errors(chunks: list[bytes]) -> None:
    p = v.ViscaParser()
    for chunk in chunks:
        for ev in p.feed(chunk):
            assert 3 <= len(ev.raw) <= 16 or isinstance(ev, v.Discarded)
            if isinstance(ev, v.InquiryAnswer):
                for decode in (v.decode_pan_tilt_position, v.decode_max_speed, v.decode_zoom_position,
                               v.decode_focus_mode, v.decode_power, v.decode_version, v.decode_on_off):
                    try:
                        decode(ev)
                    except ViscaProtocolError:
                        pass
            if isinstance(ev, v.ErrorReply):
                assert isinstance(ev.to_exception(), ViscaError)
    assert p.pending < 16


@settings(max_examples=200, deadline=None)
@given(st.integers(-0x8000, 0x7FFF), st.integers(-0x8000, 0x7FFF), st.binary(max_size=20))
def test_positions_round_trip_through_garbage(pan: int, tilt: int, junk: bytes) -> None:
    answer = b"\x90\x50" + v.nibbles(pan, 4) + v.nibbles(tilt, 4) + b"\xff"
    events = v.ViscaParser().feed(junk.replace(b"\xff", b"") + b"\xff" + answer)
    answers = [e for e in events if isinstance(e, v.InquiryAnswer)]
    assert answers and v.decode_pan_tilt_position(answers[-1]) == v.PanTiltPosition(pan, tilt,
                                                                                      v.PanTiltLayout.FOUR_FOUR)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=64), st.sampled_from(["inquiry", "command", "cancel", "if_clear", "none"]))
def test_client_reply_matching_survives_arbitrary_bytes(data: bytes, pending_kind: str) -> None:
    """Whatever the camera sends, matching only settles requests with typed results or errors."""
    from drivers.ptz_cam.client import CommandHandle, ViscaClient, _Pending

    client = ViscaClient("socket://127.0.0.1:9")  # never opened: the matcher is exercised alone
    requests = {"inquiry": v.zoom_position_inquiry(), "command": v.pan_tilt_home(), "cancel": v.command_cancel(1),
                "if_clear": v.if_clear()}
    slot = _Pending(requests[pending_kind]) if pending_kind in requests else None
    client._pending = slot
    held = CommandHandle(v.zoom_direct(0x1000), 1, 0.0, 1.0)
    client._sockets[1] = held
    client._dispatch(v.ViscaParser().feed(data))
    if slot is not None and slot.done:
        assert slot.error is None or isinstance(slot.error, ViscaError)
        if slot.error is None:
            assert slot.result is not None
    if held.done:
        try:
            held.wait(0)
        except ViscaError:
            pass


# issue 12 row 6: an unterminated fragment must not swallow the next reply
@pytest.mark.parametrize(
    ("stream", "expected"),
    [
        ("90 50 90 51 FF", v.Completion(1, 1, bytes.fromhex("9051FF"))),
        ("90 50 90 61 41 FF", v.ErrorReply(1, 1, v.ErrorCode(0x41), 0x41, bytes.fromhex("906141FF"))),
        ("90 42 90 41 FF", v.Ack(1, 1, bytes.fromhex("9041FF"))),
    ],
)
def test_a_reply_after_an_unterminated_fragment_is_kept(stream: str, expected: v.Event) -> None:
    events = v.ViscaParser().feed(bytes.fromhex(stream))
    assert events[-1] == expected
    assert all(isinstance(e, v.Discarded) for e in events[:-1]) and events[:-1]


def test_a_high_byte_inside_a_reply_body_is_a_new_header() -> None:
    assert v.parse_packet(bytes.fromhex("9050905000FF")) is None
    assert v.parse_packet(bytes.fromhex("905002FF")) == v.InquiryAnswer(1, b"\x02", bytes.fromhex("905002FF"))
