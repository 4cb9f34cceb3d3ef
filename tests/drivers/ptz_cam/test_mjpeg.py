"""Multipart MJPEG parser: boundaries, Content-Length or scanning, truncated JPEGs counted and dropped."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.ptz_cam.errors import MjpegFormatError, ViscaError
from drivers.ptz_cam.mjpeg import JpegPart, MjpegParser, TruncatedJpeg, boundary_from_content_type

JPEG_A = b"\xff\xd8" + bytes(range(200)) + b"\xff\xd9"
JPEG_B = b"\xff\xd8" + b"--not-a-boundary\r\n" * 3 + b"\xff\xd9"


def part(jpeg: bytes, length: int | None = -1, delim: bytes = b"--myboundary") -> bytes:
    head = delim + b"\r\nContent-Type: image/jpeg\r\n"
    if length is not None:
        head += b"Content-Length: %d\r\n" % (len(jpeg) if length == -1 else length)
    return head + b"\r\n" + jpeg + b"\r\n"


@pytest.mark.parametrize(
    ("content_type", "token"),
    [
        ("multipart/x-mixed-replace;boundary=--myboundary", "myboundary"),
        ("multipart/x-mixed-replace; boundary=myboundary", "myboundary"),
        ('multipart/x-mixed-replace; boundary="--myboundary"', "myboundary"),
    ],
)
def test_boundary_from_content_type(content_type: str, token: str) -> None:
    assert boundary_from_content_type(content_type) == token


@pytest.mark.parametrize("content_type", ["image/jpeg", "multipart/x-mixed-replace", "multipart/mixed; boundary=--"])
def test_bad_content_types_are_typed_errors(content_type: str) -> None:
    with pytest.raises(MjpegFormatError):
        boundary_from_content_type(content_type)


@pytest.mark.parametrize("length", [-1, None])
@pytest.mark.parametrize("delim", [b"--myboundary", b"----myboundary"])
def test_frames_with_and_without_content_length(length: int | None, delim: bytes) -> None:
    p = MjpegParser("--myboundary")
    stream = part(JPEG_A, length, delim) + part(JPEG_B, length, delim) + part(JPEG_A, length, delim)
    events = [e for i in range(0, len(stream), 7) for e in p.feed(stream[i : i + 7])]
    if length is None:
        events += p.feed(delim + b"\r\n")  # the last part ends at the next boundary
    jpegs = [e.jpeg for e in events if isinstance(e, JpegPart)]
    assert jpegs == [JPEG_A, JPEG_B, JPEG_A]
    assert p.truncated == 0 and p.frames == 3


def test_truncated_jpeg_with_a_short_content_length_is_counted_not_delivered() -> None:
    p = MjpegParser("myboundary")
    events = p.feed(part(JPEG_A) + part(JPEG_A[:50]) + part(JPEG_B))
    assert [e.jpeg for e in events if isinstance(e, JpegPart)] == [JPEG_A, JPEG_B]
    assert [e.reason for e in events if isinstance(e, TruncatedJpeg)] == ["no JPEG EOI (truncated)"]
    assert p.truncated == 1


def test_part_shorter_than_its_content_length_resyncs_at_the_next_boundary() -> None:
    p = MjpegParser("myboundary")
    events = p.feed(part(JPEG_A[:60], length=len(JPEG_A)) + part(JPEG_B) + part(JPEG_A))
    assert [e.jpeg for e in events if isinstance(e, JpegPart)] == [JPEG_B, JPEG_A]
    assert p.truncated == 1


def test_garbage_without_soi_is_counted() -> None:
    p = MjpegParser("myboundary")
    events = p.feed(b"junk before\r\n" + part(b"hello world") + part(JPEG_A))
    assert [e.jpeg for e in events if isinstance(e, JpegPart)] == [JPEG_A]
    assert p.truncated == 1 and p.skipped_bytes > 0


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(st.binary(max_size=64), st.sampled_from([part(JPEG_A), part(JPEG_B), b"--myboundary\r\n",
                                                                     b"Content-Length: 9999999999\r\n\r\n"])),
                max_size=12))
def test_arbitrary_streams_never_raise_and_never_deliver_a_broken_jpeg(chunks: list[bytes]) -> None:
    p = MjpegParser("myboundary", max_part_bytes=4096)
    try:
        for c in chunks:
            for ev in p.feed(c):
                if isinstance(ev, JpegPart):
                    assert ev.jpeg.startswith(b"\xff\xd8") and ev.jpeg.endswith(b"\xff\xd9")
    except ViscaError:
        pytest.fail("the parser must not raise on stream bytes")


# ---------------------------------------------------------------------------------------------
# issue 12 rows 1 and 8: bounded memory, linear work, split-independence, no swallowed parts


def feed_all(p: MjpegParser, stream: bytes, cuts: list[int]) -> list[object]:
    events: list[object] = []
    last = 0
    for c in [*sorted(cuts), len(stream)]:
        events += p.feed(stream[last:c])
        last = c
    return events


def outcome(stream: bytes, cuts: list[int], max_part: int = 1 << 20) -> tuple[list[bytes], int]:
    p = MjpegParser("myboundary", max_part_bytes=max_part)
    events = feed_all(p, stream + b"--myboundary\r\n", cuts)
    return [e.jpeg for e in events if isinstance(e, JpegPart)], p.truncated


def test_a_boundary_line_without_a_line_feed_is_not_buffered_forever() -> None:
    p = MjpegParser("myboundary")
    p.feed(b"--myboundary")
    for _ in range(256):  # 1 MiB of bytes with no line feed
        p.feed(b"x" * 4096)
        assert p.buffered <= 4096 + 256
    events = p.feed(part(JPEG_A))
    assert [e.jpeg for e in events if isinstance(e, JpegPart)] == [JPEG_A]


def test_endless_distinct_header_lines_are_not_kept() -> None:
    p = MjpegParser("myboundary")
    p.feed(b"--myboundary\r\n")
    for i in range(20_000):
        p.feed(b"X-Header-%d: value\r\n" % i)
        assert p.buffered <= 8192 + 64
    assert len(p._headers) <= 32  # noqa: SLF001 - the bound itself
    events = p.feed(part(JPEG_A))
    assert [e.jpeg for e in events if isinstance(e, JpegPart)] == [JPEG_A]


def test_a_part_header_cut_short_does_not_swallow_the_next_part() -> None:
    for cut_at in (b"Content-Len", b"Content-Type: image/jp", b"Content-Length: 2"):
        stream = b"--myboundary\r\n" + cut_at + part(JPEG_A) + part(JPEG_B)
        assert outcome(stream, [])[0] == [JPEG_A, JPEG_B], cut_at


@pytest.mark.parametrize("wrong", [-5, -1, 1, 3, 20, 400])
def test_a_wrong_content_length_gives_the_same_frames_however_the_stream_is_split(wrong: int) -> None:
    stream = part(JPEG_A, length=len(JPEG_A) + wrong) + part(JPEG_B) + part(JPEG_A)
    whole = outcome(stream, [])
    assert whole[0][-2:] == [JPEG_B, JPEG_A]  # the wrong length never costs the next parts
    for cut in range(1, len(stream)):
        assert outcome(stream, [cut]) == whole, cut
    assert outcome(stream, list(range(1, len(stream)))) == whole  # byte by byte


_FRAGMENTS = st.sampled_from([
    part(JPEG_A), part(JPEG_B), part(JPEG_A, None), part(JPEG_A, len(JPEG_A) + 7), part(JPEG_B, 10),
    part(JPEG_A[:50]), b"--myboundary\r\n", b"--myboundary", b"Content-Length: 12\r\n", b"\r\n", b"\xff\xd8",
    b"--myboundary\r\nContent-Type: image/jpeg\r\nContent-Len",
])


@settings(max_examples=150, deadline=None)
@given(st.lists(st.one_of(_FRAGMENTS, st.binary(max_size=40)), max_size=10), st.lists(st.integers(0, 2000), max_size=6))
def test_splitting_a_stream_anywhere_yields_the_same_frames(chunks: list[bytes], cuts: list[int]) -> None:
    stream = b"".join(chunks)
    assert outcome(stream, [c % (len(stream) + 1) for c in cuts]) == outcome(stream, [])


@settings(max_examples=150, deadline=None)
@given(st.lists(st.one_of(_FRAGMENTS, st.binary(max_size=40)), max_size=8), st.sampled_from([JPEG_A, JPEG_B]))
def test_a_valid_part_after_any_corruption_is_delivered(junk: list[bytes], jpeg: bytes) -> None:
    p = MjpegParser("myboundary", max_part_bytes=4096)
    for c in junk:
        p.feed(c)
    events = p.feed(b"\r\n" + part(jpeg) + b"--myboundary\r\n")
    assert jpeg in [e.jpeg for e in events if isinstance(e, JpegPart)]


@settings(max_examples=150, deadline=None)
@given(st.lists(st.one_of(_FRAGMENTS, st.binary(min_size=1, max_size=3000)), max_size=30))
def test_the_buffer_stays_bounded(chunks: list[bytes]) -> None:
    p = MjpegParser("myboundary", max_part_bytes=4096)
    for c in chunks:
        p.feed(c)
        assert p.buffered <= 4096 + 8192 + 256 + len(c)
