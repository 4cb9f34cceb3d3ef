"""Sans-I/O pieces of the WebSocket protocol (RFC 6455) that the live view's front needs: the HTTP
upgrade request's head (read, checked, its subprotocol rewritten), the response head's subprotocol,
and a frame reader that splits a byte stream into whole frames (unmasking client frames).

No socket, clock or thread in here: bytes in, typed values out. The Foxglove WebSocket protocol's
one binary message the front builds itself (Message Data, opcode 0x01) is :func:`message_data_frame`.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

#: the Foxglove SDK's name of the protocol, and the older name of the same protocol (the SDK's
#: messages are those of ``foxglove.websocket.v1``; only the name changed)
SDK_SUBPROTOCOL = "foxglove.sdk.v1"
LEGACY_SUBPROTOCOL = "foxglove.websocket.v1"
#: the longest HTTP request head accepted (a browser's is well under 4 KiB)
MAX_HEAD_BYTES = 16 * 1024

OP_CONT, OP_TEXT, OP_BINARY, OP_CLOSE, OP_PING, OP_PONG = 0x0, 0x1, 0x2, 0x8, 0x9, 0xA
#: Foxglove binary opcode of a server's Message Data (subscription id u32, log time u64 ns, payload)
FOXGLOVE_MESSAGE_DATA = 0x01


class HandshakeError(ValueError):
    """A request that is not a WebSocket upgrade the live view serves; ``status`` is the HTTP answer."""

    def __init__(self, status: int, reason: str) -> None:
        super().__init__(reason)
        self.status = status
        self.reason = reason


class FrameError(ValueError):
    """A frame that breaks RFC 6455 or is larger than the reader allows."""


@dataclass(frozen=True)
class RequestHead:
    request_line: str
    headers: tuple[tuple[str, str], ...]

    def values(self, name: str) -> list[str]:
        """Comma-separated values of every header ``name`` (case-insensitive), stripped."""
        out: list[str] = []
        for key, value in self.headers:
            if key.lower() == name.lower():
                out += [v.strip() for v in value.split(",") if v.strip()]
        return out


def head_end(buf: bytes | bytearray) -> int:
    """Index just after the blank line ending an HTTP head; -1 while incomplete; HandshakeError
    when the head is already longer than :data:`MAX_HEAD_BYTES`."""
    end = bytes(buf[: MAX_HEAD_BYTES + 4]).find(b"\r\n\r\n")
    if end < 0:
        if len(buf) > MAX_HEAD_BYTES:
            raise HandshakeError(431, "request head too long")
        return -1
    return end + 4


def parse_request_head(head: bytes) -> RequestHead:
    """A GET upgrade request's head -> :class:`RequestHead`; HandshakeError otherwise."""
    try:
        text = head.decode("ascii")
    except UnicodeDecodeError:
        raise HandshakeError(400, "request head is not ASCII") from None
    lines = text.split("\r\n")
    parts = lines[0].split(" ")
    if len(parts) != 3 or parts[0] != "GET" or not parts[2].startswith("HTTP/1."):
        raise HandshakeError(400, "expected a GET WebSocket upgrade request")
    headers = []
    for line in lines[1:]:
        if not line:
            continue
        name, sep, value = line.partition(":")
        if not sep or not name.strip() or name != name.strip():
            raise HandshakeError(400, "malformed header line")
        headers.append((name, value.strip()))
    req = RequestHead(lines[0], tuple(headers))
    if "websocket" not in [v.lower() for v in req.values("Upgrade")]:
        raise HandshakeError(426, "this port serves the Foxglove WebSocket protocol only (no Upgrade: websocket)")
    return req


def choose_subprotocol(offered: list[str]) -> tuple[str, str]:
    """(what the SDK server is asked for, what the client is answered) for the offered list; the SDK's
    own name is kept when offered, the older name is served as the SDK's (the same messages)."""
    if SDK_SUBPROTOCOL in offered or any(p.startswith(SDK_SUBPROTOCOL + ".") for p in offered):
        return ", ".join(offered), ""
    if LEGACY_SUBPROTOCOL in offered:
        return SDK_SUBPROTOCOL, LEGACY_SUBPROTOCOL
    raise HandshakeError(400, f"a Foxglove viewer is expected: subprotocol {SDK_SUBPROTOCOL} or "
                              f"{LEGACY_SUBPROTOCOL} (Foxglove, Lichtblick), got {', '.join(offered) or 'none'}")


def backend_request(req: RequestHead, subprotocols: str) -> bytes:
    """The request forwarded to the SDK server: the subprotocol chosen, no extensions (frames stay
    uncompressed, so the front can read and drop whole messages)."""
    skip = {"sec-websocket-protocol", "sec-websocket-extensions"}
    lines = [req.request_line] + [f"{k}: {v}" for k, v in req.headers if k.lower() not in skip]
    lines.append(f"Sec-WebSocket-Protocol: {subprotocols}")
    return ("\r\n".join(lines) + "\r\n\r\n").encode("ascii")


def response_status(head: bytes) -> int:
    """The status code of an HTTP response head (0 when unreadable)."""
    parts = head.split(b"\r\n", 1)[0].split(b" ")
    return int(parts[1]) if len(parts) >= 2 and parts[1].isdigit() and len(parts[1]) == 3 else 0


def rename_response_subprotocol(head: bytes, answer: str) -> bytes:
    """The SDK's response head with its ``Sec-WebSocket-Protocol`` value replaced by ``answer``."""
    if not answer:
        return head
    lines = head.decode("latin-1").split("\r\n")
    out = [f"Sec-WebSocket-Protocol: {answer}" if ln.lower().startswith("sec-websocket-protocol:") else ln
           for ln in lines]
    return "\r\n".join(out).encode("latin-1")


def http_error(status: int, reason: str) -> bytes:
    """A short plain-text HTTP error response that closes the connection."""
    titles = {400: "Bad Request", 426: "Upgrade Required", 431: "Request Header Fields Too Large",
              503: "Service Unavailable"}
    body = (reason + "\n").encode("utf-8", "replace")
    return (f"HTTP/1.1 {status} {titles.get(status, 'Error')}\r\nContent-Type: text/plain; charset=utf-8\r\n"
            f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n").encode("ascii") + body


@dataclass(frozen=True)
class Frame:
    fin: bool
    opcode: int
    #: the payload, unmasked
    payload: bytes
    #: the frame's bytes as received (forwarded unchanged)
    raw: bytes

    def is_message_data(self) -> bool:
        """A whole Foxglove Message Data frame (the data plane; the one kind a slow client may miss)."""
        return self.fin and self.opcode == OP_BINARY and self.payload[:1] == bytes([FOXGLOVE_MESSAGE_DATA])


class FrameReader:
    """Bytes in, whole frames out; at most ``max_frame_bytes`` of payload per frame (FrameError)."""

    def __init__(self, max_frame_bytes: int) -> None:
        self.max_frame_bytes = max_frame_bytes
        self._buf = bytearray()

    @property
    def buffered(self) -> int:
        return len(self._buf)

    def feed(self, data: bytes) -> list[Frame]:
        self._buf += data
        frames = []
        while (frame := self._next()) is not None:
            frames.append(frame)
        return frames

    def _next(self) -> Frame | None:
        buf = self._buf
        if len(buf) < 2:
            return None
        b0, b1 = buf[0], buf[1]
        if b0 & 0x70:
            raise FrameError("reserved bits set (no extension was agreed)")
        size, at = b1 & 0x7F, 2
        if size == 126:
            if len(buf) < 4:
                return None
            size, at = struct.unpack_from(">H", buf, 2)[0], 4
        elif size == 127:
            if len(buf) < 10:
                return None
            size, at = struct.unpack_from(">Q", buf, 2)[0], 10
        if size > self.max_frame_bytes:
            raise FrameError(f"frame of {size} bytes (at most {self.max_frame_bytes})")
        mask = b""
        if b1 & 0x80:
            mask, at = bytes(buf[at:at + 4]), at + 4
        if len(buf) < at + size:
            return None
        payload = bytes(buf[at:at + size])
        raw = bytes(buf[:at + size])
        del buf[:at + size]
        if mask:
            payload = _unmask(payload, mask)
        return Frame(bool(b0 & 0x80), b0 & 0x0F, payload, raw)


def _unmask(payload: bytes, mask: bytes) -> bytes:
    n = len(payload)
    key = int.from_bytes((mask * (n // 4 + 1))[:n], "big")
    return (int.from_bytes(payload, "big") ^ key).to_bytes(n, "big")


def message_data_frame(subscription_id: int, log_time_ns: int, payload: bytes) -> bytes:
    """A server's Foxglove Message Data, framed as an unmasked binary WebSocket frame."""
    body = struct.pack("<BIQ", FOXGLOVE_MESSAGE_DATA, subscription_id, log_time_ns) + payload
    n = len(body)
    if n < 126:
        head = struct.pack(">BB", 0x80 | OP_BINARY, n)
    elif n < 1 << 16:
        head = struct.pack(">BBH", 0x80 | OP_BINARY, 126, n)
    else:
        head = struct.pack(">BBQ", 0x80 | OP_BINARY, 127, n)
    return head + body


def client_close_frame(mask: bytes) -> bytes:
    """A client's Close frame (status 1000, normal closure), masked with the 4-byte ``mask``."""
    payload = _unmask(struct.pack(">H", 1000), mask)
    return struct.pack(">BB", 0x80 | OP_CLOSE, 0x80 | len(payload)) + mask + payload
