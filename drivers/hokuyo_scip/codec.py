"""SCIP 2.0 codec for the Hokuyo UTM-30LX: bytes in, typed events out; commands to bytes. Sans-I/O.

No port, no clock, no threads: :class:`ScipDecoder` is fed whatever the transport delivered (any
split or merge of the stream) and returns frozen events; the ``build_*`` functions make request
bytes. Reference: ``shared/protocols/scip2_utm30lx.md`` (the fact sheet) and the real recorded
session in ``shared/data/hokuyo_utm30lx_session/``.

Framing: every reply is ``echo LF status(2)+sum LF payload-lines LF``; the empty line (two LFs in a
row) ends it. CR and CR+LF are accepted as line ends too. Every checksum is checked: the status
line, each ``KEY:value;S`` info line (sum over ``KEY:value``, the ``;`` excluded; for a line
holding ``<-`` the sum over the text before ``<-`` is accepted as a fallback and flagged, the
UTM-30LX II quirk), the timestamp line and every data line. A reply that fails any check becomes a
:class:`DecodeError` event carrying a typed :class:`~drivers.hokuyo_scip.errors.ScipProtocolError`
and the raw bytes; decoding goes on with the next reply (resynchronising on the next echo line
followed by a valid status line when two replies were merged by a lost line end).

Junk glued to an echo (no line end between them) can itself look like an echo with a tag (``CR00;``
before ``MD...``, ``QT;`` before ``CR00``). The client tells the decoder every request it sends
(:meth:`ScipDecoder.sent`); the decoder then takes the longest tail of the line that echoes a request
sent (a stream request's frames echo it with the count replaced) and drops the rest as junk; a
decoder told nothing (a recording) judges by the echo grammar. A line where a reply must start but
that holds no echo of a SCIP command (``DM1``) is junk up to the next reply start, and a reply that
has no payload (BM, QT, RS, RT, RB, SS, CR, HS) never takes the lines after its status as payload: a
reply merged into it is decoded on its own.

Status codes stay two-character strings; :func:`status_for` maps them per command to a
:class:`StatusMeaning` with a success flag (``00`` everywhere, ``99`` in scan frames, BM ``02``,
TM ``02``/``03``, SS/CR ``03``, HS ``02``), with :attr:`StatusMeaning.UNKNOWN` as fallback. They
are never converted with ``int()``.
"""

from __future__ import annotations

import enum
import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from .errors import ScipChecksumError, ScipConfigError, ScipProtocolError

# --------------------------------------------------------------------------------------------
# Checksums and the 6-bit character encoding
# --------------------------------------------------------------------------------------------

_LF = 0x0A
_CHAR_OFFSET = 0x30
_CHAR_MAX = 0x6F
DATA_LINE_CHARS = 64  # data characters per full data line
TIMESTAMP_MODULUS = 1 << 24  # the ms counter is 24 bits wide
MAX_TAG_CHARS = 16
_TAG_RE = re.compile(r"[A-Za-z0-9 ._+@]{0,16}")


def checksum(content: bytes) -> int:
    """The SCIP sum character of ``content``: low 6 bits of the byte sum, plus 0x30."""
    return (sum(content) & 0x3F) + _CHAR_OFFSET


def encode_values(values: Iterable[int] | np.ndarray, width: int) -> bytes:
    """Encode non-negative integers in ``width`` (1..4) characters each, most significant first."""
    if not 1 <= width <= 4:
        raise ScipConfigError(f"encoding width must be 1..4 characters, got {width}")
    arr = np.asarray(values if isinstance(values, np.ndarray) else list(values), dtype=np.int64).ravel()
    if arr.size and (arr.min() < 0 or arr.max() >= (1 << (6 * width))):
        raise ScipConfigError(f"value out of range for {width}-character encoding")
    shifts = np.arange(width - 1, -1, -1, dtype=np.int64) * 6
    chars = ((arr[:, None] >> shifts[None, :]) & 0x3F) + _CHAR_OFFSET
    return chars.astype(np.uint8).tobytes()


def decode_values(chars: bytes | np.ndarray, width: int) -> np.ndarray:
    """Decode a concatenated run of ``width``-character values (vectorised) to ``uint32``.

    Raises :class:`ScipProtocolError` when the length is not a multiple of ``width`` or a
    character lies outside ``'0'..'o'``.
    """
    if not 1 <= width <= 4:
        raise ScipConfigError(f"encoding width must be 1..4 characters, got {width}")
    a = np.frombuffer(chars, dtype=np.uint8) if isinstance(chars, bytes | bytearray | memoryview) else chars
    if a.size % width:
        raise ScipProtocolError(f"{a.size} characters are not a whole number of {width}-character values")
    v = a.reshape(-1, width).astype(np.uint32)
    v -= _CHAR_OFFSET  # characters below '0' wrap to huge values and fail the range check below
    if v.size and int(v.max()) > 0x3F:
        raise ScipProtocolError("data character outside the SCIP range '0'..'o'", raw=bytes(a.tobytes()[:128]))
    if width == 1:
        return v[:, 0].copy()
    out = v[:, 0] << 6
    out |= v[:, 1]
    for k in range(2, width):
        out <<= 6
        out |= v[:, k]
    return out


def _decode_small(chars: bytes) -> int:
    """Decode a short value (the 4-character timestamp) without numpy."""
    value = 0
    for c in chars:
        d = c - _CHAR_OFFSET
        if not 0 <= d <= 0x3F:
            raise ScipProtocolError(f"character {bytes([c])!r} outside the SCIP range '0'..'o'", raw=chars)
        value = (value << 6) | d
    return value


def encode_data_block(chars: bytes) -> bytes:
    """Cut encoded data into 64-character lines, each followed by its sum and LF (no closing blank line)."""
    out = bytearray()
    for i in range(0, len(chars), DATA_LINE_CHARS):
        part = chars[i : i + DATA_LINE_CHARS]
        out += part
        out.append(checksum(part))
        out.append(_LF)
    return bytes(out)


def encode_timestamp_line(timestamp_ms: int) -> bytes:
    """The 4-character timestamp, its sum and LF."""
    chars = encode_values([timestamp_ms % TIMESTAMP_MODULUS], 4)
    return chars + bytes([checksum(chars), _LF])


# --------------------------------------------------------------------------------------------
# Status codes
# --------------------------------------------------------------------------------------------


class StatusMeaning(enum.Enum):
    OK = "ok"
    SCAN_DATA = "scan data follows"
    ALREADY_SET = "already in the requested state"
    LASER_FAULT = "laser cannot be switched on (laser fault)"
    LASER_OFF = "laser is off"
    PARAMETER_ERROR = "parameter error"
    NOT_IN_TIME_MODE = "TM1 outside time-adjust mode"
    NOT_SUPPORTED = "not supported by this model"
    REBOOT_ARMED = "reboot armed (send RB again)"
    PAUSED = "processing paused to check an error"
    HARDWARE_ERROR = "hardware trouble"
    RESUMED = "resumed after the laser checked normal"
    REPLY_BUILD_FAILED = "could not build the reply"
    BUSY = "buffer shortage or command repeated while busy"
    MISSING_PARAMETER = "missing parameters"
    UNDEFINED_COMMAND = "undefined command"
    TAG_TOO_LONG = "user string longer than 16 characters"
    TAG_INVALID = "user string has an invalid character"
    FIRMWARE_UPDATE = "sensor in firmware-update mode"
    ABNORMAL_STATE = "abnormal state"
    UNSTABLE = "unstable"
    DENIED = "denied"
    UNKNOWN = "unknown status"


@dataclass(frozen=True)
class Status:
    """A status as the sensor sent it (``code``, two characters) and what it means for its command."""

    code: str
    meaning: StatusMeaning
    success: bool

    @property
    def description(self) -> str:
        return f"{self.code} ({self.meaning.value})"


_GENERAL_CODES: dict[str, StatusMeaning] = {
    "0A": StatusMeaning.REPLY_BUILD_FAILED,
    "0B": StatusMeaning.BUSY,
    "0C": StatusMeaning.MISSING_PARAMETER,
    "0D": StatusMeaning.UNDEFINED_COMMAND,
    "0E": StatusMeaning.UNDEFINED_COMMAND,
    "0F": StatusMeaning.MISSING_PARAMETER,
    "0G": StatusMeaning.TAG_TOO_LONG,
    "0H": StatusMeaning.TAG_INVALID,
    "0I": StatusMeaning.FIRMWARE_UPDATE,
    "0L": StatusMeaning.ABNORMAL_STATE,
    "0M": StatusMeaning.UNSTABLE,
}

#: commands whose reply is an echo and a status only [SPEC]
_STATUS_ONLY_COMMANDS = frozenset({"BM", "QT", "RS", "RT", "RB", "SS", "CR", "HS"})
SCAN_COMMANDS = frozenset({"MD", "MS", "ME", "ND", "NE", "GD", "GS", "GE", "HD", "HE"})
STREAM_COMMANDS = frozenset({"MD", "MS", "ME", "ND", "NE"})

# command -> {code: (meaning, success)}; codes not here fall back to the general table, then UNKNOWN
_PER_COMMAND: dict[str, dict[str, tuple[StatusMeaning, bool]]] = {
    "BM": {"01": (StatusMeaning.LASER_FAULT, False), "02": (StatusMeaning.ALREADY_SET, True)},
    "TM": {
        "01": (StatusMeaning.PARAMETER_ERROR, False),
        "02": (StatusMeaning.ALREADY_SET, True),  # TM0 while already in time-adjust mode
        "03": (StatusMeaning.ALREADY_SET, True),  # TM2 while not in time-adjust mode
        "04": (StatusMeaning.NOT_IN_TIME_MODE, False),
    },
    "SS": {
        "01": (StatusMeaning.PARAMETER_ERROR, False),
        "02": (StatusMeaning.PARAMETER_ERROR, False),
        "03": (StatusMeaning.ALREADY_SET, True),
        "04": (StatusMeaning.NOT_SUPPORTED, False),
    },
    "CR": {
        "01": (StatusMeaning.PARAMETER_ERROR, False),
        "02": (StatusMeaning.PARAMETER_ERROR, False),
        "03": (StatusMeaning.ALREADY_SET, True),
        "04": (StatusMeaning.NOT_SUPPORTED, False),
    },
    "HS": {
        "01": (StatusMeaning.PARAMETER_ERROR, False),
        "02": (StatusMeaning.ALREADY_SET, True),
        "03": (StatusMeaning.NOT_SUPPORTED, False),
    },
    "RB": {"01": (StatusMeaning.REBOOT_ARMED, True)},
}


def _two_digits_between(code: str, low: str, high: str) -> bool:
    """String comparison of two decimal digits (no int(): letter codes never count as numbers)."""
    return len(code) == 2 and code.isascii() and code.isdigit() and low <= code <= high


def status_for(command: str, code: str) -> Status:
    """Map a raw status ``code`` to its meaning for ``command`` (``"MD"``, ``"TM"``, ``"%ST"``, ...)."""
    if code == "00":
        return Status(code, StatusMeaning.OK, True)
    if code == "99":
        ok = command in STREAM_COMMANDS
        return Status(code, StatusMeaning.SCAN_DATA if ok else StatusMeaning.UNKNOWN, ok)
    specific = _PER_COMMAND.get(command, {}).get(code)
    if specific is not None:
        return Status(code, specific[0], specific[1])
    general = _GENERAL_CODES.get(code)
    if general is not None:
        return Status(code, general, False)
    if command in SCAN_COMMANDS:
        if _two_digits_between(code, "01", "07"):
            return Status(code, StatusMeaning.PARAMETER_ERROR, False)
        if code == "10":
            return Status(code, StatusMeaning.LASER_OFF, False)
        if _two_digits_between(code, "21", "49"):
            return Status(code, StatusMeaning.PAUSED, False)
        if _two_digits_between(code, "50", "97"):
            return Status(code, StatusMeaning.HARDWARE_ERROR, False)
        if code == "98":
            return Status(code, StatusMeaning.RESUMED, False)
    if code == "10":
        return Status(code, StatusMeaning.DENIED, False)
    return Status(code, StatusMeaning.UNKNOWN, False)


# --------------------------------------------------------------------------------------------
# Typed sensor information
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class VersionInfo:
    """The VV reply."""

    vendor: str
    product: str
    firmware: str
    protocol: str
    serial: str


@dataclass(frozen=True)
class SensorParameters:
    """The PP reply (device units) with derived SI quantities."""

    model: str
    dmin_mm: int
    dmax_mm: int
    ares: int  # steps per full revolution
    amin: int  # first measurable step
    amax: int  # last measurable step
    afrt: int  # front step
    scan_rpm: int

    @property
    def scan_period_s(self) -> float:
        return 60.0 / self.scan_rpm

    @property
    def step_angle_rad(self) -> float:
        return 2.0 * math.pi / self.ares

    @property
    def step_dt_s(self) -> float:
        """Time between two adjacent steps of the sweep."""
        return self.scan_period_s / self.ares

    @property
    def n_steps(self) -> int:
        return self.amax - self.amin + 1

    def step_bearing_rad(self, step: int | np.ndarray) -> float | np.ndarray:
        """Bearing of a step in the sensor frame (0 = front, counter-clockwise positive)."""
        return (np.asarray(step, dtype=np.float64) - self.afrt) * self.step_angle_rad

    def bearings_rad(self, start: int, end: int, cluster: int = 1) -> np.ndarray:
        """Bearings of the values a scan over ``start..end`` with ``cluster`` returns.

        A cluster's bearing is that of its first step (as urg_library's ``urg_index2rad``).
        """
        c = max(cluster, 1)
        steps = np.arange(start, end + 1, c, dtype=np.float64)
        return (steps - self.afrt) * self.step_angle_rad


@dataclass(frozen=True)
class SensorState:
    """The II reply."""

    model: str
    laser_on: bool | None  # None when the reply has no LASR line
    motor_speed: str
    measurement_mode: str
    bit_rate: str
    time_ms: int | None  # the 24-bit counter; None when the reply has no TIME line
    status_text: str


def _require(values: Mapping[str, str], key: str, command: str) -> str:
    try:
        return values[key]
    except KeyError:
        raise ScipProtocolError(f"{command} reply lacks the {key} line") from None


def _int_value(values: Mapping[str, str], key: str, command: str) -> int:
    text = _require(values, key, command)
    if not (text.isascii() and text.isdigit()):
        raise ScipProtocolError(f"{command} {key} is not a decimal number: {text!r}")
    return int(text)


def parse_version(values: Mapping[str, str]) -> VersionInfo:
    """VV by key. Keys other models leave out become "" (the VV layout differs across URG models)."""
    if not values:
        raise ScipProtocolError("VV reply has no info lines")
    return VersionInfo(
        vendor=values.get("VEND", ""),
        product=values.get("PROD", ""),
        firmware=values.get("FIRM", ""),
        protocol=values.get("PROT", ""),
        serial=values.get("SERI", ""),
    )


def parse_parameters(values: Mapping[str, str]) -> SensorParameters:
    p = SensorParameters(
        model=_require(values, "MODL", "PP"),
        dmin_mm=_int_value(values, "DMIN", "PP"),
        dmax_mm=_int_value(values, "DMAX", "PP"),
        ares=_int_value(values, "ARES", "PP"),
        amin=_int_value(values, "AMIN", "PP"),
        amax=_int_value(values, "AMAX", "PP"),
        afrt=_int_value(values, "AFRT", "PP"),
        scan_rpm=_int_value(values, "SCAN", "PP"),
    )
    if p.ares <= 0 or p.scan_rpm <= 0 or p.amax < p.amin or p.dmax_mm <= p.dmin_mm:
        raise ScipProtocolError(f"PP values are inconsistent: {p}")
    return p


def parse_state(values: Mapping[str, str]) -> SensorState:
    """II by key. The UTM-30LX sends 7 lines; some models send 4, so absent keys become "" / None."""
    if not values:
        raise ScipProtocolError("II reply has no info lines")
    time_text = values.get("TIME")
    time_ms: int | None = None
    if time_text is not None:
        try:
            time_ms = int(time_text, 16)
        except ValueError:
            raise ScipProtocolError(f"II TIME is not hexadecimal: {time_text!r}") from None
    laser = values.get("LASR")
    return SensorState(
        model=values.get("MODL", ""),
        laser_on=None if laser is None else laser.upper().startswith("ON"),
        motor_speed=values.get("SCSP", ""),
        measurement_mode=values.get("MESM", ""),
        bit_rate=values.get("SBPS", ""),
        time_ms=time_ms,
        status_text=values.get("STAT", ""),
    )


# --------------------------------------------------------------------------------------------
# Events
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Reply:
    """Common part of every decoded reply."""

    echo: str  # the request line as echoed (for scan frames: with the remaining count)
    command: str  # "VV", "MD", "TM", "%ST", ...
    status: Status


@dataclass(frozen=True)
class StatusReply(Reply):
    """A reply without data: BM, QT, RS, RT, TM0/TM2, CR, SS, the MD/ME acknowledgement, errors."""

    payload: tuple[bytes, ...] = ()


@dataclass(frozen=True)
class VersionReply(Reply):
    values: Mapping[str, str]
    info: VersionInfo
    checksum_fallback_keys: tuple[str, ...] = ()


@dataclass(frozen=True)
class ParametersReply(Reply):
    values: Mapping[str, str]
    info: SensorParameters
    checksum_fallback_keys: tuple[str, ...] = ()


@dataclass(frozen=True)
class StateReply(Reply):
    values: Mapping[str, str]
    info: SensorState
    #: keys whose line matched only with the II ``<-`` fallback (a warning, not an error)
    checksum_fallback_keys: tuple[str, ...] = ()


@dataclass(frozen=True)
class TimeReply(Reply):
    """TM1: the sensor's 24-bit millisecond counter."""

    timestamp_ms: int


@dataclass(frozen=True)
class ScanRequest:
    """The parameters of a scan command, as parsed from its echo."""

    command: str
    start: int
    end: int
    cluster: int
    interval: int | None = None  # streams only
    count: int | None = None  # streams only: the count field as echoed (remaining in frames)
    tag: str = ""

    @property
    def n_values(self) -> int:
        return -(-(self.end - self.start + 1) // max(self.cluster, 1))

    @property
    def with_intensity(self) -> bool:
        return self.command in ("ME", "GE")

    @property
    def value_width(self) -> int:
        return 2 if self.command in ("MS", "GS") else 3


@dataclass(frozen=True, eq=False)
class ScanFrame(Reply):
    """One scan (GD/GS/GE reply or one MD/MS/ME frame). Distances are raw device codes in mm:
    values below DMIN are error codes, not ranges (the client turns them into NaN)."""

    request: ScanRequest
    timestamp_ms: int
    distances: np.ndarray  # uint32, read-only
    intensities: np.ndarray | None = None  # uint32, read-only (ME/GE)

    @property
    def remaining(self) -> int | None:
        """Scans still to come in this MD/ME run (the echo's last field); None for GD/GE."""
        return self.request.count


class DecodeErrorKind(enum.Enum):
    CHECKSUM = "checksum"
    LAYOUT = "layout"
    GARBAGE = "garbage"
    OVERFLOW = "overflow"


@dataclass(frozen=True)
class DecodeError:
    """Bytes that were not a valid reply; they were dropped. ``error`` is the typed error."""

    kind: DecodeErrorKind
    error: ScipProtocolError
    raw: bytes
    command: str = ""  # the command the dropped reply seemed to answer, when known

    @property
    def message(self) -> str:
        return str(self.error)


Event = StatusReply | VersionReply | ParametersReply | StateReply | TimeReply | ScanFrame | DecodeError

# --------------------------------------------------------------------------------------------
# Request builders
# --------------------------------------------------------------------------------------------

_MAX_ECHO_CHARS = 32
_ECHO_RE = re.compile(
    rb"(?:(?:MD|MS|ME|ND|NE)[0-9]{13}|(?:GD|GS|GE|HD|HE)[0-9]{10}|TM[0-9]|VV|PP|II|BM|QT|RS|RT|RB"
    rb"|SS[0-9]{6}|CR[0-9]{2}|HS[0-9]|DB[0-9]{2}|%ST|%SL)(?:;[A-Za-z0-9 ._+@]{0,16})?"
)

#: the shape of any command line: 2 letters (3 with '%'), digits, an optional tag
_ANY_ECHO_RE = re.compile(rb"%?[A-Z]{2}[0-9]*(?:;[A-Za-z0-9 ._+@]{0,16})?")


def _check_tag(tag: str | None) -> str:
    if tag is None or tag == "":
        return ""
    if len(tag) > MAX_TAG_CHARS or not _TAG_RE.fullmatch(tag):
        raise ScipConfigError(f"user string {tag!r}: at most 16 of letters, digits, space, '.', '_', '+', '@'")
    return ";" + tag


def build_command(command: str, params: str = "", tag: str | None = None) -> bytes:
    """``command`` + fixed-width ``params`` + optional ``;tag`` + LF."""
    text = command + params + _check_tag(tag)
    if not text.isascii() or "\n" in text or "\r" in text:
        raise ScipConfigError(f"command text must be one ASCII line: {text!r}")
    return text.encode("ascii") + b"\n"


def _check_range(name: str, value: int, low: int, high: int) -> None:
    if not isinstance(value, int) or not low <= value <= high:
        raise ScipConfigError(f"{name} must be an integer in {low}..{high}, got {value!r}")


def build_scan(
    start: int,
    end: int,
    cluster: int = 1,
    *,
    intensity: bool = False,
    stream: bool = True,
    interval: int = 0,
    count: int = 0,
    tag: str | None = None,
) -> bytes:
    """MD/ME (``stream``) or GD/GE request over steps ``start..end``.

    ``count`` 0 streams until QT; 1..99 asks for that many scans. ``interval`` skips that many
    scans between frames. The 2-character MS/GS forms are not offered: they cannot carry UTM-30LX
    ranges above 4095 mm.
    """
    _check_range("start", start, 0, 9999)
    _check_range("end", end, 0, 9999)
    if end < start:
        raise ScipConfigError(f"end {end} < start {start}")
    _check_range("cluster", cluster, 0, 99)
    if stream:
        _check_range("interval", interval, 0, 9)
        _check_range("count", count, 0, 99)
        cmd = "ME" if intensity else "MD"
        return build_command(cmd, f"{start:04d}{end:04d}{cluster:02d}{interval:01d}{count:02d}", tag)
    cmd = "GE" if intensity else "GD"
    return build_command(cmd, f"{start:04d}{end:04d}{cluster:02d}", tag)


def build_time_mode(code: int, tag: str | None = None) -> bytes:
    """TM0 (enter time-adjust mode), TM1 (read the clock), TM2 (leave)."""
    _check_range("TM code", code, 0, 2)
    return build_command("TM", str(code), tag)


def build_simple(command: str, tag: str | None = None) -> bytes:
    """VV, PP, II, BM, QT, RS, RT: commands without parameters."""
    if command not in ("VV", "PP", "II", "BM", "QT", "RS", "RT"):
        raise ScipConfigError(f"{command!r} is not a parameterless SCIP command this driver sends")
    return build_command(command, "", tag)


# --------------------------------------------------------------------------------------------
# Decoder
# --------------------------------------------------------------------------------------------


def parse_scan_echo(command: str, echo: bytes) -> ScanRequest:
    """Parse a scan command line (request or echo, without LF) into its fields."""
    body, _, tag = echo.partition(b";")
    digits = body[len(command) :]
    try:
        if not digits.isdigit():
            raise ValueError
        if command in STREAM_COMMANDS:
            if len(digits) != 13:
                raise ValueError
            return ScanRequest(
                command,
                int(digits[0:4]),
                int(digits[4:8]),
                int(digits[8:10]),
                int(digits[10:11]),
                int(digits[11:13]),
                tag.decode("ascii"),
            )
        if len(digits) != 10:
            raise ValueError
        return ScanRequest(command, int(digits[0:4]), int(digits[4:8]), int(digits[8:10]), tag=tag.decode("ascii"))
    except (ValueError, UnicodeDecodeError):
        raise ScipProtocolError(f"malformed {command} echo {echo!r}", raw=echo) from None


def _command_of(echo: bytes) -> str:
    n = 3 if echo[:1] == b"%" else 2
    return echo[:n].decode("ascii", "replace")


def _check_status_line(line: bytes) -> str:
    if len(line) != 3:
        raise ScipProtocolError(f"status line {line!r} is not 2 characters plus a sum", raw=line)
    if checksum(line[:2]) != line[2]:
        raise ScipChecksumError(f"status line {line!r} fails its checksum", code=line[:2].decode("latin-1"), raw=line)
    code = line[:2]
    if not code.isascii() or not code.isalnum():
        raise ScipProtocolError(f"status {code!r} is not two letters or digits", raw=line)
    return code.decode("ascii")


def _check_plain_line(line: bytes, what: str) -> bytes:
    """A payload line whose sum covers every character before it; returns the content."""
    if len(line) < 2:
        raise ScipProtocolError(f"{what} line {line!r} too short", raw=line)
    if checksum(line[:-1]) != line[-1]:
        raise ScipChecksumError(f"{what} line {line!r} fails its checksum", raw=line)
    return line[:-1]


def _decode_timestamp_line(line: bytes) -> int:
    if len(line) != 5:
        raise ScipProtocolError(f"timestamp line {line!r} is not 4 characters plus a sum", raw=line)
    content = _check_plain_line(line, "timestamp")
    return _decode_small(content)


def _parse_info_lines(command: str, lines: list[bytes]) -> tuple[dict[str, str], tuple[str, ...]]:
    values: dict[str, str] = {}
    fallback: list[str] = []
    for line in lines:
        if len(line) < 3 or line[-2:-1] != b";":
            raise ScipProtocolError(f"{command} info line {line!r} lacks ';' and a sum", raw=line)
        content = line[:-2]
        if checksum(content) != line[-1]:
            cut = content.find(b"<-")
            if cut >= 0 and checksum(content[:cut]) == line[-1]:
                fallback.append(content.partition(b":")[0].decode("ascii", "replace"))
            else:
                raise ScipChecksumError(f"{command} info line {line!r} fails its checksum", raw=line)
        key, sep, value = content.partition(b":")
        if not sep:
            raise ScipProtocolError(f"{command} info line {line!r} has no 'KEY:'", raw=line)
        try:
            values[key.decode("ascii")] = value.decode("ascii")
        except UnicodeDecodeError:
            raise ScipProtocolError(f"{command} info line {line!r} is not ASCII", raw=line) from None
    return values, tuple(fallback)


def _join_data_lines(lines: list[bytes]) -> np.ndarray:
    """Check every data line's length and sum (vectorised) and return the concatenated characters."""
    if not lines:
        raise ScipProtocolError("scan reply has no data lines")
    full = lines[:-1]
    last = lines[-1]
    parts: list[np.ndarray] = []
    width = DATA_LINE_CHARS + 1
    if full:
        joined = b"".join(full)
        if len(joined) != width * len(full):
            bad = next(i for i, line in enumerate(full) if len(line) != width)
            raise ScipProtocolError(
                f"data line {bad} has {len(full[bad]) - 1} characters, not {DATA_LINE_CHARS}", raw=full[bad]
            )
        a = np.frombuffer(joined, dtype=np.uint8).reshape(-1, width)
        d = a[:, :DATA_LINE_CHARS]
        sums = (d.sum(axis=1, dtype=np.uint32) & 0x3F) + _CHAR_OFFSET
        bad_rows = np.flatnonzero(sums != a[:, DATA_LINE_CHARS])
        if bad_rows.size:
            i = int(bad_rows[0])
            raise ScipChecksumError(f"data line {i} fails its checksum", raw=full[i])
        parts.append(d.reshape(-1))
    if not 2 <= len(last) <= width:
        raise ScipProtocolError(f"last data line has {len(last) - 1} characters", raw=last)
    parts.append(np.frombuffer(_check_plain_line(last, "data"), dtype=np.uint8))
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def _decode_scan_data(request: ScanRequest, lines: list[bytes], status: Status, echo: str) -> ScanFrame:
    if len(lines) < 2:
        raise ScipProtocolError(f"{request.command} frame lacks its timestamp or data lines")
    timestamp_ms = _decode_timestamp_line(lines[0])
    chars = _join_data_lines(lines[1:])
    n = request.n_values
    width = request.value_width
    per_step = 2 * width if request.with_intensity else width
    if chars.size != n * per_step:
        raise ScipProtocolError(
            f"{request.command} frame holds {chars.size} characters, expected {n} values x {per_step}"
        )
    values = decode_values(chars, width)
    if request.with_intensity:
        pairs = values.reshape(-1, 2)
        distances = np.ascontiguousarray(pairs[:, 0])
        intensities: np.ndarray | None = np.ascontiguousarray(pairs[:, 1])
        intensities.setflags(write=False)
    else:
        distances = values
        intensities = None
    distances.setflags(write=False)
    return ScanFrame(echo, request.command, status, request, timestamp_ms, distances, intensities)


def _decode_reply(lines: list[bytes]) -> Event:
    """Decode one reply given as its lines (without LFs, without the closing empty line)."""
    if len(lines) < 2:
        raise ScipProtocolError("reply shorter than an echo and a status line", raw=b"\n".join(lines))
    echo_b = lines[0]
    try:
        echo = echo_b.decode("ascii")
    except UnicodeDecodeError:
        raise ScipProtocolError(f"echo {echo_b!r} is not ASCII", raw=echo_b) from None
    if not echo or not echo.isprintable():
        raise ScipProtocolError(f"echo {echo_b!r} is empty or not printable", raw=echo_b)
    command = _command_of(echo_b)
    code = _check_status_line(lines[1])
    status = status_for(command, code)
    payload = lines[2:]
    if command in ("VV", "PP", "II") and status.success:
        values, fallback = _parse_info_lines(command, payload)
        if command == "VV":
            return VersionReply(echo, command, status, values, parse_version(values), fallback)
        if command == "PP":
            return ParametersReply(echo, command, status, values, parse_parameters(values), fallback)
        return StateReply(echo, command, status, values, parse_state(values), fallback)
    if command == "TM" and echo_b[:3] == b"TM1" and code == "00":
        if len(payload) != 1:
            raise ScipProtocolError(f"TM1 reply has {len(payload)} payload lines, expected 1")
        return TimeReply(echo, command, status, _decode_timestamp_line(payload[0]))
    if command in SCAN_COMMANDS and payload:
        if command in ("ND", "NE", "HD", "HE"):
            raise ScipProtocolError(f"multi-echo {command} data is not supported by this driver")
        is_frame = code == "99" if command in STREAM_COMMANDS else code == "00"
        if not is_frame:
            raise ScipProtocolError(f"{command} reply with status {code} carries data", code=code)
        request = parse_scan_echo(command, echo_b)
        return _decode_scan_data(request, payload, status, echo)
    if command in SCAN_COMMANDS and code == "99":
        raise ScipProtocolError(f"{command} scan frame without data", code=code)
    if command in _STATUS_ONLY_COMMANDS and payload:  # another reply merged in: resynchronise on it
        raise ScipProtocolError(f"{command} reply carries {len(payload)} payload lines; it has none", code=code)
    checked = tuple(_check_plain_line(line, "payload") for line in payload)
    return StatusReply(echo, command, status, checked)


def _split_garbage(echo_line: bytes, sent: SentCommands | None = None) -> tuple[bytes, bytes]:
    """Split junk glued in front of an echo: (junk, echo). With ``sent``, the longest tail that echoes a
    command actually sent wins (junk can itself look like an echo with a tag: ``CR00;`` before
    ``MD...``, ``QT;`` before ``CR00``); otherwise the whole line if the echo grammar takes it, else the
    longest tail it takes. A line holding no echo is left whole."""
    # The longest echo is 32 characters ("MD" + 13 digits + ";" + 16); only the tail can hold it.
    first = max(0, len(echo_line) - _MAX_ECHO_CHARS)
    if sent is not None and sent:
        for start in range(first, len(echo_line) - 1):
            if sent.echoes(echo_line[start:]):
                return echo_line[:start], echo_line[start:]
    if _ECHO_RE.fullmatch(echo_line):
        return b"", echo_line
    for start in range(max(1, first), len(echo_line) - 1):
        if _ECHO_RE.fullmatch(echo_line, start):
            return echo_line[:start], echo_line[start:]
    return b"", echo_line


class SentCommands:
    """The request lines recently sent (bounded), so the decoder can tell an echo from junk that looks
    like one. A stream request (MD/ME...) is echoed by each of its frames with the last two digits
    replaced by the remaining count; those echoes match it too."""

    def __init__(self, keep: int = 32) -> None:
        self._lines: dict[bytes, None] = {}
        self._streams: dict[tuple[bytes, bytes], None] = {}
        self._keep = keep

    def __len__(self) -> int:
        return len(self._lines)

    def add(self, request: bytes) -> None:
        line = request.rstrip(b"\r\n")
        if not line:
            return
        for table, key in ((self._lines, line), (self._streams, self._stream_key(line))):
            if key is None:
                continue
            table.pop(key, None)  # type: ignore[arg-type]
            table[key] = None  # type: ignore[index]
            while len(table) > self._keep:
                del table[next(iter(table))]

    @staticmethod
    def _stream_key(line: bytes) -> tuple[bytes, bytes] | None:
        body, sep, tag = line.partition(b";")
        if body[:2].decode("latin-1") in STREAM_COMMANDS and len(body) == 15 and body[2:].isdigit():
            return body[:13], sep + tag
        return None

    def echoes(self, echo: bytes) -> bool:
        """Whether ``echo`` is the echo of a request sent (or of a frame of a stream request sent)."""
        if echo in self._lines:
            return True
        key = self._stream_key(echo)
        return key is not None and key in self._streams


def _looks_like_reply_start(lines: list[bytes], i: int) -> bool:
    if i + 1 >= len(lines):
        return False
    status = lines[i + 1]
    return (
        len(status) == 3
        and checksum(status[:2]) == status[2]
        and status[:2].isalnum()
        and _ECHO_RE.search(lines[i]) is not None
    )


def _error_kind(exc: ScipProtocolError) -> DecodeErrorKind:
    return DecodeErrorKind.CHECKSUM if isinstance(exc, ScipChecksumError) else DecodeErrorKind.LAYOUT


class ScipDecoder:
    """Incremental SCIP 2.0 reply decoder. ``feed(bytes)`` returns the events completed so far.

    It never raises on device input: every malformed reply becomes a :class:`DecodeError` event
    and decoding goes on. Unterminated input is kept (up to ``max_buffer_bytes``; beyond that it
    is dropped as an OVERFLOW error) until its closing empty line arrives.
    """

    def __init__(self, max_buffer_bytes: int = 1 << 20) -> None:
        if max_buffer_bytes < 1024:
            raise ScipConfigError("max_buffer_bytes must be at least 1024")
        self._buf = bytearray()
        self._search_from = 0
        self._pending_cr = False
        self._max = max_buffer_bytes
        self._sent = SentCommands()
        #: counters of what was decoded or dropped since construction
        self.replies = 0
        self.errors = 0

    @property
    def buffered(self) -> int:
        """Bytes waiting for the rest of their reply."""
        return len(self._buf)

    def sent(self, request: bytes) -> None:
        """Note a request line as sent (the client calls this for every request it writes). Once any
        was noted, junk glued to an echo is told apart by what was sent; a decoder told nothing (a
        recording) judges by the echo grammar alone."""
        self._sent.add(request)

    def reset(self) -> None:
        """Forget any partial reply (after a reconnect)."""
        self._buf.clear()
        self._search_from = 0
        self._pending_cr = False

    def feed(self, data: bytes) -> list[Event]:
        if data:
            if self._pending_cr and data[:1] == b"\n":
                data = data[1:]
            self._pending_cr = data[-1:] == b"\r"
            if b"\r" in data:
                data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
            self._buf += data
        events: list[Event] = []
        buf = self._buf
        while True:
            lead = 0
            while lead < len(buf) and buf[lead] == _LF:
                lead += 1
            if lead:
                del buf[:lead]
                self._search_from = 0
            end = buf.find(b"\n\n", self._search_from)
            if end < 0:
                self._search_from = max(0, len(buf) - 1)
                if len(buf) > self._max:
                    raw = bytes(buf)
                    buf.clear()
                    self._search_from = 0
                    self.errors += 1
                    err = ScipProtocolError(f"{len(raw)} bytes without a reply end; dropped", raw=raw[:256])
                    events.append(DecodeError(DecodeErrorKind.OVERFLOW, err, raw))
                break
            message = bytes(buf[:end])
            del buf[: end + 2]
            self._search_from = 0
            self._decode_message(message, events)
        return events

    def _decode_message(self, message: bytes, events: list[Event]) -> None:
        lines = message.split(b"\n")
        junk, echo = _split_garbage(lines[0], self._sent)
        if junk:
            self.errors += 1
            err = ScipProtocolError(f"{len(junk)} bytes of garbage before the echo {echo[:20]!r}", raw=junk)
            events.append(DecodeError(DecodeErrorKind.GARBAGE, err, junk))
            lines[0] = echo
        # A reply that lost its closing empty line runs into the next one; its echo line can pass as a
        # checksummed payload line (1 in 64), so split at every full echo followed by a valid status.
        cuts = [i for i in range(2, len(lines)) if self._reply_start_within(lines, i)]
        for a, b in zip([0, *cuts], [*cuts, len(lines)], strict=True):
            if a < b:
                self._decode_lines(lines[a:b], events)

    def _reply_start_within(self, lines: list[bytes], i: int) -> bool:
        """Line ``i`` of a message starts another reply: a full echo (or, once requests were noted, junk
        glued to the echo of one sent) followed by a valid status line."""
        if not _looks_like_reply_start(lines, i):
            return False
        if _ECHO_RE.fullmatch(lines[i]):
            return True
        if not self._sent:
            return False
        junk, echo = _split_garbage(lines[i], self._sent)
        if junk and self._sent.echoes(echo):
            lines[i] = echo  # the junk before it belonged to the reply before: dropped with it
            return True
        return False

    def _known_echo(self, lines: list[bytes], i: int) -> bool:
        """Line ``i`` can start a reply: the echo of a SCIP command (by grammar or as sent), or of a command
        the sensor does not know, answered as such (0D/0E; it never answers one with data)."""
        line = lines[i]
        if _ECHO_RE.fullmatch(line) or self._sent.echoes(line):
            return True
        return bool(_ANY_ECHO_RE.fullmatch(line)) and i + 1 < len(lines) and lines[i + 1][:2] in (b"0D", b"0E")

    def _decode_lines(self, lines: list[bytes], events: list[Event]) -> None:
        start = 0
        while start < len(lines):
            try:
                if not self._known_echo(lines, start):  # junk with line ends in it: "DM1", "00P", ...
                    # a reply that lost its head, or junk: dropped up to the next reply
                    raise ScipProtocolError(f"{lines[start][:40]!r} is no echo of a SCIP command", raw=lines[start])
                event = _decode_reply(lines[start:])
            except ScipProtocolError as exc:
                # Look for a later reply merged into this one (a lost line end or a truncated reply).
                nxt = next((i for i in range(start + 1, len(lines)) if _looks_like_reply_start(lines, i)), None)
                stop = len(lines) if nxt is None else nxt
                raw = b"\n".join(lines[start:stop])
                self.errors += 1
                cmd = _command_of(lines[start]) if lines[start] else ""
                events.append(DecodeError(_error_kind(exc), exc, raw, cmd))
                if nxt is None:
                    return
                junk, echo = _split_garbage(lines[nxt], self._sent)
                lines[nxt] = echo
                start = nxt
                continue
            self.replies += 1
            events.append(event)
            return
