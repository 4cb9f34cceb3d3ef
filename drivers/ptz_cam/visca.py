"""Sans-I/O VISCA codec for the Sony SNC-RZ50 (fact sheet: shared/protocols/visca_snc_rz50.md).

Receiving: :class:`ViscaParser` is fed the bytes the camera sent, frames them by the 0xFF
terminator (3..16 bytes per packet), validates header and shape, and returns typed events
(:class:`Ack`, :class:`Completion`, :class:`InquiryAnswer`, :class:`ErrorReply`,
:class:`AddressSetReply`, :class:`IfClearEcho`, :class:`NetworkChange`, and :class:`Discarded` for
bytes it had to drop to resynchronise). It never raises on input: garbage becomes a
``Discarded`` event and parsing goes on at the next plausible packet.

Sending: one builder function per command and inquiry returns the exact bytes; each validates its
parameters and raises :class:`ViscaConfigError` before anything is sent. Every builder returns a
:class:`Request`, which also says what kind of reply to wait for, so the client can match replies
to requests by socket and kind.

Inquiry answers are decoded by ``decode_*`` functions that check the answer's length and that
every nibble byte is <= 0x0F, raising :class:`ViscaProtocolError` otherwise. The pan/tilt position
answer comes in two layouts, told apart by length: 8 data bytes (4+4 nibbles, the RZ30/RZ50/EVI-D70
generation) or 9 (5+4 nibbles, newer BRC/SRG cameras and clones).
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass

from .errors import (
    BufferFullError,
    CommandCancelledError,
    MessageLengthError,
    NoSocketError,
    NotExecutableError,
    SyntaxReplyError,
    UnknownReplyError,
    ViscaConfigError,
    ViscaProtocolError,
    ViscaReplyError,
)

TERMINATOR = 0xFF
MIN_PACKET = 3
MAX_PACKET = 16

#: pan speed range of Sony VISCA tables (0x01..0x18); the RZ50's own maximum is [?]
PAN_SPEED_MAX = 0x18
#: tilt speed range of most Sony VISCA tables (0x01..0x14); [?] for the RZ50
TILT_SPEED_MAX = 0x14
ZOOM_SPEED_MAX = 7


# --------------------------------------------------------------------------------------------
# Replies (camera -> controller)


class ErrorCode(enum.Enum):
    MESSAGE_LENGTH = 0x01
    SYNTAX = 0x02
    BUFFER_FULL = 0x03
    CANCELLED = 0x04
    NO_SOCKET = 0x05
    NOT_EXECUTABLE = 0x41
    UNKNOWN = -1


@dataclass(frozen=True)
class Ack:
    """``z0 4y FF``: the command was accepted into socket y."""

    address: int
    socket: int
    raw: bytes


@dataclass(frozen=True)
class Completion:
    """``z0 5y FF``: the command in socket y finished (socket 0: an IF_Clear's reply)."""

    address: int
    socket: int
    raw: bytes


@dataclass(frozen=True)
class InquiryAnswer:
    """``z0 50 d.. FF``: an inquiry's answer; ``data`` is everything between ``50`` and ``FF``."""

    address: int
    data: bytes
    raw: bytes


@dataclass(frozen=True)
class ErrorReply:
    """``z0 6y cc FF``: an error for socket y (0 = not tied to a socket)."""

    address: int
    socket: int
    code: ErrorCode
    code_byte: int
    raw: bytes

    def to_exception(self, context: str = "") -> ViscaReplyError:
        cls: type[ViscaReplyError] = _ERROR_CLASSES.get(self.code, UnknownReplyError)
        what = context + ": " if context else ""
        name = self.code.name.lower().replace("_", " ") if self.code is not ErrorCode.UNKNOWN else "unknown error"
        return cls(
            f"{what}camera replied {name} (code 0x{self.code_byte:02X}, socket {self.socket}, raw {self.raw.hex(' ')})",
            socket=self.socket,
            code=f"{self.code_byte:02X}",
            raw=self.raw,
        )


@dataclass(frozen=True)
class AddressSetReply:
    """``88 30 0n FF``: n is the last device's address plus one, so the camera count is n - 1."""

    next_address: int
    raw: bytes

    @property
    def camera_count(self) -> int:
        return self.next_address - 1


@dataclass(frozen=True)
class IfClearEcho:
    """``88 01 00 01 FF``: the broadcast IF_Clear came back round the chain."""

    raw: bytes


@dataclass(frozen=True)
class NetworkChange:
    """``z0 38 FF``: a device was plugged in or out; re-run AddressSet."""

    address: int
    raw: bytes


@dataclass(frozen=True)
class Discarded:
    """Bytes dropped while resynchronising (never silently: the reason says why)."""

    raw: bytes
    reason: str


ReplyEvent = Ack | Completion | InquiryAnswer | ErrorReply | AddressSetReply | IfClearEcho | NetworkChange
Event = ReplyEvent | Discarded

_ERROR_CLASSES: dict[ErrorCode, type[ViscaReplyError]] = {
    ErrorCode.MESSAGE_LENGTH: MessageLengthError,
    ErrorCode.SYNTAX: SyntaxReplyError,
    ErrorCode.BUFFER_FULL: BufferFullError,
    ErrorCode.CANCELLED: CommandCancelledError,
    ErrorCode.NO_SOCKET: NoSocketError,
    ErrorCode.NOT_EXECUTABLE: NotExecutableError,
}


def _is_reply_header(byte: int) -> bool:
    """Camera replies start with (address + 8) << 4 (0x90..0xF0) or the broadcast header 0x88."""
    return byte == 0x88 or (0x90 <= byte <= 0xF0 and byte & 0x0F == 0)


def parse_packet(packet: bytes) -> ReplyEvent | None:
    """Decode one complete packet (header .. 0xFF); None when it is not a valid camera reply."""
    n = len(packet)
    if n < MIN_PACKET or n > MAX_PACKET or packet[-1] != TERMINATOR or TERMINATOR in packet[:-1]:
        return None
    if any(b & 0x80 for b in packet[1:-1]):
        return None  # reply bodies are nibbles and message codes below 0x80: a high byte is a new header
    header = packet[0]
    if not _is_reply_header(header):
        return None
    raw = bytes(packet)
    if header == 0x88:
        if n == 4 and packet[1] == 0x30 and 0x02 <= packet[2] <= 0x08:
            return AddressSetReply(next_address=packet[2], raw=raw)
        if raw == b"\x88\x01\x00\x01\xff":
            return IfClearEcho(raw=raw)
        return None
    address = (header >> 4) - 8
    kind, nib = packet[1] >> 4, packet[1] & 0x0F
    if n == 3:
        if kind == 4 and nib != 0:
            return Ack(address, nib, raw)
        if kind == 5:
            return Completion(address, nib, raw)
        if packet[1] == 0x38:
            return NetworkChange(address, raw)
        return None
    if packet[1] == 0x50:
        return InquiryAnswer(address, bytes(packet[2:-1]), raw)
    if kind == 6 and n == 4:
        code_byte = packet[2]
        try:
            code = ErrorCode(code_byte)
        except ValueError:
            code = ErrorCode.UNKNOWN
        return ErrorReply(address, nib, code, code_byte, raw)
    return None


class ViscaParser:
    """Incremental reply framer. ``feed(data)`` returns the events completed by ``data``.

    Resynchronisation: a terminated chunk that is not a valid reply is searched for the first
    reply header from which the rest parses; the bytes before it become a :class:`Discarded`
    event. A reply header byte (0x88, 0x90..0xF0) arriving inside an unterminated packet starts a
    new packet: the fragment before it is discarded. More than 16 bytes without a terminator cannot
    be one packet, so all but the last 15 are discarded. Counters ``packets`` and ``discarded_bytes`` say what happened.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.packets = 0
        self.discarded_bytes = 0

    def reset(self) -> bytes:
        """Drop any partial packet (e.g. after a reconnect); returns what was dropped."""
        dropped = bytes(self._buf)
        self._buf.clear()
        return dropped

    @property
    def pending(self) -> int:
        """Bytes held waiting for a terminator."""
        return len(self._buf)

    def feed(self, data: bytes) -> list[Event]:
        events: list[Event] = []
        for byte in data:
            self._buf.append(byte)
            if byte == TERMINATOR:
                self._frame(events)
            elif _is_reply_header(byte) and len(self._buf) > 1:
                # reply data bytes are below 0x80: a header byte starts a new reply, so an unterminated
                # fragment before it is dropped and cannot swallow the reply that follows
                self._discard(events, bytes(self._buf[:-1]), "unterminated fragment before a reply header")
                del self._buf[:-1]
            elif len(self._buf) > MAX_PACKET - 1:
                # no terminator within a packet's length: keep only what could still start one
                cut = len(self._buf) - (MAX_PACKET - 1)
                self._discard(events, bytes(self._buf[:cut]), "no 0xFF terminator within 16 bytes")
                del self._buf[:cut]
        return events

    def _discard(self, events: list[Event], raw: bytes, reason: str) -> None:
        if raw:
            self.discarded_bytes += len(raw)
            events.append(Discarded(raw=raw, reason=reason))

    def _frame(self, events: list[Event]) -> None:
        chunk = bytes(self._buf)
        self._buf.clear()
        for start in range(len(chunk) - MIN_PACKET + 1):
            if not _is_reply_header(chunk[start]):
                continue
            event = parse_packet(chunk[start:])
            if event is not None:
                self._discard(events, chunk[:start], "garbage before a reply header")
                self.packets += 1
                events.append(event)
                return
        self._discard(events, chunk, "not a valid VISCA reply")


# --------------------------------------------------------------------------------------------
# Requests (controller -> camera)


class ReplyKind(enum.Enum):
    """What a request expects back."""

    COMMAND = "command"  # ACK into a socket, later completion (or an error instead)
    INQUIRY = "inquiry"  # one InquiryAnswer (or an error)
    IF_CLEAR = "if_clear"  # addressed IF_Clear: Completion with socket 0
    ADDRESS_SET = "address_set"  # broadcast: AddressSetReply
    IF_CLEAR_BROADCAST = "if_clear_broadcast"  # broadcast: IfClearEcho
    CANCEL = "cancel"  # ErrorReply 6y 04 (cancelled) or 6y 05 (no socket)


class Motion(enum.Enum):
    """How the client scales a command's completion timeout."""

    NONE = "none"
    PAN_TILT_ABSOLUTE = "pan_tilt_absolute"
    PAN_TILT_RELATIVE = "pan_tilt_relative"
    PAN_TILT_HOME = "pan_tilt_home"
    PAN_TILT_RESET = "pan_tilt_reset"
    ZOOM = "zoom"
    FOCUS = "focus"


@dataclass(frozen=True)
class Request:
    """Bytes to send plus what they expect back.

    ``answer_lengths`` lists the data lengths an inquiry answer may have (others are stale
    answers to some other inquiry and are not taken). ``pan_counts``/``tilt_counts`` are the
    target (absolute) or delta (relative) of a pan-tilt move, ``pan_speed``/``tilt_speed`` its
    speeds, ``zoom_position`` the target of a zoom direct: the client uses them to size the
    completion timeout.
    """

    name: str
    packet: bytes
    kind: ReplyKind
    answer_lengths: tuple[int, ...] = ()
    motion: Motion = Motion.NONE
    pan_counts: int = 0
    tilt_counts: int = 0
    pan_speed: int = 0
    tilt_speed: int = 0
    zoom_position: int | None = None
    socket: int = 0  # for CANCEL: the socket to cancel

    @property
    def idempotent(self) -> bool:
        """Safe to re-send after a lost reply (never a relative move or a continuous drive)."""
        return (
            self.kind is ReplyKind.INQUIRY
            or self.motion in (Motion.PAN_TILT_ABSOLUTE, Motion.PAN_TILT_HOME)
            or (
                self.name in ("zoom_direct", "zoom_stop", "pan_tilt_stop", "focus_auto", "focus_manual", "digital_zoom")
            )
        )


def _header(address: int) -> int:
    if not 1 <= address <= 7:
        raise ViscaConfigError(f"VISCA address must be 1..7, got {address}")
    return 0x80 | address


def _check_int(name: str, value: int, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ViscaConfigError(f"{name} must be an int, got {value!r}")
    if not lo <= value <= hi:
        raise ViscaConfigError(f"{name} must be {lo}..{hi}, got {value}")
    return value


def nibbles(value: int, count: int) -> bytes:
    """``value`` as ``count`` nibble bytes (0p 0q ..), most significant first; negatives in two's complement."""
    bits = 4 * count
    lo, hi = -(1 << (bits - 1)), (1 << bits) - 1
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ViscaConfigError(f"{value!r} does not fit {count} nibbles")
    value &= (1 << bits) - 1
    return bytes((value >> (4 * (count - 1 - i))) & 0x0F for i in range(count))


def from_nibbles(data: bytes, signed: bool) -> int:
    """Inverse of :func:`nibbles`; raises :class:`ViscaProtocolError` for a byte above 0x0F."""
    value = 0
    for byte in data:
        if byte > 0x0F:
            raise ViscaProtocolError(f"nibble byte 0x{byte:02X} > 0x0F in {data.hex(' ')}", raw=data)
        value = (value << 4) | byte
    bits = 4 * len(data)
    if signed and bits and value >= 1 << (bits - 1):
        value -= 1 << bits
    return value


def address_set() -> Request:
    return Request("address_set", b"\x88\x30\x01\xff", ReplyKind.ADDRESS_SET)


def if_clear_broadcast() -> Request:
    return Request("if_clear_broadcast", b"\x88\x01\x00\x01\xff", ReplyKind.IF_CLEAR_BROADCAST)


def if_clear(address: int = 1) -> Request:
    return Request("if_clear", bytes([_header(address), 0x01, 0x00, 0x01, 0xFF]), ReplyKind.IF_CLEAR)


def _command(name: str, address: int, body: Sequence[int], **kw: object) -> Request:
    return Request(name, bytes([_header(address), 0x01, *body, 0xFF]), ReplyKind.COMMAND, **kw)  # type: ignore[arg-type]


def _inquiry(name: str, address: int, body: Sequence[int], lengths: tuple[int, ...]) -> Request:
    return Request(name, bytes([_header(address), 0x09, *body, 0xFF]), ReplyKind.INQUIRY, answer_lengths=lengths)


class PanDirection(enum.IntEnum):
    LEFT = 0x01
    RIGHT = 0x02
    STOP = 0x03


class TiltDirection(enum.IntEnum):
    UP = 0x01
    DOWN = 0x02
    STOP = 0x03


def _speeds(pan_speed: int, tilt_speed: int, pan_max: int, tilt_max: int) -> tuple[int, int]:
    # Never 0, not even for an axis that does not move: Sony cameras reject it (pitfall 5).
    _check_int("pan_max", pan_max, 1, 0x7F)
    _check_int("tilt_max", tilt_max, 1, 0x7F)
    return _check_int("pan_speed", pan_speed, 1, pan_max), _check_int("tilt_speed", tilt_speed, 1, tilt_max)


def pan_tilt_drive(
    pan: PanDirection,
    tilt: TiltDirection,
    pan_speed: int = 1,
    tilt_speed: int = 1,
    *,
    address: int = 1,
    pan_max: int = PAN_SPEED_MAX,
    tilt_max: int = TILT_SPEED_MAX,
) -> Request:
    """Continuous drive (or stop with both STOP). Both speeds must be legal even for an idle axis."""
    vv, ww = _speeds(pan_speed, tilt_speed, pan_max, tilt_max)
    pan, tilt = PanDirection(pan), TiltDirection(tilt)
    name = "pan_tilt_stop" if pan is PanDirection.STOP and tilt is TiltDirection.STOP else "pan_tilt_drive"
    return _command(name, address, [0x06, 0x01, vv, ww, int(pan), int(tilt)], pan_speed=vv, tilt_speed=ww)


def pan_tilt_stop(pan_speed: int = 1, tilt_speed: int = 1, *, address: int = 1) -> Request:
    return pan_tilt_drive(PanDirection.STOP, TiltDirection.STOP, pan_speed, tilt_speed, address=address)


def _position(
    name: str,
    sub: int,
    motion: Motion,
    pan_counts: int,
    tilt_counts: int,
    pan_speed: int,
    tilt_speed: int,
    address: int,
    pan_max: int,
    tilt_max: int,
) -> Request:
    vv, ww = _speeds(pan_speed, tilt_speed, pan_max, tilt_max)
    _check_int("pan_counts", pan_counts, -0x8000, 0x7FFF)
    _check_int("tilt_counts", tilt_counts, -0x8000, 0x7FFF)
    body = [0x06, sub, vv, ww, *nibbles(pan_counts, 4), *nibbles(tilt_counts, 4)]
    return _command(
        name,
        address,
        body,
        motion=motion,
        pan_counts=pan_counts,
        tilt_counts=tilt_counts,
        pan_speed=vv,
        tilt_speed=ww,
    )


def pan_tilt_absolute(
    pan_counts: int,
    tilt_counts: int,
    pan_speed: int = PAN_SPEED_MAX,
    tilt_speed: int = TILT_SPEED_MAX,
    *,
    address: int = 1,
    pan_max: int = PAN_SPEED_MAX,
    tilt_max: int = TILT_SPEED_MAX,
) -> Request:
    """Absolute position, RZ50 layout: 16-bit two's-complement pan and tilt in 4 nibbles each."""
    return _position(
        "pan_tilt_absolute",
        0x02,
        Motion.PAN_TILT_ABSOLUTE,
        pan_counts,
        tilt_counts,
        pan_speed,
        tilt_speed,
        address,
        pan_max,
        tilt_max,
    )


def pan_tilt_relative(
    pan_counts: int,
    tilt_counts: int,
    pan_speed: int = PAN_SPEED_MAX,
    tilt_speed: int = TILT_SPEED_MAX,
    *,
    address: int = 1,
    pan_max: int = PAN_SPEED_MAX,
    tilt_max: int = TILT_SPEED_MAX,
) -> Request:
    """Relative move by a delta, same encoding as :func:`pan_tilt_absolute`. Never retried blindly."""
    return _position(
        "pan_tilt_relative",
        0x03,
        Motion.PAN_TILT_RELATIVE,
        pan_counts,
        tilt_counts,
        pan_speed,
        tilt_speed,
        address,
        pan_max,
        tilt_max,
    )


def pan_tilt_home(address: int = 1) -> Request:
    return _command("pan_tilt_home", address, [0x06, 0x04], motion=Motion.PAN_TILT_HOME)


def pan_tilt_reset(address: int = 1) -> Request:
    return _command("pan_tilt_reset", address, [0x06, 0x05], motion=Motion.PAN_TILT_RESET)


def auto_pan_tilt_speed(on: bool, address: int = 1) -> Request:
    """Auto pan-tilt speed (the camera slows panning when zoomed in): listed for the RZ30, [?] RZ50."""
    return _command("auto_pan_tilt_speed", address, [0x06, 0x24, 0x02 if on else 0x03])


def zoom_stop(address: int = 1) -> Request:
    return _command("zoom_stop", address, [0x04, 0x07, 0x00])


def zoom_tele(address: int = 1, speed: int | None = None) -> Request:
    """Zoom in; ``speed`` 0 (slow)..7 (fast) for the variable-speed form, None for the standard one."""
    if speed is None:
        return _command("zoom_tele", address, [0x04, 0x07, 0x02], motion=Motion.ZOOM)
    p = _check_int("zoom speed", speed, 0, ZOOM_SPEED_MAX)
    return _command("zoom_tele_variable", address, [0x04, 0x07, 0x20 | p], motion=Motion.ZOOM)


def zoom_wide(address: int = 1, speed: int | None = None) -> Request:
    if speed is None:
        return _command("zoom_wide", address, [0x04, 0x07, 0x03], motion=Motion.ZOOM)
    p = _check_int("zoom speed", speed, 0, ZOOM_SPEED_MAX)
    return _command("zoom_wide_variable", address, [0x04, 0x07, 0x30 | p], motion=Motion.ZOOM)


def zoom_direct(position: int, address: int = 1) -> Request:
    """Zoom to a position: 0x0000 wide .. 0x4000 optical tele (above: digital zoom)."""
    _check_int("zoom position", position, 0, 0xFFFF)
    return _command(
        "zoom_direct", address, [0x04, 0x47, *nibbles(position, 4)], motion=Motion.ZOOM, zoom_position=position
    )


def digital_zoom(on: bool, address: int = 1) -> Request:
    """Digital zoom on/off; keep it off for geometry (above 0x4000 the image is a crop)."""
    return _command("digital_zoom", address, [0x04, 0x06, 0x02 if on else 0x03])


def focus_auto(address: int = 1) -> Request:
    return _command("focus_auto", address, [0x04, 0x38, 0x02], motion=Motion.FOCUS)


def focus_manual(address: int = 1) -> Request:
    return _command("focus_manual", address, [0x04, 0x38, 0x03])


def focus_one_push(address: int = 1) -> Request:
    """One-push auto focus trigger ([?] for the RZ50)."""
    return _command("focus_one_push", address, [0x04, 0x18, 0x01], motion=Motion.FOCUS)


def power(on: bool, address: int = 1) -> Request:
    return _command("power", address, [0x04, 0x00, 0x02 if on else 0x03])


def command_cancel(socket: int, address: int = 1) -> Request:
    """CommandCancel ``8x 2y FF``: answered ``6y 04`` (cancelled) or ``6y 05`` (no socket)."""
    y = _check_int("socket", socket, 1, 0x0F)
    return Request("command_cancel", bytes([_header(address), 0x20 | y, 0xFF]), ReplyKind.CANCEL, socket=y)


def pan_tilt_position_inquiry(address: int = 1) -> Request:
    return _inquiry("pan_tilt_position_inq", address, [0x06, 0x12], (8, 9))


def pan_tilt_max_speed_inquiry(address: int = 1) -> Request:
    return _inquiry("pan_tilt_max_speed_inq", address, [0x06, 0x11], (2,))


def zoom_position_inquiry(address: int = 1) -> Request:
    return _inquiry("zoom_position_inq", address, [0x04, 0x47], (4,))


def focus_mode_inquiry(address: int = 1) -> Request:
    return _inquiry("focus_mode_inq", address, [0x04, 0x38], (1,))


def power_inquiry(address: int = 1) -> Request:
    return _inquiry("power_inq", address, [0x04, 0x00], (1,))


def digital_zoom_inquiry(address: int = 1) -> Request:
    return _inquiry("digital_zoom_inq", address, [0x04, 0x06], (1,))


def version_inquiry(address: int = 1) -> Request:
    """CAM_VersionInq ``8x 09 00 02 FF`` (whether the RZ50 answers is [?])."""
    return _inquiry("version_inq", address, [0x00, 0x02], (7,))


# --------------------------------------------------------------------------------------------
# Inquiry answer decoding


class PanTiltLayout(enum.Enum):
    FOUR_FOUR = "4+4"  # RZ30/RZ50/EVI-D70 generation: 11-byte answer
    FIVE_FOUR = "5+4"  # newer BRC/SRG cameras and clones: 12-byte answer


@dataclass(frozen=True)
class PanTiltPosition:
    pan_counts: int
    tilt_counts: int
    layout: PanTiltLayout


@dataclass(frozen=True)
class MaxSpeed:
    pan: int
    tilt: int


class FocusMode(enum.Enum):
    AUTO = 0x02
    MANUAL = 0x03
    UNKNOWN = -1


class PowerState(enum.Enum):
    ON = 0x02
    OFF = 0x03
    UNKNOWN = -1


@dataclass(frozen=True)
class Version:
    vendor: int
    model: int
    rom_version: int
    sockets: int


def _expect_len(answer: InquiryAnswer, lengths: tuple[int, ...], what: str) -> bytes:
    if len(answer.data) not in lengths:
        raise ViscaProtocolError(
            f"{what} answer has {len(answer.data)} data bytes, expected {' or '.join(map(str, lengths))}",
            raw=answer.raw,
        )
    return answer.data


def decode_pan_tilt_position(answer: InquiryAnswer) -> PanTiltPosition:
    """Both layouts, told apart by length (pitfall 1); every data byte must be a nibble."""
    data = _expect_len(answer, (8, 9), "pan-tilt position")
    try:
        if len(data) == 8:
            return PanTiltPosition(from_nibbles(data[:4], True), from_nibbles(data[4:], True), PanTiltLayout.FOUR_FOUR)
        return PanTiltPosition(from_nibbles(data[:5], True), from_nibbles(data[5:], True), PanTiltLayout.FIVE_FOUR)
    except ViscaProtocolError as exc:
        raise ViscaProtocolError(f"pan-tilt position: {exc}", raw=answer.raw) from exc


def decode_max_speed(answer: InquiryAnswer) -> MaxSpeed:
    data = _expect_len(answer, (2,), "pan-tilt max speed")
    if not (1 <= data[0] <= 0x7F and 1 <= data[1] <= 0x7F):
        raise ViscaProtocolError(f"max speed out of range: {data.hex(' ')}", raw=answer.raw)
    return MaxSpeed(data[0], data[1])


def decode_zoom_position(answer: InquiryAnswer) -> int:
    data = _expect_len(answer, (4,), "zoom position")
    try:
        return from_nibbles(data, False)
    except ViscaProtocolError as exc:
        raise ViscaProtocolError(f"zoom position: {exc}", raw=answer.raw) from exc


def _mode_byte(answer: InquiryAnswer, what: str) -> int:
    return _expect_len(answer, (1,), what)[0]


def decode_focus_mode(answer: InquiryAnswer) -> FocusMode:
    byte = _mode_byte(answer, "focus mode")
    return FocusMode(byte) if byte in (0x02, 0x03) else FocusMode.UNKNOWN


def decode_power(answer: InquiryAnswer) -> PowerState:
    byte = _mode_byte(answer, "power")
    return PowerState(byte) if byte in (0x02, 0x03) else PowerState.UNKNOWN


def decode_on_off(answer: InquiryAnswer, what: str = "mode") -> bool:
    byte = _mode_byte(answer, what)
    if byte not in (0x02, 0x03):
        raise ViscaProtocolError(f"{what} answer 0x{byte:02X} is neither on (02) nor off (03)", raw=answer.raw)
    return byte == 0x02


def decode_version(answer: InquiryAnswer) -> Version:
    d = _expect_len(answer, (7,), "version")
    return Version(vendor=d[0] << 8 | d[1], model=d[2] << 8 | d[3], rom_version=d[4] << 8 | d[5], sockets=d[6])
