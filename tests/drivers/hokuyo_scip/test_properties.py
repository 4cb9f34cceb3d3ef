"""Property tests: encode/decode round trips; arbitrary bytes never raise and never hang the decoder."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.hokuyo_scip.codec import (
    DecodeError,
    ScanFrame,
    ScipDecoder,
    build_scan,
    decode_values,
    encode_data_block,
    encode_timestamp_line,
    encode_values,
    status_for,
)
from drivers.hokuyo_scip.timebase import TIMESTAMP_MODULUS, TimestampUnwrapper

SETTINGS = settings(max_examples=60, deadline=None)


@SETTINGS
@given(st.integers(1, 4).flatmap(lambda w: st.tuples(st.just(w), st.lists(st.integers(0, (1 << (6 * w)) - 1)))))
def test_value_round_trip(case: tuple[int, list[int]]) -> None:
    width, values = case
    chars = encode_values(values, width)
    assert len(chars) == width * len(values)
    assert all(0x30 <= c <= 0x6F for c in chars)
    assert decode_values(chars, width).tolist() == values


@st.composite
def scan_frames(draw: st.DrawFn) -> tuple[bytes, list[int], list[int] | None, int, int]:
    start = draw(st.integers(0, 1080))
    end = draw(st.integers(start, 1080))
    cluster = draw(st.integers(0, 5))
    intensity = draw(st.booleans())
    stream = draw(st.booleans())
    n = -(-(end - start + 1) // max(cluster, 1))
    dist = draw(st.lists(st.integers(0, 262143), min_size=n, max_size=n))
    inten = draw(st.lists(st.integers(0, 262143), min_size=n, max_size=n)) if intensity else None
    ts = draw(st.integers(0, TIMESTAMP_MODULUS - 1))
    remaining = draw(st.integers(0, 99))
    request = build_scan(start, end, cluster, intensity=intensity, stream=stream, count=remaining).rstrip(b"\n")
    values = [v for pair in zip(dist, inten) for v in pair] if inten is not None else dist
    status = b"99b" if stream else b"00P"
    data = request + b"\n" + status + b"\n" + encode_timestamp_line(ts) + encode_data_block(encode_values(values, 3))
    return data + b"\n", dist, inten, ts, remaining if stream else -1


@SETTINGS
@given(scan_frames(), st.lists(st.integers(1, 500), min_size=1, max_size=40))
def test_frame_round_trip_under_any_chunking(case: tuple[bytes, list[int], list[int] | None, int, int],
                                             cuts: list[int]) -> None:
    data, dist, inten, ts, remaining = case
    dec = ScipDecoder()
    events = []
    pos = 0
    for n in cuts * (len(data) // max(1, sum(cuts)) + 1):
        if pos >= len(data):
            break
        events.extend(dec.feed(data[pos : pos + n]))
        pos += n
    events.extend(dec.feed(data[pos:]))
    assert len(events) == 1
    ev = events[0]
    assert isinstance(ev, ScanFrame)
    assert ev.distances.tolist() == dist
    assert (ev.intensities.tolist() if ev.intensities is not None else None) == inten
    assert ev.timestamp_ms == ts
    if remaining >= 0:
        assert ev.remaining == remaining


@SETTINGS
@given(st.lists(st.binary(max_size=300), max_size=20))
def test_arbitrary_bytes_never_raise_and_resync(chunks: list[bytes]) -> None:
    dec = ScipDecoder(max_buffer_bytes=2048)
    for chunk in chunks:
        for ev in dec.feed(chunk):
            assert isinstance(ev, DecodeError) or hasattr(ev, "status")
    assert dec.buffered <= 2048 + 300
    # after any garbage, an empty line ends it and the next good frame decodes
    good = b"GD0000000401\n00P\n" + encode_timestamp_line(42) + encode_data_block(encode_values([500] * 5, 3)) + b"\n"
    events = dec.feed(b"\n\n" + good)
    frames = [e for e in events if isinstance(e, ScanFrame)]
    assert frames and frames[-1].timestamp_ms == 42 and frames[-1].distances.tolist() == [500] * 5


@SETTINGS
@given(st.binary(min_size=1, max_size=2000), st.integers(0, 6000))
def test_corrupting_one_byte_of_a_frame_never_yields_a_wrong_frame(noise: bytes, position: int) -> None:
    values = list(range(23, 23 + 1081))
    frame = b"MD0000108001000\n99b\n" + encode_timestamp_line(9) + encode_data_block(encode_values(values, 3)) + b"\n"
    pos = position % len(frame)
    bad = bytearray(frame)
    bad[pos] ^= noise[0] or 1
    for ev in ScipDecoder().feed(bytes(bad)):
        if isinstance(ev, ScanFrame):
            # a flip inside the echo's count digits or the tag is still a valid frame; data never differs
            assert ev.distances.tolist() == values and ev.timestamp_ms == 9


@SETTINGS
@given(st.text(min_size=2, max_size=2), st.sampled_from(["MD", "GD", "BM", "TM", "QT", "VV", "SS", "CR", "%ST"]))
def test_status_for_never_raises(code: str, command: str) -> None:
    s = status_for(command, code)
    assert s.code == code
    if s.success:
        assert code in ("00", "99", "02", "03", "01")


@SETTINGS
@given(st.integers(0, TIMESTAMP_MODULUS - 1), st.lists(st.integers(1, 200_000), min_size=1, max_size=50))
def test_unwrap_recovers_true_elapsed_time(start_ms: int, steps_ms: list[int]) -> None:
    unwrapper = TimestampUnwrapper()
    true_ms = 0
    first = unwrapper.update(start_ms, 0.0)
    for step in steps_ms:
        true_ms += step
        stamp = unwrapper.update((start_ms + true_ms) % TIMESTAMP_MODULUS, true_ms / 1000.0)
        assert stamp.unwrapped_ms - first.unwrapped_ms == true_ms
    assert unwrapper.resets == 0
    assert unwrapper.wraps == (start_ms + true_ms) // TIMESTAMP_MODULUS


def test_decode_of_random_frame_matches_numpy_reference() -> None:
    rng = np.random.default_rng(1)
    values = rng.integers(0, 262144, 1081)
    chars = encode_values(values, 3)
    ref = [(chars[i] - 48) * 4096 + (chars[i + 1] - 48) * 64 + (chars[i + 2] - 48) for i in range(0, len(chars), 3)]
    assert ref == values.tolist()


_SENT = (b"QT\n", b"CR00\n", b"BM\n", b"II\n", b"TM1\n", b"MD0000108001000\n", b"GE0000108001\n")


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=80).filter(lambda b: b"\n" not in b and b"\r" not in b), st.integers(0, 6))
def test_a_junk_prefix_never_loses_the_following_frame(junk: bytes, which: int) -> None:
    """Issue 32 row 10: whatever junk without a line end is glued before an echo, the frame after it is
    decoded intact (the decoder knows the requests sent, as the client tells it)."""
    dec = ScipDecoder()
    for r in _SENT:
        dec.sent(r)
    values = [23 + (7 * i) % 4000 for i in range(1081)]
    frames = [
        b"MD0000108001000\n99b\n" + encode_timestamp_line(11) + encode_data_block(encode_values(values, 3)) + b"\n",
        b"GE0000108001\n00P\n" + encode_timestamp_line(11)
        + encode_data_block(encode_values([v for x in values for v in (x, 5)], 3)) + b"\n",
    ]
    frame = frames[which % 2]
    events = dec.feed(junk + frame)
    scans = [e for e in events if isinstance(e, ScanFrame)]
    assert len(scans) == 1 and scans[0].timestamp_ms == 11 and scans[0].distances.tolist() == values
    assert all(isinstance(e, DecodeError) for e in events if e is not scans[0])
