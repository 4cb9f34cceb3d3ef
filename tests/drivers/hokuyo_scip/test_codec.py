"""Unit tests of the SCIP 2.0 codec: checksums, encodings, framing, statuses, errors, builders."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.hokuyo_scip.codec import (
    DecodeError,
    DecodeErrorKind,
    ScanFrame,
    ScipDecoder,
    StateReply,
    StatusMeaning,
    StatusReply,
    TimeReply,
    build_scan,
    build_simple,
    build_time_mode,
    checksum,
    decode_values,
    encode_data_block,
    encode_timestamp_line,
    encode_values,
    status_for,
)
from drivers.hokuyo_scip.errors import ScipChecksumError, ScipConfigError, ScipError, ScipProtocolError


def md_frame(values: list[int] | np.ndarray, ts: int = 1234, echo: bytes = b"MD0000108001000") -> bytes:
    chars = encode_values(values, 3)
    return echo + b"\n99b\n" + encode_timestamp_line(ts) + encode_data_block(chars) + b"\n"


FULL = np.arange(1081) * 7 % 60000 + 23


def test_checksum_examples_from_the_fact_sheet() -> None:
    for status, expected in [("00", "P"), ("99", "b"), ("01", "Q"), ("02", "R"), ("04", "T"), ("0E", "e"),
                             ("0F", "f"), ("10", "Q")]:
        assert chr(checksum(status.encode())) == expected
    assert chr(checksum(b"DMIN:23")) == "7"  # the ';' is not summed


def test_timestamp_worked_example() -> None:
    assert decode_values(b"BI9Y", 4).tolist() == [4821609]
    assert encode_values([4821609], 4) == b"BI9Y"
    assert encode_timestamp_line(4821609) == b"BI9YM\n"


def test_encoding_limits() -> None:
    assert encode_values([0, 4095], 2) == b"00oo"
    assert decode_values(b"ooo", 3).tolist() == [262143]
    with pytest.raises(ScipConfigError):
        encode_values([4096], 2)
    with pytest.raises(ScipConfigError):
        encode_values([-1], 3)
    with pytest.raises(ScipProtocolError):
        decode_values(b"0p0", 3)  # 'p' is above 'o'
    with pytest.raises(ScipProtocolError):
        decode_values(b"0/0", 3)  # '/' is below '0'
    with pytest.raises(ScipProtocolError):
        decode_values(b"0000", 3)


def test_md_frame_decodes_and_values_straddle_line_breaks() -> None:
    # 1081 x 3 = 3243 chars: value 21 spans the first line break (chars 63..65)
    [ev] = ScipDecoder().feed(md_frame(FULL, ts=99))
    assert isinstance(ev, ScanFrame)
    assert ev.distances.tolist() == FULL.tolist()
    assert ev.timestamp_ms == 99 and ev.remaining == 0 and ev.intensities is None
    assert not ev.distances.flags.writeable


def test_byte_at_a_time_and_cr_line_ends() -> None:
    frame = md_frame(FULL)
    for data in (frame, frame.replace(b"\n", b"\r"), frame.replace(b"\n", b"\r\n")):
        dec = ScipDecoder()
        events = []
        for i in range(len(data)):
            events.extend(dec.feed(data[i : i + 1]))
        assert len(events) == 1 and isinstance(events[0], ScanFrame)
        assert events[0].distances.tolist() == FULL.tolist()


def test_cluster_zero_counts_as_one_and_cluster_reduces_count() -> None:
    [ev] = ScipDecoder().feed(md_frame(FULL, echo=b"GD0000108000").replace(b"99b", b"00P"))
    assert isinstance(ev, ScanFrame) and ev.distances.size == 1081
    vals = list(range(100, 100 + 541))
    [ev] = ScipDecoder().feed(md_frame(vals, echo=b"MD0000108002000"))
    assert isinstance(ev, ScanFrame) and ev.request.n_values == 541 and ev.distances.tolist() == vals


def test_me_frame_splits_distance_and_intensity() -> None:
    pairs = np.stack([FULL, FULL % 5000 + 1], axis=1).ravel()
    data = b"ME0000108001005\n99b\n" + encode_timestamp_line(5) + encode_data_block(encode_values(pairs, 3)) + b"\n"
    [ev] = ScipDecoder().feed(data)
    assert isinstance(ev, ScanFrame) and ev.intensities is not None
    assert ev.distances.tolist() == FULL.tolist() and ev.intensities.tolist() == (FULL % 5000 + 1).tolist()
    assert ev.remaining == 5


@pytest.mark.parametrize(
    "mutate, kind",
    [
        (lambda f: f.replace(b"99b", b"99c"), DecodeErrorKind.CHECKSUM),  # status sum
        (lambda f: f[:20] + bytes([f[20] ^ 1]) + f[21:], DecodeErrorKind.CHECKSUM),  # timestamp char
        (lambda f: f[:24] + bytes([f[24] ^ 1]) + f[25:], DecodeErrorKind.CHECKSUM),  # timestamp sum
        (lambda f: f[:100] + bytes([f[100] ^ 1]) + f[101:], DecodeErrorKind.CHECKSUM),  # data char
        (lambda f: f[:100] + f[101:], DecodeErrorKind.LAYOUT),  # a dropped byte
        (lambda f: f[:-40] + f[-39:], DecodeErrorKind.CHECKSUM),  # a dropped byte in the last line
    ],
)
def test_every_checksum_and_length_is_checked(mutate: object, kind: DecodeErrorKind) -> None:
    bad = mutate(md_frame(FULL))  # type: ignore[operator]
    dec = ScipDecoder()
    events = dec.feed(bad + md_frame(FULL, ts=7))
    assert isinstance(events[0], DecodeError) and events[0].kind is kind
    assert isinstance(events[0].error, ScipProtocolError)
    assert isinstance(events[-1], ScanFrame) and events[-1].timestamp_ms == 7
    assert sum(isinstance(e, ScanFrame) for e in events) == 1
    assert dec.errors == 1


def test_value_count_must_match_the_request() -> None:
    frame = md_frame(FULL[:-1])  # 1080 values for a 1081-step request
    [ev] = ScipDecoder().feed(frame)
    assert isinstance(ev, DecodeError) and "expected 1081" in ev.message


def test_lost_blank_line_merges_two_frames_and_both_are_recovered() -> None:
    first = md_frame(FULL, ts=1)[:-1]  # no closing empty line: the decoder splits at the second echo
    events = ScipDecoder().feed(first + md_frame(FULL, ts=2))
    assert not any(isinstance(e, DecodeError) for e in events)
    frames = [e for e in events if isinstance(e, ScanFrame)]
    assert [f.timestamp_ms for f in frames] == [1, 2]


def test_garbage_before_an_echo_is_skipped() -> None:
    events = ScipDecoder().feed(b"\x00\xffjunk" + md_frame(FULL, ts=3))
    assert isinstance(events[0], DecodeError) and events[0].kind is DecodeErrorKind.GARBAGE
    assert events[0].raw == b"\x00\xffjunk"
    assert isinstance(events[1], ScanFrame) and events[1].timestamp_ms == 3


def test_unterminated_garbage_is_bounded() -> None:
    dec = ScipDecoder(max_buffer_bytes=4096)
    events = dec.feed(b"x" * 5000)
    assert len(events) == 1 and isinstance(events[0], DecodeError) and events[0].kind is DecodeErrorKind.OVERFLOW
    assert dec.buffered == 0
    assert isinstance(dec.feed(md_frame(FULL))[0], ScanFrame)


def test_stray_empty_lines_between_replies_are_ignored() -> None:
    events = ScipDecoder().feed(b"\n\n\nQT\n00P\n\n\n\nBM\n02R\n\n")
    assert [(e.echo, e.status.code) for e in events if isinstance(e, StatusReply)] == [("QT", "00"), ("BM", "02")]


def test_ii_checksum_fallback_before_arrow_is_flagged() -> None:
    text = b"SCSP:Initial(2400[rpm])<-Default setting by user"
    short_sum = checksum(text[: text.index(b"<-")])
    assert short_sum != checksum(text)
    reply = (b"II\n00P\nMODL:X;" + bytes([checksum(b"MODL:X")]) + b"\nLASR:OFF;" + bytes([checksum(b"LASR:OFF")])
             + b"\n" + text + b";" + bytes([short_sum]) + b"\nTIME:00000A;" + bytes([checksum(b"TIME:00000A")])
             + b"\n\n")
    [ev] = ScipDecoder().feed(reply)
    assert isinstance(ev, StateReply)
    assert ev.checksum_fallback_keys == ("SCSP",)
    assert ev.info.laser_on is False and ev.info.time_ms == 10
    # a wrong sum on a line without '<-' is an error
    [bad] = ScipDecoder().feed(reply.replace(b"LASR:OFF;" + bytes([checksum(b"LASR:OFF")]), b"LASR:OFF;0"))
    assert isinstance(bad, DecodeError) and isinstance(bad.error, ScipChecksumError)


def test_info_sum_including_the_semicolon_is_rejected() -> None:
    wrong = checksum(b"DMIN:23;")
    assert wrong != checksum(b"DMIN:23")
    [ev] = ScipDecoder().feed(b"PP\n00P\nDMIN:23;" + bytes([wrong]) + b"\n\n")
    assert isinstance(ev, DecodeError) and ev.kind is DecodeErrorKind.CHECKSUM


def test_tm1_reply_and_letter_statuses() -> None:
    events = ScipDecoder().feed(b"TM1\n00P\n<SfkP\n\nTM0\n0Ee\n\nXX\n0Ee\n\n")
    assert isinstance(events[0], TimeReply) and events[0].timestamp_ms == 3292603
    assert isinstance(events[1], StatusReply) and events[1].status.code == "0E" and not events[1].status.success
    assert events[1].status.meaning is StatusMeaning.UNDEFINED_COMMAND
    assert isinstance(events[2], StatusReply) and events[2].command == "XX"


@pytest.mark.parametrize(
    "command, code, success, meaning",
    [
        ("BM", "00", True, StatusMeaning.OK),
        ("BM", "02", True, StatusMeaning.ALREADY_SET),
        ("BM", "01", False, StatusMeaning.LASER_FAULT),
        ("TM", "02", True, StatusMeaning.ALREADY_SET),
        ("TM", "03", True, StatusMeaning.ALREADY_SET),
        ("TM", "04", False, StatusMeaning.NOT_IN_TIME_MODE),
        ("MD", "99", True, StatusMeaning.SCAN_DATA),
        ("GD", "99", False, StatusMeaning.UNKNOWN),
        ("QT", "02", False, StatusMeaning.UNKNOWN),
        ("MD", "04", False, StatusMeaning.PARAMETER_ERROR),
        ("GD", "10", False, StatusMeaning.LASER_OFF),
        ("MD", "35", False, StatusMeaning.PAUSED),
        ("MD", "50", False, StatusMeaning.HARDWARE_ERROR),
        ("MD", "98", False, StatusMeaning.RESUMED),
        ("VV", "0E", False, StatusMeaning.UNDEFINED_COMMAND),
        ("SS", "0F", False, StatusMeaning.MISSING_PARAMETER),
        ("CR", "04", False, StatusMeaning.NOT_SUPPORTED),
        ("CR", "03", True, StatusMeaning.ALREADY_SET),
        ("MD", "0M", False, StatusMeaning.UNSTABLE),
        ("MD", "Z9", False, StatusMeaning.UNKNOWN),
    ],
)
def test_status_mapping_per_command(command: str, code: str, success: bool, meaning: StatusMeaning) -> None:
    s = status_for(command, code)
    assert (s.code, s.success, s.meaning) == (code, success, meaning)


def test_letter_codes_never_count_as_success() -> None:
    for letter in "ABCDEFGHIJKLMNOPQRSTUVWXYZ":
        for cmd in ("QT", "BM", "TM", "MD", "GD", "VV", "SS"):
            assert not status_for(cmd, "0" + letter).success


def test_builders() -> None:
    assert build_scan(0, 1080) == b"MD0000108001000\n"
    assert build_scan(0, 1080, intensity=True, count=1) == b"ME0000108001001\n"
    assert build_scan(0, 1080, 0, stream=False) == b"GD0000108000\n"
    assert build_scan(44, 725, 2, stream=False, intensity=True, tag="a.b") == b"GE0044072502;a.b\n"
    assert build_time_mode(1) == b"TM1\n"
    assert build_simple("QT") == b"QT\n"
    for bad in (lambda: build_scan(5, 4), lambda: build_scan(0, 1080, count=100), lambda: build_scan(0, 10, 100),
                lambda: build_scan(0, 10, interval=10), lambda: build_time_mode(3), lambda: build_simple("SS"),
                lambda: build_simple("QT", tag="x" * 17), lambda: build_simple("QT", tag="bad;tag")):
        with pytest.raises(ScipConfigError):
            bad()


def test_tagged_reply_keeps_the_tag() -> None:
    frame = md_frame(FULL, echo=b"MD0000108001000;abc")
    [ev] = ScipDecoder().feed(frame)
    assert isinstance(ev, ScanFrame) and ev.request.tag == "abc" and ev.echo.endswith(";abc")


def test_errors_are_driver_errors() -> None:
    assert issubclass(ScipChecksumError, ScipError)
    from drivers.errors import ChecksumError, DriverError

    assert issubclass(ScipChecksumError, ChecksumError) and issubclass(ScipChecksumError, DriverError)


def _info_reply(command: bytes, rows: list[tuple[str, str]]) -> bytes:
    body = b"".join(f"{k}:{v}".encode() + b";" + bytes([checksum(f"{k}:{v}".encode())]) + b"\n" for k, v in rows)
    return command + b"\n00P\n" + body + b"\n"


def test_short_ii_and_vv_of_other_models_parse_by_key() -> None:
    [ii] = ScipDecoder().feed(_info_reply(b"II", [("MODL", "X"), ("LASR", "ON"), ("SCSP", "y"), ("STAT", "ok")]))
    assert isinstance(ii, StateReply) and ii.info.time_ms is None and ii.info.laser_on is True
    [vv] = ScipDecoder().feed(_info_reply(b"VV", [("SERI", "H1"), ("VEND", "Hokuyo")]))
    assert vv.info.serial == "H1" and vv.info.firmware == ""  # type: ignore[union-attr]
    [bad] = ScipDecoder().feed(_info_reply(b"PP", [("DMIN", "23")]))
    assert isinstance(bad, DecodeError) and "lacks the" in bad.message  # PP values are needed to scan


# issue 12 row 9: a reply that lost its empty line must not absorb the next reply
def _echo_that_passes_as_a_payload_line() -> bytes:
    """An MD echo with a tag whose last character happens to be the checksum of the rest (1 in 64)."""
    for a in b"abcdefghijklmnopqrstuvwxyz":
        for b in b"ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789":
            echo = b"MD0000108001000;t" + bytes([a, b])
            if checksum(echo[:-1]) == echo[-1]:
                return echo
    raise AssertionError("no such tag")


@pytest.mark.parametrize("split", [None, 7, 12, 40])
def test_a_reply_without_its_empty_line_does_not_swallow_the_next_scan(split: int | None) -> None:
    echo = _echo_that_passes_as_a_payload_line()
    stream = b"CR00\n" + b"00" + bytes([checksum(b"00")]) + b"\n" + md_frame(FULL, echo=echo)
    dec = ScipDecoder()
    chunks = [stream] if split is None else [stream[:split], stream[split:]]
    events = [e for c in chunks for e in dec.feed(c)]
    scans = [e for e in events if isinstance(e, ScanFrame)]
    assert len(scans) == 1 and np.array_equal(scans[0].distances, FULL)
    assert any(isinstance(e, StatusReply) and e.command == "CR" for e in events)


# issue 32 row 10: junk without a line feed glued to the next echo was read as a tagged echo (the first
# audit's three inputs). The client notes every request it sends; the decoder prefers the echo of one.


def ge_reply(ts: int = 77) -> bytes:
    chars = encode_values(np.column_stack((FULL, FULL % 97)).ravel(), 3)
    return b"GE0000108001\n00P\n" + encode_timestamp_line(ts) + encode_data_block(chars) + b"\n"


def _client_decoder(*requests: bytes) -> ScipDecoder:
    dec = ScipDecoder()
    for r in requests:
        dec.sent(r)
    return dec


def test_a_tag_like_junk_before_a_scan_frame_does_not_lose_the_scan() -> None:
    dec = _client_decoder(build_simple("QT"), b"CR00\n", build_scan(0, 1080, count=0))
    events = dec.feed(b"CR00;" + md_frame(FULL, ts=5))
    assert isinstance(events[0], DecodeError) and events[0].kind is DecodeErrorKind.GARBAGE
    assert events[0].raw == b"CR00;"
    assert isinstance(events[1], ScanFrame) and np.array_equal(events[1].distances, FULL) and len(events) == 2


def test_qt_junk_before_a_cr_reply_leaves_the_cr_reply() -> None:
    dec = _client_decoder(build_simple("QT"), b"CR00\n")
    events = dec.feed(b"QT;CR00\n04T\n\n")
    assert isinstance(events[0], DecodeError) and events[0].raw == b"QT;"
    reply = events[1]
    assert isinstance(reply, StatusReply) and reply.echo == "CR00"
    assert reply.status.meaning is StatusMeaning.NOT_SUPPORTED


@pytest.mark.parametrize("noted", [True, False])
def test_junk_lines_before_a_ge_reply_are_not_a_reply_that_swallows_it(noted: bool) -> None:
    """``DM1`` is no SCIP command: its lines are junk, the GE reply after them decodes (with or without
    the requests noted: the echo grammar alone rejects ``DM1``)."""
    dec = _client_decoder(build_scan(0, 1080, intensity=True, stream=False)) if noted else ScipDecoder()
    events = dec.feed(b"DM1\n00P\n<" + ge_reply(ts=77))
    frames = [e for e in events if isinstance(e, ScanFrame)]
    assert len(frames) == 1 and frames[0].timestamp_ms == 77 and np.array_equal(frames[0].distances, FULL)
    assert all(isinstance(e, DecodeError) for e in events if e is not frames[0])
    assert not any(isinstance(e, StatusReply) for e in events)


def test_a_status_only_reply_never_carries_another_reply_as_payload() -> None:
    """QT (no payload) that lost its empty line, then junk glued to a scan frame such that every line after
    the status passes as a checksummed payload line: the frame survives even without the requests noted."""
    echo = b"MD0000108001000"
    junk = next(bytes([c]) for c in range(0x21, 0x7F) if checksum(bytes([c]) + echo[:-1]) == echo[-1])
    events = ScipDecoder().feed(b"QT\n00P\n" + junk + md_frame(FULL, ts=8, echo=echo))
    frames = [e for e in events if isinstance(e, ScanFrame)]
    assert len(frames) == 1 and frames[0].timestamp_ms == 8


def test_an_echo_of_a_request_not_sent_is_still_decoded_by_its_grammar() -> None:
    """A scanner left streaming by a previous client: its frames echo a request this client never sent."""
    dec = _client_decoder(build_simple("VV"))
    [frame] = dec.feed(md_frame(FULL[:101], echo=b"MD0100020001000"))
    assert isinstance(frame, ScanFrame) and frame.request.start == 100 and len(frame.distances) == 101
