"""Sans-I/O codec for the ARCOS/P2OS client-server protocol of the Pioneer 3-DX.

Frames (both directions, fact sheet section 1.2)::

    0xFA 0xFB | N | payload (N - 2 bytes, type/command byte first) | CHK_hi CHK_lo

``N`` is unsigned (3..255) and counts the payload plus the two checksum bytes. The checksum sums the
payload as big-endian 16-bit pairs mod 2**16, XORs a trailing odd byte into the low byte, and is
sent high byte first. Data integers are little-endian.

This module does no I/O, keeps no clock and runs no thread. :class:`Deframer` (and
:class:`ArcosDecoder` on top of it) takes bytes in whatever pieces they arrive and returns typed
events; the ``*_command`` functions build the bytes to send. Everything here is in device units
(counts, mm, mm/s, degrees, 4096ths of a revolution, decivolts); the client and the odometry
convert to SI. Bad input never raises out of ``feed``: it becomes a :class:`BadFrame` event and is
counted, and the deframer resynchronises by skipping only the two header bytes of a bad frame, so a
junk run that looks like a header cannot cost the next good packet.
"""

from __future__ import annotations

import enum
import math
import struct
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from .errors import ArcosChecksumError, ArcosConfigError, ArcosProtocolError

HEADER = b"\xfa\xfb"
#: smallest and largest legal count byte (payload with at least the type byte, plus 2 checksum bytes)
MIN_COUNT = 3
MAX_COUNT = 255
#: frames this short carry a checksum equal to their own payload (``FA FB 03 XX 00 XX``), so the
#: checksum proves nothing: such a frame is refused when a checksum-valid frame starts inside it
WEAK_COUNT = 4

ARGINT = 0x3B  # non-negative integer, 2 bytes LE
ARGNINT = 0x1B  # negative integer, 2 bytes LE magnitude
ARGSTR = 0x2B  # length byte + characters

INT16_MAX = 32767

SIP_TYPES = frozenset({0x32, 0x33})
CONFIG_TYPE = 0x20
ENCODER_TYPE = 0x90
IO_TYPE = 0xF0
RESET_TYPES = frozenset({0xFF, 0xFE})

#: VEL2 wheel-speed unit on the P3-DX (mm/s per VEL2 byte step), the ``Vel2Divisor`` of p3dx.p
VEL2_DIVISOR_MMPS = 20


class Command(enum.IntEnum):
    """Client command numbers (fact sheet section 1.5)."""

    SYNC0 = 0
    SYNC1 = 1
    SYNC2 = 2
    POLLING = 3
    ENABLE = 4
    SETA = 5
    SETV = 6
    SETO = 7
    MOVE = 8
    ROTATE = 9
    SETRV = 10
    VEL = 11
    HEAD = 12
    DHEAD = 13
    SAY = 15
    JOYINFO = 17
    CONFIG = 18
    ENCODER = 19
    RVEL = 21
    DCHEAD = 22
    SETRA = 23
    SONAR = 28
    STOP = 29
    DIGOUT = 30
    VEL2 = 32
    IOREQUEST = 40
    BUMPSTALL = 44
    HOSTBAUD = 50
    E_STOP = 55
    E_STALL = 56
    GYRO = 58
    BATTERYINFO = 62
    SOUND = 90
    SOUNDTOG = 92
    RESET = 253


# After OPEN the handshake ids are reused:
PULSE = Command.SYNC0
OPEN = Command.SYNC1
CLOSE = Command.SYNC2

#: HOSTBAUD argument per baud rate
HOSTBAUD_CODES: dict[int, int] = {9600: 0, 19200: 1, 38400: 2, 57600: 3, 115200: 4}


# --------------------------------------------------------------------------------------------
# checksum and framing


def checksum(payload: bytes | bytearray | memoryview) -> int:
    """The ARCOS checksum of a payload (type byte onwards, checksum bytes excluded)."""
    c = 0
    n = len(payload)
    for i in range(0, n - 1, 2):
        c = (c + ((payload[i] << 8) | payload[i + 1])) & 0xFFFF
    if n & 1:
        c ^= payload[n - 1]
    return c


def frame(payload: bytes | bytearray) -> bytes:
    """Wrap a payload (type/command byte first) into a complete frame."""
    if not 1 <= len(payload) <= MAX_COUNT - 2:
        raise ArcosConfigError(f"payload must be 1..{MAX_COUNT - 2} bytes, got {len(payload)}")
    c = checksum(payload)
    return HEADER + bytes((len(payload) + 2,)) + bytes(payload) + bytes((c >> 8, c & 0xFF))


# --------------------------------------------------------------------------------------------
# command builders (device units)


def _command_id(command: int) -> int:
    if not 0 <= int(command) <= 255:
        raise ArcosConfigError(f"command number must be 0..255, got {command}")
    return int(command)


def command(cmd: int) -> bytes:
    """A command without argument (SYNC0/PULSE, OPEN, CLOSE, SETO, STOP, E_STOP, ...)."""
    return frame(bytes((_command_id(cmd),)))


def int_command(cmd: int, value: int) -> bytes:
    """A command with a signed integer argument: 0x3B + value, or 0x1B + magnitude when negative.

    ``value`` must be an int in -32767..32767 (ARIA overflows at -32768; we refuse it).
    """
    if isinstance(value, bool) or not isinstance(value, int):
        raise ArcosConfigError(f"integer argument expected, got {value!r}")
    if not -INT16_MAX <= value <= INT16_MAX:
        raise ArcosConfigError(f"argument {value} is outside -32767..32767")
    arg_type = ARGINT if value >= 0 else ARGNINT
    return frame(bytes((_command_id(cmd), arg_type)) + struct.pack("<H", abs(value)))


def str_command(cmd: int, data: bytes) -> bytes:
    """A command with a string argument: 0x2B, a length byte, then the characters."""
    if len(data) > MAX_COUNT - 2 - 3:
        raise ArcosConfigError(f"string argument too long ({len(data)} bytes)")
    return frame(bytes((_command_id(cmd), ARGSTR, len(data))) + bytes(data))


def clamp_int16(value: float) -> int:
    """Round to the nearest integer and clamp to the legal argument range +-32767."""
    if not math.isfinite(value):
        raise ArcosConfigError(f"argument must be finite, got {value}")
    return max(-INT16_MAX, min(INT16_MAX, round(value)))


def sync_command(step: int) -> bytes:
    if step not in (0, 1, 2):
        raise ArcosConfigError(f"sync step must be 0, 1 or 2, got {step}")
    return command(step)


def pulse_command() -> bytes:
    return command(PULSE)


def open_command() -> bytes:
    return command(OPEN)


def close_command() -> bytes:
    return command(CLOSE)


def enable_command(on: bool) -> bytes:
    return int_command(Command.ENABLE, 1 if on else 0)


def vel_command(v_mmps: float) -> bytes:
    """VEL: translational velocity, mm/s (rounded, clamped to +-32767)."""
    return int_command(Command.VEL, clamp_int16(v_mmps))


def rvel_command(w_degps: float) -> bytes:
    """RVEL: rotational velocity in whole deg/s (the protocol's resolution), CCW positive."""
    return int_command(Command.RVEL, clamp_int16(w_degps))


def vel2_value(left_mmps: float, right_mmps: float, divisor_mmps: int = VEL2_DIVISOR_MMPS) -> int:
    """The signed 16-bit VEL2 argument: high byte left, low byte right, each a signed byte of ``divisor`` mm/s."""
    if divisor_mmps <= 0:
        raise ArcosConfigError(f"VEL2 divisor must be positive, got {divisor_mmps}")

    def wheel(v: float) -> int:
        if not math.isfinite(v):
            raise ArcosConfigError(f"wheel speed must be finite, got {v}")
        return max(-128, min(127, round(v / divisor_mmps))) & 0xFF

    raw = (wheel(left_mmps) << 8) | wheel(right_mmps)
    return raw - 0x10000 if raw >= 0x8000 else raw


def vel2_command(left_mmps: float, right_mmps: float, divisor_mmps: int = VEL2_DIVISOR_MMPS) -> bytes:
    """VEL2: independent wheel speeds. A negative combined value goes out as 0x1B + two's-complement magnitude."""
    value = vel2_value(left_mmps, right_mmps, divisor_mmps)
    if value == -32768:
        # 0x8000: left -128, right 0. The magnitude 32768 still fits the 2 argument bytes.
        return frame(bytes((Command.VEL2, ARGNINT)) + struct.pack("<H", 32768))
    return int_command(Command.VEL2, value)


def seta_command(accel_mmps2: float) -> bytes:
    """SETA: translational acceleration (+) or deceleration (-), mm/s^2."""
    return int_command(Command.SETA, clamp_int16(accel_mmps2))


def setv_command(vmax_mmps: float) -> bytes:
    """SETV: maximum translational velocity, mm/s (non-negative)."""
    if vmax_mmps < 0:
        raise ArcosConfigError(f"SETV needs a non-negative speed, got {vmax_mmps}")
    return int_command(Command.SETV, clamp_int16(vmax_mmps))


def setrv_command(wmax_degps: float) -> bytes:
    """SETRV: maximum rotational velocity, deg/s (non-negative)."""
    if wmax_degps < 0:
        raise ArcosConfigError(f"SETRV needs a non-negative rate, got {wmax_degps}")
    return int_command(Command.SETRV, clamp_int16(wmax_degps))


def setra_command(accel_degps2: float) -> bytes:
    """SETRA: rotational acceleration (+) or deceleration (-), deg/s^2."""
    return int_command(Command.SETRA, clamp_int16(accel_degps2))


def seto_command() -> bytes:
    """SETO: reset the controller's odometry to (0, 0, 0); sent without argument."""
    return command(Command.SETO)


def stop_command() -> bytes:
    return command(Command.STOP)


def e_stop_command() -> bytes:
    return command(Command.E_STOP)


def config_command() -> bytes:
    return int_command(Command.CONFIG, 1)


def encoder_command(mode: int) -> bytes:
    """ENCODER: > 0 starts the 0x90 stream (ARIA uses 2), 0 stops it."""
    return int_command(Command.ENCODER, mode)


def sonar_command(on: bool) -> bytes:
    return int_command(Command.SONAR, 1 if on else 0)


def hostbaud_command(baudrate: int) -> bytes:
    if baudrate not in HOSTBAUD_CODES:
        raise ArcosConfigError(f"HOSTBAUD supports {sorted(HOSTBAUD_CODES)}, got {baudrate}")
    return int_command(Command.HOSTBAUD, HOSTBAUD_CODES[baudrate])


def head_command(heading_deg: float) -> bytes:
    """HEAD: turn to an absolute odometric heading, degrees 0..359."""
    return int_command(Command.HEAD, round(heading_deg) % 360)


def battery_info_command(mode: int) -> bytes:
    return int_command(Command.BATTERYINFO, mode)


# --------------------------------------------------------------------------------------------
# events


class BadFrameKind(enum.Enum):
    CHECKSUM = "checksum"
    COUNT = "count"  # count byte below 3
    TRUNCATED = "truncated"  # header seen, body never completed (expired by the caller)
    PAYLOAD = "payload"  # checksum fine, payload does not fit its packet type
    OVERLAP = "overlap"  # a tiny frame whose bytes hold the header of a checksum-valid frame


@dataclass(frozen=True)
class BadFrame:
    """Bytes rejected by the deframer or the payload decoder (never silently dropped)."""

    kind: BadFrameKind
    reason: str
    raw: bytes


@dataclass(frozen=True)
class RawFrame:
    """A frame whose checksum verified; ``payload`` starts with the type byte."""

    payload: bytes

    @property
    def packet_type(self) -> int:
        return self.payload[0]


@dataclass(frozen=True)
class SyncEcho:
    """The server's echo of SYNC0 or SYNC1 (packet id 0 or 1)."""

    step: int
    extra: bytes = b""


@dataclass(frozen=True)
class RobotIdentity:
    """The SYNC2 reply: robot name, class (``Pioneer``) and subclass (``p3dx``, ``p3dx-sh``, ...).

    ``complete`` is False when fewer than three NUL-terminated strings came (missing ones are '').
    """

    name: str
    robot_class: str
    subclass: str
    complete: bool


@dataclass(frozen=True)
class SonarReading:
    index: int
    range_raw: int  # mm x RangeConvFactor


@dataclass(frozen=True)
class Sip:
    """Standard server information packet (0x32/0x33), in device units.

    Every field after ``sonars`` is optional firmware-dependent tail; it is None when the SIP ended
    before it. ``extra`` keeps unknown trailing bytes.
    """

    packet_type: int
    x_raw: int  # 15-bit counter (low 15 bits of XPOS), DistConvFactor mm per count
    y_raw: int
    th_raw: int  # signed THPOS as sent, 4096ths of a revolution
    left_vel_raw: int  # mm/s x VelConvFactor
    right_vel_raw: int
    battery_dv: int  # decivolts
    stall_bumpers: int
    control_raw: int
    flags: int
    compass_raw: int
    sonars: tuple[SonarReading, ...]
    grip_state: int | None = None
    anport: int | None = None
    analog: int | None = None
    digin: int | None = None
    digout: int | None = None
    battery_x10_dv: int | None = None
    charge_state: int | None = None
    rotvel_decidegps: int | None = None
    fault_flags: int | None = None
    latvel_raw: int | None = None
    temperature_c: int | None = None
    state_of_charge: int | None = None
    uc_time_ms: int | None = None
    flags3: int | None = None
    extra: bytes = b""

    @property
    def motors_enabled(self) -> bool:
        return bool(self.flags & 0x0001)

    @property
    def sonar_arrays_enabled(self) -> int:
        return (self.flags >> 1) & 0x0F

    @property
    def estop_pressed(self) -> bool:
        return bool(self.flags & 0x0020)

    @property
    def left_stall(self) -> bool:
        return bool(self.stall_bumpers & 0x0001)

    @property
    def right_stall(self) -> bool:
        return bool(self.stall_bumpers & 0x0100)

    @property
    def rear_bumpers(self) -> int:
        return (self.stall_bumpers >> 1) & 0x7F

    @property
    def front_bumpers(self) -> int:
        return (self.stall_bumpers >> 9) & 0x7F


@dataclass(frozen=True)
class EncoderPacket:
    """ENCODERpac (0x90): raw left and right encoder counts."""

    left_counts: int
    right_counts: int


@dataclass(frozen=True)
class IoPacket:
    """IOpac (0xF0): digital inputs, digital outputs (one byte per 8 lines) and raw analog values."""

    digital_in: bytes
    digital_out: bytes
    analog_raw: tuple[int, ...]


@dataclass(frozen=True)
class ResetPacket:
    """0xFF / 0xFE: the microcontroller reset; the session is gone."""

    packet_type: int


@dataclass(frozen=True)
class UnknownPacket:
    """A checksum-valid packet of a type this codec does not decode (kept raw)."""

    packet_type: int
    payload: bytes


# CONFIGpac layout, in ARIA's reader order (fact sheet section 1.7). Kinds: s = NUL-terminated
# string, B = u8, b = s8, H = u16, h = s16, I = u32.
CONFIG_LAYOUT: tuple[tuple[str, str], ...] = (
    ("robot_class", "s"), ("robot_subclass", "s"), ("serial_number", "s"),
    ("four_mots", "B"),
    ("rot_vel_top_degps", "H"), ("trans_vel_top_mmps", "H"), ("rot_accel_top_degps2", "H"),
    ("trans_accel_top_mmps2", "H"), ("pwm_max", "H"),
    ("name", "s"),
    ("sip_cycle_ms", "B"), ("host_baud", "B"), ("aux1_baud", "B"),
    ("has_gripper", "H"), ("front_sonar", "H"), ("rear_sonar", "B"),
    ("low_battery_dv", "H"), ("rev_count", "H"), ("watchdog_ms", "H"),
    ("normal_mpacs", "B"), ("stall_val", "H"), ("stall_count", "H"), ("joy_vel_mmps", "H"), ("joy_rot_vel_degps", "H"),
    ("rot_vel_max_degps", "H"), ("trans_vel_max_mmps", "H"), ("rot_accel_degps2", "H"), ("rot_decel_degps2", "H"),
    ("rot_kp", "H"), ("rot_kv", "H"), ("rot_ki", "H"),
    ("trans_accel_mmps2", "H"), ("trans_decel_mmps2", "H"), ("trans_kp", "H"), ("trans_kv", "H"), ("trans_ki", "H"),
    ("front_bumps", "B"), ("rear_bumps", "B"), ("charger", "B"), ("sonar_cycle_ms", "B"), ("reset_baud", "B"),
    ("gyro_type", "B"),
    ("drift_factor", "h"), ("aux2_baud", "B"), ("aux3_baud", "B"), ("ticks_mm", "H"), ("shutdown_voltage_dv", "H"),
    ("firmware_version", "s"),
    ("gyro_cw", "H"), ("gyro_ccw", "H"), ("kinematics_delay", "B"),
    ("lat_vel_top_mmps", "H"), ("lat_accel_top_mmps2", "H"), ("lat_vel_max_mmps", "H"), ("lat_accel_mmps2", "H"),
    ("lat_decel_mmps2", "H"),
    ("powerbot_charge_threshold", "H"), ("pdb_port", "B"), ("gyro_rate_limit", "H"),
    ("high_temp_shutdown", "b"), ("power_bits", "H"), ("battery_type", "B"), ("soc_low", "H"), ("soc_shutdown", "H"),
    ("bootloader_version", "s"), ("config_flags", "I"), ("gyro_fw_version", "h"),
)  # fmt: skip

_FIXED: dict[str, struct.Struct] = {k: struct.Struct("<" + k) for k in "BbHhI"}


@dataclass(frozen=True)
class ConfigPacket:
    """CONFIGpac (0x20). ``values`` holds every field that was present, by the names of CONFIG_LAYOUT.

    Fields beyond the end of a (shorter, older) packet are absent; ``extra`` keeps bytes beyond
    the known layout (newer firmware).
    """

    values: Mapping[str, int | str] = field(hash=False)
    extra: bytes = b""

    def __post_init__(self) -> None:
        object.__setattr__(self, "values", MappingProxyType(dict(self.values)))

    def get(self, name: str, default: int | str | None = None) -> int | str | None:
        return self.values.get(name, default)

    def int_value(self, name: str) -> int | None:
        v = self.values.get(name)
        return v if isinstance(v, int) else None


Event = (
    SyncEcho | RobotIdentity | Sip | ConfigPacket | EncoderPacket | IoPacket | ResetPacket | UnknownPacket | BadFrame
)


# --------------------------------------------------------------------------------------------
# payload decoders (raise ArcosProtocolError on a malformed payload)


def _strings(data: bytes, count: int) -> tuple[list[str], bool, int]:
    """Up to ``count`` NUL-terminated strings; returns them, whether all were terminated, bytes used."""
    out: list[str] = []
    pos = 0
    for _ in range(count):
        if pos >= len(data):
            return out, False, pos
        end = data.find(b"\x00", pos)
        if end < 0:
            out.append(data[pos:].decode("latin-1"))
            return out, False, len(data)
        out.append(data[pos:end].decode("latin-1"))
        pos = end + 1
    return out, True, pos


def decode_identity(payload: bytes) -> RobotIdentity:
    strings, complete, _ = _strings(payload[1:], 3)
    strings += [""] * (3 - len(strings))
    return RobotIdentity(name=strings[0], robot_class=strings[1], subclass=strings[2], complete=complete)


_SIP_HEAD = struct.Struct("<BHHhhhBHhHBB")  # type, x, y, th, lvel, rvel, battery, stall, control, flags, compass, n
_SONAR = struct.Struct("<BH")


def decode_sip(payload: bytes) -> Sip:
    if len(payload) < _SIP_HEAD.size:
        raise ArcosProtocolError(f"SIP too short: {len(payload)} bytes < {_SIP_HEAD.size}", raw=payload)
    (ptype, x, y, th, lvel, rvel, battery, stall, control, flags, compass, n) = _SIP_HEAD.unpack_from(payload)
    pos = _SIP_HEAD.size
    if pos + n * _SONAR.size > len(payload):
        raise ArcosProtocolError(
            f"SIP claims {n} sonar readings but has room for {(len(payload) - pos) // _SONAR.size}", raw=payload
        )
    sonars = tuple(SonarReading(*_SONAR.unpack_from(payload, pos + i * _SONAR.size)) for i in range(n))
    pos += n * _SONAR.size
    tail: dict[str, int] = {}
    for name, fmt in (
        ("grip_state", "B"), ("anport", "B"), ("analog", "B"), ("digin", "B"), ("digout", "B"),
        ("battery_x10_dv", "H"), ("charge_state", "B"), ("rotvel_decidegps", "h"), ("fault_flags", "H"),
        ("latvel_raw", "h"), ("temperature_c", "b"), ("state_of_charge", "B"), ("uc_time_ms", "I"), ("flags3", "I"),
    ):  # fmt: skip
        st = _FIXED[fmt]
        if pos + st.size > len(payload):
            break
        tail[name] = st.unpack_from(payload, pos)[0]
        pos += st.size
    return Sip(
        packet_type=ptype,
        x_raw=x & 0x7FFF,
        y_raw=y & 0x7FFF,
        th_raw=th,
        left_vel_raw=lvel,
        right_vel_raw=rvel,
        battery_dv=battery,
        stall_bumpers=stall,
        control_raw=control,
        flags=flags,
        compass_raw=compass,
        sonars=sonars,
        extra=bytes(payload[pos:]),
        **tail,  # type: ignore[arg-type]
    )


def decode_config(payload: bytes) -> ConfigPacket:
    values: dict[str, int | str] = {}
    pos = 1
    for name, kind in CONFIG_LAYOUT:
        if pos >= len(payload):
            break
        if kind == "s":
            strings, complete, used = _strings(payload[pos:], 1)
            if not complete:
                raise ArcosProtocolError(f"CONFIGpac string {name} is not NUL-terminated", raw=payload)
            values[name] = strings[0]
            pos += used
        else:
            st = _FIXED[kind]
            if pos + st.size > len(payload):
                raise ArcosProtocolError(f"CONFIGpac ends inside field {name}", raw=payload)
            values[name] = st.unpack_from(payload, pos)[0]
            pos += st.size
    if "name" not in values:
        raise ArcosProtocolError("CONFIGpac too short to hold the robot identity", raw=payload)
    return ConfigPacket(values=values, extra=bytes(payload[pos:]))


def decode_encoder(payload: bytes) -> EncoderPacket:
    if len(payload) < 9:
        raise ArcosProtocolError(f"ENCODERpac needs 9 bytes, got {len(payload)}", raw=payload)
    left, right = struct.unpack_from("<ii", payload, 1)
    return EncoderPacket(left_counts=left, right_counts=right)


def decode_io(payload: bytes) -> IoPacket:
    """u8 count + digital-in bytes, u8 count + digital-out bytes, u8 count + u16 analog values."""
    pos = 1
    parts: list[bytes] = []
    for what, width in (("digital inputs", 1), ("digital outputs", 1), ("analog values", 2)):
        if pos >= len(payload):
            raise ArcosProtocolError(f"IOpac ends before its {what} count", raw=payload)
        n = payload[pos]
        pos += 1
        if pos + n * width > len(payload):
            raise ArcosProtocolError(f"IOpac claims {n} {what} but is too short", raw=payload)
        parts.append(bytes(payload[pos : pos + n * width]))
        pos += n * width
    analog = tuple(struct.unpack(f"<{len(parts[2]) // 2}H", parts[2]))
    return IoPacket(digital_in=parts[0], digital_out=parts[1], analog_raw=analog)


def io_request_command(mode: int) -> bytes:
    """IOREQUEST: IOpac 0 stop / 1 once / 2 continuous (mind the bandwidth at 9600 baud)."""
    if mode not in (0, 1, 2):
        raise ArcosConfigError(f"IOREQUEST mode must be 0, 1 or 2, got {mode}")
    return int_command(Command.IOREQUEST, mode)


def decode_payload(payload: bytes) -> Event:
    """Decode one checksum-valid payload; raises :class:`ArcosProtocolError` if it is malformed."""
    if not payload:
        raise ArcosProtocolError("empty payload")
    ptype = payload[0]
    if ptype in (0, 1):
        return SyncEcho(step=ptype, extra=bytes(payload[1:]))
    if ptype == 2:
        return decode_identity(payload)
    if ptype in SIP_TYPES:
        return decode_sip(payload)
    if ptype == CONFIG_TYPE:
        return decode_config(payload)
    if ptype == ENCODER_TYPE:
        return decode_encoder(payload)
    if ptype == IO_TYPE:
        return decode_io(payload)
    if ptype in RESET_TYPES:
        return ResetPacket(packet_type=ptype)
    return UnknownPacket(packet_type=ptype, payload=bytes(payload))


def decode_frame(wire: bytes) -> Event:
    """Strictly decode exactly one complete frame (e.g. one recorded for replay).

    Raises :class:`ArcosChecksumError` on a checksum mismatch and :class:`ArcosProtocolError` on a
    bad header, count or length, or a malformed payload.
    """
    wire = bytes(wire)
    if len(wire) < MIN_COUNT + 3 or wire[:2] != HEADER:
        raise ArcosProtocolError("not an ARCOS frame (needs FA FB, a count and at least 1+2 bytes)", raw=wire)
    count = wire[2]
    if count < MIN_COUNT or len(wire) != count + 3:
        raise ArcosProtocolError(f"count byte {count} does not match a frame of {len(wire)} bytes", raw=wire)
    payload = wire[3:-2]
    sent = (wire[-2] << 8) | wire[-1]
    calc = checksum(payload)
    if sent != calc:
        raise ArcosChecksumError(f"checksum {sent:#06x} != computed {calc:#06x}", code=f"{sent:04X}", raw=wire)
    return decode_payload(payload)


# --------------------------------------------------------------------------------------------
# deframer


@dataclass
class DeframerStats:
    frames: int = 0
    junk_bytes: int = 0
    checksum_errors: int = 0
    count_errors: int = 0
    truncated: int = 0
    overlap_rejects: int = 0


def _embedded_frame(buf: bytearray, total: int) -> bool | None:
    """Does a checksum-valid frame start inside ``buf[1:total]``? None: not enough bytes yet to tell."""
    if len(buf) == total and buf[total - 1] == HEADER[0]:
        return None  # the last byte may be the first half of a header
    h = buf.find(HEADER, 1)
    while 0 < h < total:
        if h + 3 > len(buf):
            return None
        end = h + buf[h + 2] + 3
        if buf[h + 2] >= MIN_COUNT:
            if end > len(buf):
                return None
            body = bytes(buf[h + 3 : end - 2])
            if checksum(body) == (buf[end - 2] << 8) | buf[end - 1]:
                return True
        h = buf.find(HEADER, h + 1)
    return False


class Deframer:
    """Finds checksum-valid frames in a byte stream that may hold junk, splits and corruption.

    ``feed`` returns :class:`RawFrame` and :class:`BadFrame` items and never raises. A partial frame
    is kept across calls; a caller that sees no progress for a while (ARIA: 100 ms) calls
    :meth:`expire_partial` so a junk header with a large count cannot hold later frames back.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.stats = DeframerStats()

    @property
    def pending(self) -> int:
        """Bytes held back (a partial frame or a lone trailing 0xFA)."""
        return len(self._buf)

    def clear(self) -> None:
        self._buf.clear()

    def _junk(self, n: int) -> None:
        self.stats.junk_bytes += n
        del self._buf[:n]

    def feed(self, data: bytes | bytearray | memoryview) -> list[RawFrame | BadFrame]:
        self._buf += data
        return self._scan()

    def _scan(self) -> list[RawFrame | BadFrame]:
        out: list[RawFrame | BadFrame] = []
        buf = self._buf
        while True:
            start = buf.find(HEADER)
            if start < 0:
                # keep a trailing 0xFA: it may be the first half of a header
                keep = 1 if buf[-1:] == b"\xfa" else 0
                if len(buf) > keep:
                    self._junk(len(buf) - keep)
                return out
            if start:
                self._junk(start)
            if len(buf) < 3:
                return out
            count = buf[2]
            if count < MIN_COUNT:
                self.stats.count_errors += 1
                out.append(BadFrame(BadFrameKind.COUNT, f"count byte {count} < {MIN_COUNT}", bytes(buf[:3])))
                del buf[:2]  # skip only the header, then rescan
                continue
            total = count + 3
            if len(buf) < total:
                return out
            payload = bytes(buf[3 : total - 2])
            sent = (buf[total - 2] << 8) | buf[total - 1]
            calc = checksum(payload)
            if sent != calc:
                self.stats.checksum_errors += 1
                out.append(
                    BadFrame(BadFrameKind.CHECKSUM, f"checksum {sent:#06x} != computed {calc:#06x}", bytes(buf[:total]))
                )
                del buf[:2]  # skip only the header: the claimed body may hold the next real frame
                continue
            if count <= WEAK_COUNT:
                embedded = _embedded_frame(buf, total)
                if embedded is None:
                    return out
                if embedded:
                    self.stats.overlap_rejects += 1
                    out.append(
                        BadFrame(BadFrameKind.OVERLAP, "tiny frame holds a valid frame's header", bytes(buf[:total]))
                    )
                    del buf[:2]
                    continue
            self.stats.frames += 1
            out.append(RawFrame(payload))
            del buf[:total]

    def _release_held_tiny_frame(self) -> RawFrame | None:
        """A complete tiny frame held back while a header inside it waited for its body: accept it."""
        buf = self._buf
        if len(buf) < 3 or not MIN_COUNT <= buf[2] <= WEAK_COUNT or len(buf) < buf[2] + 3:
            return None
        total = buf[2] + 3
        payload = bytes(buf[3 : total - 2])
        if checksum(payload) != (buf[total - 2] << 8) | buf[total - 1]:
            return None
        self.stats.frames += 1
        del buf[:total]
        return RawFrame(payload)

    def expire_partial(self) -> list[RawFrame | BadFrame]:
        """Give up on the partial frame at the head of the buffer (skip its header) and rescan."""
        if len(self._buf) < 2 or self._buf[:2] != HEADER:
            return []
        held = self._release_held_tiny_frame()
        if held is not None:
            return [held, *self._scan()]
        self.stats.truncated += 1
        bad = BadFrame(BadFrameKind.TRUNCATED, f"frame body incomplete ({len(self._buf)} bytes held)", bytes(self._buf))
        del self._buf[:2]
        return [bad, *self._scan()]


class ArcosDecoder:
    """Deframer plus payload decoding: bytes in, typed events out; never raises."""

    def __init__(self) -> None:
        self.deframer = Deframer()
        self.payload_errors = 0

    def _decode(self, items: Iterable[RawFrame | BadFrame]) -> list[Event]:
        events: list[Event] = []
        for item in items:
            if isinstance(item, BadFrame):
                events.append(item)
                continue
            try:
                events.append(decode_payload(item.payload))
            except ArcosProtocolError as exc:
                self.payload_errors += 1
                events.append(BadFrame(BadFrameKind.PAYLOAD, str(exc), item.payload))
        return events

    def feed(self, data: bytes | bytearray | memoryview) -> list[Event]:
        return self._decode(self.deframer.feed(data))

    def expire_partial(self) -> list[Event]:
        return self._decode(self.deframer.expire_partial())

    @property
    def pending(self) -> int:
        return self.deframer.pending

    def clear(self) -> None:
        self.deframer.clear()
