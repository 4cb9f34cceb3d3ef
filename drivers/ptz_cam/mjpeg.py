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


#: a boundary line (``--token`` plus optional ``--`` and blanks) longer than this has lost its line feed
MAX_BOUNDARY_LINE = 256
#: one part's header block: at most this many bytes and lines, else it is junk and skipped
MAX_HEADER_BYTES = 8192
MAX_HEADER_LINES = 32


class MjpegParser:
    """Feed stream body bytes; get :class:`JpegPart` / :class:`TruncatedJpeg` / :class:`SkippedBytes`.

    Bounded: the buffer never holds more than ``max_part_bytes`` plus one delimiter and one header
    block; each byte is scanned a bounded number of times (no rescans of a growing buffer). The events
    do not depend on how the stream is split into ``feed`` calls. A part whose ``Content-Length``
    does not frame a complete JPEG is delimited by the next boundary instead (a wrong length loses
    no frame and cannot swallow the next part); a boundary inside a part's headers or body starts a
    new part.
    """

    def __init__(self, boundary: str, max_part_bytes: int = 8 * 1024 * 1024) -> None:
        token = boundary.lstrip("-")
        if not token:
            raise MjpegFormatError("empty multipart boundary")
        self._delim = b"--" + token.encode("latin-1")
        self._max = max_part_bytes
        self._buf = bytearray()
        self._state = _State.SEEK
        self._headers: dict[str, str] = {}
        self._header_bytes = 0
        self._length: int | None = None
        self._scan_from = 0  # where the next delimiter search in a body resumes
        self.frames = 0
        self.truncated = 0
        self.skipped_bytes = 0

    @property
    def buffered(self) -> int:
        return len(self._buf)

    def feed(self, data: bytes) -> list[MjpegEvent]:
        self._buf += data
        events: list[MjpegEvent] = []
        step = {_State.SEEK: self._seek, _State.HEADERS: self._read_headers, _State.BODY: self._read_body}
        while step[self._state](events):
            pass
        return events

    def _skip(self, events: list[MjpegEvent], n: int, reason: str) -> None:
        # CR/LF between a body and the next delimiter is framing, not loss
        chunk = bytes(self._buf[:n])
        del self._buf[:n]
        if chunk.strip(b"\r\n"):
            self.skipped_bytes += len(chunk)
            events.append(SkippedBytes(len(chunk), reason))

    def _resync(self, events: list[MjpegEvent], n: int, reason: str) -> bool:
        """Drop ``n`` bytes and look for the next boundary."""
        self._skip(events, n, reason)
        self._state = _State.SEEK
        return True

    def _seek(self, events: list[MjpegEvent]) -> bool:
        d = len(self._delim)
        i = self._buf.find(self._delim)
        if i < 0:
            if len(self._buf) >= d:
                self._skip(events, len(self._buf) - d + 1, "bytes outside any part")
            return False
        if i:
            self._skip(events, i, "bytes before a boundary")
        eol = self._buf.find(b"\n", d, MAX_BOUNDARY_LINE)
        if eol < 0:
            if len(self._buf) >= MAX_BOUNDARY_LINE:
                return self._resync(events, d, "a boundary line without a line feed")
            return False
        del self._buf[: eol + 1]
        self._state = _State.HEADERS
        self._headers = {}
        self._header_bytes = 0
        self._length = None
        return True

    def _read_headers(self, events: list[MjpegEvent]) -> bool:
        room = MAX_HEADER_BYTES - self._header_bytes
        eol = self._buf.find(b"\n", 0, room)
        cut = self._buf.find(self._delim, 0, room if eol < 0 else eol)
        if cut >= 0:  # the header block was cut short by the next part's boundary
            return self._resync(events, cut, "part headers cut short by a boundary")
        if eol < 0:
            if len(self._buf) >= room:
                return self._resync(events, room, "part headers too long")
            return False
        line = bytes(self._buf[:eol]).rstrip(b"\r")
        del self._buf[: eol + 1]
        self._header_bytes += eol + 1
        if not line:
            self._state = _State.BODY
            self._scan_from = 0
            return True
        if len(self._headers) >= MAX_HEADER_LINES:
            return self._drop_part(events, line, "too many part headers")
        return self._header_line(events, line)

    def _drop_part(self, events: list[MjpegEvent], line: bytes, reason: str) -> bool:
        self.skipped_bytes += len(line)
        events.append(SkippedBytes(len(line), reason))
        self._state = _State.SEEK
        return True

    def _header_line(self, events: list[MjpegEvent], line: bytes) -> bool:
        name, sep, value = line.decode("latin-1").partition(":")
        if not sep:
            return self._drop_part(events, line, "malformed part header")
        key = name.strip().lower()
        self._headers[key] = value.strip()
        if key == "content-length":
            try:
                length = int(value.strip())
            except ValueError:
                length = -1
            if not 0 <= length <= self._max:
                events.append(TruncatedJpeg(0, f"bad Content-Length {value.strip()!r}"))
                self.truncated += 1
                self._state = _State.SEEK
                return True
            self._length = length
        return True

    def _deliver(self, events: list[MjpegEvent], body: bytes, reason: str | None = None) -> None:
        if is_complete_jpeg(body):
            self.frames += 1
            events.append(JpegPart(body, dict(self._headers)))
        else:
            self.truncated += 1
            why = reason or ("no JPEG SOI" if not body.startswith(SOI) else "no JPEG EOI (truncated)")
            events.append(TruncatedJpeg(len(body), why))
        self._state = _State.SEEK

    def _read_body(self, events: list[MjpegEvent]) -> bool:
        if self._length is not None:
            return self._read_sized_body(events, self._length)
        d = len(self._delim)
        i = self._buf.find(self._delim, self._scan_from)
        if i < 0:
            self._scan_from = max(0, len(self._buf) - d + 1)
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

    def _read_sized_body(self, events: list[MjpegEvent], n: int) -> bool:
        """Content-Length framing, decided on the first ``n`` bytes alone (so however the stream is
        split): a complete JPEG with no boundary inside is the frame; anything else is delimited by
        the next boundary instead, as a part without a length would be."""
        inner = self._buf.find(self._delim, 0, n)
        if inner < 0 and len(self._buf) < n:
            return False
        body = bytes(self._buf[:n])
        if inner < 0 and is_complete_jpeg(body):
            del self._buf[:n]
            self._deliver(events, body)
            return True
        self._length = None  # a wrong Content-Length: find the part's end by its boundary
        return True
