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
