"""The ARCOS codec against the fact sheet's golden frames, edge cases and random input."""

from __future__ import annotations

import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivers.errors import ChecksumError, ProtocolError
from drivers.p2os import codec
from drivers.p2os.codec import (
    ArcosDecoder,
    BadFrame,
    BadFrameKind,
    ConfigPacket,
    Deframer,
    EncoderPacket,
    RawFrame,
    ResetPacket,
    RobotIdentity,
    Sip,
    SyncEcho,
)
from drivers.p2os.errors import ArcosChecksumError, ArcosConfigError, ArcosError, ArcosProtocolError

H = bytes.fromhex

# fact sheet section 1.2, "Worked frames"
GOLDEN_COMMANDS = [
    (codec.sync_command(0), "FA FB 03 00 00 00"),
    (codec.pulse_command(), "FA FB 03 00 00 00"),
    (codec.sync_command(1), "FA FB 03 01 00 01"),
    (codec.open_command(), "FA FB 03 01 00 01"),
    (codec.sync_command(2), "FA FB 03 02 00 02"),
    (codec.close_command(), "FA FB 03 02 00 02"),
    (codec.enable_command(True), "FA FB 06 04 3B 01 00 05 3B"),
    (codec.vel_command(200), "FA FB 06 0B 3B C8 00 D3 3B"),
    (codec.vel_command(-200), "FA FB 06 0B 1B C8 00 D3 1B"),
    (codec.rvel_command(-10), "FA FB 06 15 1B 0A 00 1F 1B"),
    (codec.setv_command(400), "FA FB 06 06 3B 90 01 96 3C"),
    (codec.seta_command(-300), "FA FB 06 05 1B 2C 01 31 1C"),
    (codec.head_command(90), "FA FB 06 0C 3B 5A 00 66 3B"),
    (codec.seto_command(), "FA FB 03 07 00 07"),
    (codec.e_stop_command(), "FA FB 03 37 00 37"),
    (codec.config_command(), "FA FB 06 12 3B 01 00 13 3B"),
    (codec.encoder_command(2), "FA FB 06 13 3B 02 00 15 3B"),
    (codec.sonar_command(False), "FA FB 06 1C 3B 00 00 1C 3B"),
    (codec.vel2_command(-100, 100), "FA FB 06 20 1B FB 04 1B 1F"),
]

SYNC2_REPLY = H("FA FB 18 02 41 4D 52 49 53 69 6D 00 50 69 6F 6E 65 65 72 00 70 33 64 78 00 EB BD")

# fact sheet 1.6, "Real bytes from AMRISim" (stationary p3dx, all 16 sonars, payload 84 bytes)
AMRISIM_SIP_PAYLOAD = (
    H("32 0000 0000 0000 0000 0000 82 0000 0000 1f00 00 10")
    + b"".join(bytes((i, 0x88, 0x13)) for i in range(16))
    + H("00 00 00 ff ff 8200 00 0000 0000 0000 81 00")
)


@pytest.mark.parametrize(("built", "expected"), GOLDEN_COMMANDS)
def test_command_builders_match_the_worked_frames(built: bytes, expected: str) -> None:
    assert built == H(expected)


@pytest.mark.parametrize(("built", "expected"), GOLDEN_COMMANDS)
def test_worked_frames_deframe_with_their_checksum(built: bytes, expected: str) -> None:
    items = Deframer().feed(H(expected))
    assert len(items) == 1 and isinstance(items[0], RawFrame)
    assert codec.frame(items[0].payload) == H(expected)


def test_sync2_reply_decodes_to_the_three_strings() -> None:
    events = ArcosDecoder().feed(SYNC2_REPLY)
    assert events == [RobotIdentity(name="AMRISim", robot_class="Pioneer", subclass="p3dx", complete=True)]
    assert codec.frame(SYNC2_REPLY[3:-2]) == SYNC2_REPLY


def test_recorded_amrisim_sip_decodes_every_field() -> None:
    assert len(AMRISIM_SIP_PAYLOAD) == 84
    wire = codec.frame(AMRISIM_SIP_PAYLOAD)
    assert wire[2] == 86
    (sip,) = ArcosDecoder().feed(wire)
    assert isinstance(sip, Sip)
    assert (sip.packet_type, sip.x_raw, sip.y_raw, sip.th_raw) == (0x32, 0, 0, 0)
    assert sip.battery_dv == 130 and sip.flags == 0x1F and sip.motors_enabled
    assert sip.sonar_arrays_enabled == 0x0F
    assert [(s.index, s.range_raw) for s in sip.sonars] == [(i, 5000) for i in range(16)]
    assert (sip.grip_state, sip.anport, sip.analog, sip.digin, sip.digout) == (0, 0, 0, 0xFF, 0xFF)
    assert sip.battery_x10_dv == 130 and sip.charge_state == 0
    assert sip.rotvel_decidegps == 0 and sip.fault_flags == 0 and sip.latvel_raw == 0
    assert sip.temperature_c == -127 and sip.state_of_charge == 0
    assert sip.uc_time_ms is None and sip.flags3 is None and sip.extra == b""


@pytest.mark.parametrize(
    ("tail_len", "present", "absent"),
    [
        (0, [], ["grip_state"]),
        (5, ["grip_state", "digout"], ["battery_x10_dv"]),
        (6, ["digout"], ["battery_x10_dv"]),  # half a field: not parsed
        (7, ["battery_x10_dv"], ["charge_state"]),
        (12, ["fault_flags"], ["latvel_raw"]),
        (16, ["state_of_charge"], ["uc_time_ms"]),
    ],
)
def test_optional_sip_tail_fields_only_when_present(tail_len: int, present: list[str], absent: list[str]) -> None:
    full_tail = AMRISIM_SIP_PAYLOAD[20 + 48 :]
    payload = AMRISIM_SIP_PAYLOAD[: 20 + 48] + full_tail[:tail_len]
    sip = codec.decode_sip(payload)
    for name in present:
        assert getattr(sip, name) is not None, name
    for name in absent:
        assert getattr(sip, name) is None, name


def test_sip_signedness_and_15_bit_position() -> None:
    payload = struct.pack("<BHHhhhBHhHBB", 0x33, 0xFFFF, 0x8001, -5, -231, 168, 125, 0x0301, -100, 0x21, 90, 0)
    sip = codec.decode_sip(payload + bytes(5) + struct.pack("<HBhH", 125, 0, -100, 2))
    assert sip.x_raw == 0x7FFF and sip.y_raw == 1  # only the low 15 bits are valid
    assert sip.th_raw == -5 and sip.left_vel_raw == -231 and sip.right_vel_raw == 168
    assert sip.control_raw == -100 and sip.rotvel_decidegps == -100 and sip.fault_flags == 2
    assert sip.left_stall and sip.right_stall and sip.front_bumpers == 1 and sip.rear_bumpers == 0
    assert sip.estop_pressed and sip.motors_enabled


def test_sip_with_more_sonar_readings_than_bytes_is_a_payload_error() -> None:
    payload = AMRISIM_SIP_PAYLOAD[:19] + bytes((30,)) + AMRISIM_SIP_PAYLOAD[20:]  # 90 bytes claimed, 64 left
    with pytest.raises(ProtocolError):
        codec.decode_sip(payload)
    (ev,) = ArcosDecoder().feed(codec.frame(payload))
    assert isinstance(ev, BadFrame) and ev.kind is BadFrameKind.PAYLOAD


@pytest.mark.parametrize(
    "payload",
    [
        b"\x01",  # odd, 1 byte
        b"\x00\x00",
        bytes(range(0x80, 0xFF)),  # N >= 128 and large sums
        b"\xff" * 200,  # sum wraps past 0x8000 many times
        b"\xff" * 251,  # the largest legal payload, odd length
    ],
)
def test_checksum_roundtrip_for_odd_even_long_and_high_sums(payload: bytes) -> None:
    wire = codec.frame(payload)
    assert wire[2] == len(payload) + 2
    items = Deframer().feed(wire)
    assert items == [RawFrame(payload)]


def test_checksum_by_hand() -> None:
    # pairs 0x0102 + 0x0304, odd trailing 0x05 XORed into the low byte
    assert codec.checksum(b"\x01\x02\x03\x04\x05") == (0x0102 + 0x0304) ^ 0x05
    assert codec.checksum(b"\xff\xff\xff\xff") == (0xFFFF + 0xFFFF) & 0xFFFF


def test_config_packet_with_count_above_127_is_accepted() -> None:
    # a real P3DX-SH CONFIGpac has N = 137 (AriaCoda#15: a signed count broke ARIA's checksum)
    body = b"\x20Pioneer\x00p3dx-sh\x00GJC_3156\x00\x00" + struct.pack("<HHHHH", 360, 1000, 300, 2000, 500)
    body += b"FAPESP_3156\x00" + bytes((100, 0, 0))
    body += bytes(135 - len(body))
    wire = codec.frame(body)
    assert wire[2] == 137
    (ev,) = ArcosDecoder().feed(wire)
    assert isinstance(ev, ConfigPacket)
    assert ev.values["robot_subclass"] == "p3dx-sh" and ev.values["serial_number"] == "GJC_3156"
    assert ev.values["rot_vel_top_degps"] == 360 and ev.values["trans_vel_top_mmps"] == 1000
    assert ev.values["name"] == "FAPESP_3156" and ev.values["sip_cycle_ms"] == 100 and ev.values["host_baud"] == 0


def test_short_config_is_parsed_as_far_as_it_goes() -> None:
    body = b"\x20Pioneer\x00p3dx\x00SIM\x00\x00" + struct.pack("<HHHHH", 9999, 9999, 9999, 9999, 400) + b"AMRISim\x00"
    cfg = codec.decode_config(body + bytes((100,)))
    assert cfg.values["name"] == "AMRISim" and cfg.values["sip_cycle_ms"] == 100 and "host_baud" not in cfg.values


def test_encoder_reset_unknown_and_sync_echo_packets() -> None:
    wire = (
        codec.frame(struct.pack("<Bii", 0x90, -5, 70000))
        + codec.frame(b"\xff")
        + codec.frame(b"\xfe")
        + codec.frame(b"\xf8\x01\x02")
        + codec.frame(b"\x00")
        + codec.frame(b"\x01")
    )
    assert ArcosDecoder().feed(wire) == [
        EncoderPacket(-5, 70000),
        ResetPacket(0xFF),
        ResetPacket(0xFE),
        codec.UnknownPacket(0xF8, b"\xf8\x01\x02"),
        SyncEcho(0),
        SyncEcho(1),
    ]


def test_io_packet_layout_and_truncation() -> None:
    payload = b"\xf0" + b"\x01\x0f" + b"\x01\xf0" + b"\x02" + struct.pack("<HH", 512, 1023)
    (ev,) = ArcosDecoder().feed(codec.frame(payload))
    assert ev == codec.IoPacket(digital_in=b"\x0f", digital_out=b"\xf0", analog_raw=(512, 1023))
    with pytest.raises(ArcosProtocolError):
        codec.decode_io(payload[:-1])
    assert codec.io_request_command(2) == codec.int_command(codec.Command.IOREQUEST, 2)


def test_truncated_sync2_strings_are_flagged() -> None:
    (ev,) = ArcosDecoder().feed(codec.frame(b"\x02robot\x00Pion"))
    assert ev == RobotIdentity(name="robot", robot_class="Pion", subclass="", complete=False)
    (ev,) = ArcosDecoder().feed(codec.frame(b"\x02"))
    assert ev == RobotIdentity("", "", "", complete=False)


def test_split_frames_are_reassembled_byte_by_byte() -> None:
    wire = codec.frame(AMRISIM_SIP_PAYLOAD) + SYNC2_REPLY
    dec = ArcosDecoder()
    events = []
    for b in wire:
        events += dec.feed(bytes((b,)))
    assert [type(e) for e in events] == [Sip, RobotIdentity]
    assert dec.pending == 0


def test_aria_junk_pattern_does_not_cost_the_next_sip() -> None:
    # fact sheet 2.1: ARIA lost the SIP after "00 FA 13 FA FB 05 j u n k"; we must not
    sip = codec.frame(AMRISIM_SIP_PAYLOAD)
    junk = b"\x00\xfa\x13\xfa\xfb\x05junk"
    dec = ArcosDecoder()
    events = dec.feed((junk + sip) * 7)
    assert sum(isinstance(e, Sip) for e in events) == 7
    assert dec.deframer.stats.checksum_errors == 7


def test_overlapping_header_fa_fa_fb() -> None:
    sip = codec.frame(AMRISIM_SIP_PAYLOAD)
    events = ArcosDecoder().feed(b"\xfa" + sip)
    assert [type(e) for e in events] == [Sip]


def test_bad_count_skips_only_the_header() -> None:
    sip = codec.frame(AMRISIM_SIP_PAYLOAD)
    events = ArcosDecoder().feed(b"\xfa\xfb\x01" + sip)
    assert [type(e) for e in events] == [BadFrame, Sip]
    assert events[0].kind is BadFrameKind.COUNT  # type: ignore[union-attr]


def test_junk_header_with_a_large_count_is_expired_by_the_caller() -> None:
    sip = codec.frame(AMRISIM_SIP_PAYLOAD)
    dec = ArcosDecoder()
    assert dec.feed(b"\xfa\xfb\xff" + sip) == []  # waiting for 258 bytes
    events = dec.expire_partial()
    assert [type(e) for e in events] == [BadFrame, Sip]
    assert events[0].kind is BadFrameKind.TRUNCATED  # type: ignore[union-attr]


def test_corrupted_frame_is_reported_and_next_frame_kept() -> None:
    sip = bytearray(codec.frame(AMRISIM_SIP_PAYLOAD))
    sip[30] ^= 0x01
    events = ArcosDecoder().feed(bytes(sip) + SYNC2_REPLY)
    assert [type(e) for e in events] == [BadFrame, RobotIdentity]
    assert events[0].kind is BadFrameKind.CHECKSUM  # type: ignore[union-attr]


@pytest.mark.parametrize("value", [32768, -32768, 1.5, True])
def test_int_arguments_out_of_range_are_refused(value: object) -> None:
    with pytest.raises(ArcosConfigError):
        codec.int_command(codec.Command.VEL, value)  # type: ignore[arg-type]


def test_velocity_builders_clamp_to_int16_and_round() -> None:
    assert codec.vel_command(1e9) == codec.int_command(codec.Command.VEL, 32767)
    assert codec.vel_command(-1e9) == codec.int_command(codec.Command.VEL, -32767)
    assert codec.rvel_command(9.6) == codec.int_command(codec.Command.RVEL, 10)
    with pytest.raises(ArcosConfigError):
        codec.vel_command(float("nan"))


def test_vel2_packing_high_byte_left_low_byte_right() -> None:
    assert codec.vel2_value(100, -100) == 0x05FB
    assert codec.vel2_value(-100, 100) == 0xFB05 - 0x10000
    assert codec.vel2_value(-2560, 0) == -32768
    wire = codec.vel2_command(-2560, 0)
    assert wire[4] == codec.ARGNINT and wire[5:7] == b"\x00\x80"


def test_string_argument_encoding() -> None:
    assert codec.str_command(codec.Command.SAY, b"\x05\x10") == codec.frame(b"\x0f\x2b\x02\x05\x10")


def test_hostbaud_codes() -> None:
    assert codec.hostbaud_command(38400) == codec.int_command(codec.Command.HOSTBAUD, 2)
    with pytest.raises(ArcosConfigError):
        codec.hostbaud_command(4800)


# ---- property tests -------------------------------------------------------------------------------

_payloads = st.binary(min_size=1, max_size=252)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=600), st.lists(st.integers(min_value=1, max_value=64), max_size=20))
def test_arbitrary_bytes_never_raise(data: bytes, cuts: list[int]) -> None:
    dec = ArcosDecoder()
    pos = 0
    for cut in cuts:
        dec.feed(data[pos : pos + cut])
        pos += cut
    dec.feed(data[pos:])
    dec.expire_partial()


@settings(max_examples=200, deadline=None)
@given(_payloads)
def test_decode_payload_raises_only_typed_errors(payload: bytes) -> None:
    try:
        codec.decode_payload(payload)
    except ArcosError as exc:
        assert isinstance(exc, ProtocolError)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(
        st.tuples(st.binary(max_size=40), _payloads),
        min_size=1,
        max_size=8,
    ),
    st.binary(max_size=40),
)
def test_deframer_finds_every_frame_in_random_junk(chunks: list[tuple[bytes, bytes]], tail: bytes) -> None:
    """Every valid frame embedded in junk comes out, in order (junk may add extra frames, never hide one).

    Junk is kept free of 0xFA so that it cannot open a header whose claimed body swallows a real
    frame's start in a way that no byte-level parser could disambiguate (see the expire test).
    """
    wire = bytearray()
    expected = []
    for junk, payload in chunks:
        wire += junk.replace(b"\xfa", b"\x00")
        wire += codec.frame(payload)
        expected.append(payload)
    wire += tail.replace(b"\xfa", b"\x00")
    deframer = Deframer()
    items = deframer.feed(bytes(wire))
    # a tiny frame ending in 0xFA at the very end is held for the next byte (it may open a header)
    # until the client, seeing no progress, calls expire_partial; it does so after every stall, so
    # back-to-back held frames come out one call each
    for _ in range(len(chunks) + 1):
        released = deframer.expire_partial()
        if not released:
            break
        items += released
    found = [i.payload for i in items if isinstance(i, RawFrame)]
    it = iter(found)
    assert all(any(p == f for f in it) for p in expected)


@settings(max_examples=150, deadline=None)
@given(
    st.lists(st.tuples(st.binary(max_size=30), _payloads), min_size=1, max_size=6),
    st.integers(min_value=1, max_value=17),
)
def test_deframer_finds_frames_after_junk_with_headers_once_expired(
    chunks: list[tuple[bytes, bytes]], chunk_size: int
) -> None:
    """Unrestricted junk (headers included): feeding in pieces and expiring stalled partials finds every frame."""
    wire = bytearray()
    expected = []
    for junk, payload in chunks:
        wire += junk
        wire += codec.frame(payload)
        expected.append(payload)
    df = Deframer()
    items: list[RawFrame | BadFrame] = []
    for i in range(0, len(wire), chunk_size):
        items += df.feed(bytes(wire[i : i + chunk_size]))
    while df.pending > 1:
        before = df.pending
        items += df.expire_partial()
        if df.pending == before:
            break
    found = [i.payload for i in items if isinstance(i, RawFrame)]
    it = iter(found)
    assert all(any(p == f for f in it) for p in expected)


def test_strict_decode_frame_raises_typed_errors() -> None:
    assert codec.decode_frame(SYNC2_REPLY) == RobotIdentity("AMRISim", "Pioneer", "p3dx", True)
    bad = bytearray(SYNC2_REPLY)
    bad[-1] ^= 0x01
    with pytest.raises(ArcosChecksumError) as info:
        codec.decode_frame(bytes(bad))
    assert info.value.raw == bytes(bad) and isinstance(info.value, ChecksumError)
    for wire in (SYNC2_REPLY[:-1], b"\xfa\xfa\x03\x00\x00\x00", b"\xfa\xfb\x02\x00\x00"):
        with pytest.raises(ArcosProtocolError):
            codec.decode_frame(wire)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=80))
def test_strict_decode_frame_raises_only_typed_errors(wire: bytes) -> None:
    try:
        codec.decode_frame(wire)
    except ArcosError:
        pass


# issue 12 row 10: a tiny junk frame must not swallow the next frame's header
def _frame(payload: bytes) -> bytes:
    c = codec.checksum(payload)
    return b"\xfa\xfb" + bytes([len(payload) + 2]) + payload + bytes([c >> 8, c & 0xFF])


@pytest.mark.parametrize("split", [None, 5, 6, 7, 8])
def test_a_tiny_junk_frame_ending_in_fa_does_not_take_the_next_header(split: int | None) -> None:
    good = _frame(bytes([0x32]) + bytes(range(20)))
    stream = b"\x11\xfa\xfb\x03\xfa\x00" + good  # junk "FA FB 03 FA 00" + the frame's own 0xFA
    d = codec.Deframer()
    chunks = [stream] if split is None else [stream[:split], stream[split:]]
    frames = [f for c in chunks for f in d.feed(c) if isinstance(f, codec.RawFrame)]
    assert frames == [codec.RawFrame(good[3:-2])]


def test_a_real_sync_reply_is_still_a_frame() -> None:
    d = codec.Deframer()
    out = d.feed(bytes.fromhex("FAFB03010001") + _frame(b"\x02abc"))
    assert [f.payload for f in out if isinstance(f, codec.RawFrame)] == [b"\x01", b"\x02abc"]
