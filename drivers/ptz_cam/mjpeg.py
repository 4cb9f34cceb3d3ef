"""Sans-I/O multipart MJPEG parser (Sony SNC ``/image?speed=N`` and ``/mjpeg``).

The boundary comes from the response's Content-Type header (``boundary=--myboundary`` on the
Sony SNC series, ``boundary=myboundary`` elsewhere); parts are delimited by lines ``--<token>``
where the token is the boundary without leading dashes, so both spellings work. A part's length is
its ``Content-Length`` when present; otherwise the body runs to the next delimiter.

Every body is checked as a JPEG (SOI ``FF D8`` first, EOI ``FF D9`` last). A body that fails the
check, or whose ``Content-Length`` runs into the next delimiter, is a :class:`TruncatedJpeg`
event: counted, never delivered as a frame. The parser never raises on stream bytes.
"""

from __future__ import annotations

import enum
import re
from dataclasses import dataclass

from .errors import MjpegFormatError

SOI = b"\xff\xd8"
EOI = b"\xff\xd9"


@dataclass(frozen=True)
class JpegPart:
    jpeg: bytes
    headers: dict[str, str]


@dataclass(frozen=True)
class TruncatedJpeg:
    size: int
    reason: str


@dataclass(frozen=True)
class SkippedBytes:
    size: int
    reason: str


MjpegEvent = JpegPart | TruncatedJpeg | SkippedBytes

_BOUNDARY_RE = re.compile(r'boundary\s*=\s*"?([^";,\s]+)"?', re.IGNORECASE)


def boundary_from_content_type(content_type: str) -> str:
    """The boundary token of a ``multipart/x-mixed-replace`` Content-Type, leading dashes removed."""
    if "multipart" not in content_type.lower():
        raise MjpegFormatError(f"not a multipart stream: Content-Type {content_type!r}")
    match = _BOUNDARY_RE.search(content_type)
    if not match:
        raise MjpegFormatError(f"no boundary in Content-Type {content_type!r}")
    token = match.group(1).lstrip("-")
    if not token:
        raise MjpegFormatError(f"empty boundary in Content-Type {content_type!r}")
    return token


def is_complete_jpeg(data: bytes) -> bool:
    return len(data) >= 4 and data.startswith(SOI) and data.endswith(EOI)


class _State(enum.Enum):
    SEEK = 0
    HEADERS = 1
    BODY = 2


class MjpegParser:
    """Feed stream body bytes; get :class:`JpegPart` / :class:`TruncatedJpeg` / :class:`SkippedBytes`."""

    def __init__(self, boundary: str, max_part_bytes: int = 8 * 1024 * 1024) -> None:
        token = boundary.lstrip("-")
        if not token:
            raise MjpegFormatError("empty multipart boundary")
        self._delim = b"--" + token.encode("latin-1")
        self._max = max_part_bytes
        self._buf = bytearray()
        self._state = _State.SEEK
        self._headers: dict[str, str] = {}
        self._length: int | None = None
        self.frames = 0
        self.truncated = 0
        self.skipped_bytes = 0

    def feed(self, data: bytes) -> list[MjpegEvent]:
        self._buf += data
        events: list[MjpegEvent] = []
        while True:
            if self._state is _State.SEEK:
                if not self._seek(events):
                    break
            elif self._state is _State.HEADERS:
                if not self._read_headers(events):
                    break
            elif not self._read_body(events):
                break
        return events

    def _skip(self, events: list[MjpegEvent], n: int, reason: str) -> None:
        # CR/LF between a body and the next delimiter is framing, not loss
        chunk = bytes(self._buf[:n])
        del self._buf[:n]
        if chunk.strip(b"\r\n"):
            self.skipped_bytes += len(chunk)
            events.append(SkippedBytes(len(chunk), reason))

    def _seek(self, events: list[MjpegEvent]) -> bool:
        i = self._buf.find(self._delim)
        if i < 0:
            keep = len(self._delim) - 1
            if len(self._buf) > keep:
                self._skip(events, len(self._buf) - keep, "bytes outside any part")
            return False
        eol = self._buf.find(b"\n", i)
        if eol < 0:
            if i:
                self._skip(events, i, "bytes before a boundary")
            return False
        self._skip(events, i, "bytes before a boundary")
        del self._buf[: eol - i + 1]
        self._state = _State.HEADERS
        self._headers = {}
        self._length = None
        return True

    def _read_headers(self, events: list[MjpegEvent]) -> bool:
        while True:
            eol = self._buf.find(b"\n")
            if eol < 0:
                if len(self._buf) > 8192:
                    self._skip(events, len(self._buf), "part headers too long")
                    self._state = _State.SEEK
                    return True
                return False
            line = bytes(self._buf[:eol]).rstrip(b"\r")
            del self._buf[: eol + 1]
            if not line:
                self._state = _State.BODY
                return True
            if line.startswith(self._delim):
                # a boundary right after a boundary: empty part
                self._headers = {}
                continue
            name, sep, value = line.decode("latin-1").partition(":")
            if not sep:
                self.skipped_bytes += len(line)
                events.append(SkippedBytes(len(line), "malformed part header"))
                self._state = _State.SEEK
                return True
            self._headers[name.strip().lower()] = value.strip()
            if name.strip().lower() == "content-length":
                try:
                    length = int(value.strip())
                except ValueError:
                    length = -1
                self._length = length if 0 <= length <= self._max else None
                if length < 0 or length > self._max:
                    events.append(TruncatedJpeg(0, f"bad Content-Length {value.strip()!r}"))
                    self.truncated += 1
                    self._state = _State.SEEK
                    return True

    def _deliver(self, events: list[MjpegEvent], body: bytes) -> None:
        if is_complete_jpeg(body):
            self.frames += 1
            events.append(JpegPart(body, dict(self._headers)))
        else:
            self.truncated += 1
            reason = "no JPEG SOI" if not body.startswith(SOI) else "no JPEG EOI (truncated)"
            events.append(TruncatedJpeg(len(body), reason))
        self._state = _State.SEEK

    def _read_body(self, events: list[MjpegEvent]) -> bool:
        if self._length is not None:
            n = self._length
            # a delimiter inside the declared length means the part was cut short
            inner = self._buf.find(self._delim, 0, n + len(self._delim))
            if 0 <= inner < n:
                body = bytes(self._buf[:inner]).rstrip(b"\r\n")
                del self._buf[:inner]
                self.truncated += 1
                events.append(TruncatedJpeg(len(body), "part shorter than its Content-Length"))
                self._state = _State.SEEK
                return True
            if len(self._buf) < n:
                return False
            body = bytes(self._buf[:n])
            del self._buf[:n]
            self._deliver(events, body)
            return True
        i = self._buf.find(self._delim)
        if i < 0:
            if len(self._buf) > self._max:
                self._skip(events, len(self._buf), "part larger than max_part_bytes without a boundary")
                self.truncated += 1
                events.append(TruncatedJpeg(0, "part too large"))
                self._state = _State.SEEK
            return False
        while i > 0 and self._buf[i - 1] == 0x2D:  # "----token": the extra dashes belong to the delimiter
            i -= 1
        body = bytes(self._buf[:i]).rstrip(b"\r\n")
        del self._buf[:i]
        self._deliver(events, body)
        return True
