"""A byte-level fake Pioneer 3-DX running ARCOS, written from the fact sheet (protocols/arcos_p3dx.md).

It is an independent model of the controller: it has its own framing, checksum and command parser
and never imports the driver, so a codec bug cannot hide behind the same bug here.

What it models:

* the handshake SYNC0/SYNC1/SYNC2 (reply: name, class, subclass), restarting at SYNC0 when a SYNC
  comes out of order (as real ARCOS does, fact sheet 1.4); OPEN starts a SIP every ``sip_cycle_s``;
  CLOSE ends the session; OPEN/CLOSE with an argument are accepted;
* CONFIG (CONFIGpac 0x20 in ARIA's field order), ENCODER (0x90 stream), IOREQUEST (0xF0), the velocity commands
  (VEL, RVEL, ROTATE, VEL2, STOP, E_STOP), limits (SETV, SETA, SETRV, SETRA), ENABLE (motors start
  disabled unless configured otherwise), SETO, SONAR, HOSTBAUD, RESET; other known commands are
  accepted and counted; frames with a bad checksum are ignored and counted;
* motion through a :class:`Plant` (default: :class:`hil_fakes.kinematics.Unicycle` advanced on the
  fake's clock), odometry through :class:`hil_fakes.wheel_odometry.WheelOdometry` in the
  controller's raw frame (optionally starting at a raw offset, so the 15-bit X/Y and the 12-bit
  heading wrap in tests) sent as wrapping 16-bit counters (only the low 15 bits are valid);
* 16 sonars at the p3dx.p poses, ray-cast in a :class:`SonarWorld` (default: a rectangular room);
* the firmware watchdog: motion halts after ``watchdog_s`` without a command; when commands
  return, the old setpoint resumes or not (``watchdog_resume``, unverified on hardware);
* faults on top of the transport's: a reset packet, a stale open session, out-of-order SYNC
  replies, junk before SIPs.

``truth(now_s)`` gives the plant's ground truth and ``raw_odometry_pose()`` the controller's own
odometry (equal to the truth, moved to the raw frame, when the odometry noise is zero).
"""

from __future__ import annotations

import argparse
import math
import signal
import struct
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from .kinematics import Unicycle
from .transport import DeviceModel, DeviceServer, PtyEndpoint, TcpEndpoint, wait_forever
from .wheel_odometry import OdometryNoise, WheelOdometry

# ---------------------------------------------------------------------------------------------
# interfaces (INTERFACES.md)


class Plant(Protocol):
    def command(self, v_mps: float, w_radps: float, now_s: float) -> None: ...

    def e_stop(self, now_s: float) -> None: ...

    def state(self, now_s: float) -> tuple[float, float, float, float, float]:
        """true (x_m, y_m, theta_rad, v_mps, w_radps) advanced to now_s"""
        ...


class SonarWorld(Protocol):
    def ray_range_m(self, x_m: float, y_m: float, angle_rad: float, max_range_m: float) -> float:
        """distance to the first surface along the ray from (x, y) at world angle angle_rad; NaN if none"""
        ...


class UnicyclePlant:
    """The standalone plant: a :class:`Unicycle` advanced lazily to each queried time (thread-safe)."""

    def __init__(self, unicycle: Unicycle | None = None, max_step_s: float = 0.01) -> None:
        self.unicycle = unicycle or Unicycle()
        self._max_step_s = max_step_s
        self._t_s: float | None = None
        self._lock = threading.Lock()

    def _advance(self, now_s: float) -> None:
        if self._t_s is None:
            self._t_s = now_s
            return
        while now_s > self._t_s:
            dt = min(self._max_step_s, now_s - self._t_s)
            self.unicycle.advance(dt)
            self._t_s += dt

    def command(self, v_mps: float, w_radps: float, now_s: float) -> None:
        with self._lock:
            self._advance(now_s)
            self.unicycle.command(v_mps, w_radps)

    def e_stop(self, now_s: float) -> None:
        with self._lock:
            self._advance(now_s)
            self.unicycle.stop_now()

    def set_accelerations(self, accel_mps2: float, rot_accel_radps2: float) -> None:
        with self._lock:
            self.unicycle.max_accel_mps2 = accel_mps2
            self.unicycle.max_rot_accel_radps2 = rot_accel_radps2

    def state(self, now_s: float) -> tuple[float, float, float, float, float]:
        with self._lock:
            self._advance(now_s)
            u = self.unicycle
            return (u.x_m, u.y_m, u.theta_rad, u.v_mps, u.w_radps)


@dataclass(frozen=True)
class RectangularRoom:
    """Axis-aligned walls around the start pose (default: 8 m x 5 m, robot 2 m from the back wall)."""

    x_min_m: float = -2.0
    x_max_m: float = 6.0
    y_min_m: float = -2.5
    y_max_m: float = 2.5

    def ray_range_m(self, x_m: float, y_m: float, angle_rad: float, max_range_m: float) -> float:
        dx, dy = math.cos(angle_rad), math.sin(angle_rad)
        best = math.inf
        if dx > 1e-12:
            best = min(best, (self.x_max_m - x_m) / dx)
        elif dx < -1e-12:
            best = min(best, (self.x_min_m - x_m) / dx)
        if dy > 1e-12:
            best = min(best, (self.y_max_m - y_m) / dy)
        elif dy < -1e-12:
            best = min(best, (self.y_min_m - y_m) / dy)
        if best < 0 or best > max_range_m:
            return math.nan
        return best


# ---------------------------------------------------------------------------------------------
# wire format, written from the fact sheet section 1.2 (independent of drivers/p2os)

_ANGLE_UNIT_RAD = 2.0 * math.pi / 4096.0

# p3dx.p sonar poses (x mm, y mm, heading deg), fact sheet 1.9
SONAR_POSES_MM_DEG: tuple[tuple[float, float, float], ...] = (
    (69, 136, 90), (114, 119, 50), (148, 78, 30), (166, 27, 10),
    (166, -27, -10), (148, -78, -30), (114, -119, -50), (69, -136, -90),
    (-157, -136, -90), (-203, -119, -130), (-237, -78, -150), (-255, -27, -170),
    (-255, 27, 170), (-237, 78, 150), (-203, 119, 130), (-157, 136, 90),
)  # fmt: skip

DIST_CONV_MM = {"p3dx": 0.485, "p3dx-sh": 1.0}


def arcos_checksum(payload: bytes) -> int:
    total = 0
    pairs = len(payload) // 2
    for k in range(pairs):
        total += payload[2 * k] * 256 + payload[2 * k + 1]
    total %= 65536
    if len(payload) % 2:
        total ^= payload[-1]
    return total


def arcos_packet(payload: bytes) -> bytes:
    chk = arcos_checksum(payload)
    return bytes([0xFA, 0xFB, len(payload) + 2]) + payload + bytes([chk // 256, chk % 256])


class _HostFrames:
    """The controller's receive side: header hunt, unsigned count, checksum; bad frames are counted."""

    def __init__(self) -> None:
        self.buf = bytearray()
        self.bad_checksum = 0

    def feed(self, data: bytes) -> list[bytes]:
        self.buf.extend(data)
        out: list[bytes] = []
        while True:
            i = self.buf.find(b"\xfa\xfb")
            if i < 0:
                del self.buf[: max(0, len(self.buf) - 1)]
                return out
            del self.buf[:i]
            if len(self.buf) < 3:
                return out
            n = self.buf[2]
            if n < 3:
                del self.buf[:2]
                continue
            if len(self.buf) < n + 3:
                return out
            body = bytes(self.buf[3 : 3 + n - 2])
            chk = self.buf[1 + n] * 256 + self.buf[2 + n]
            if chk != arcos_checksum(body):
                self.bad_checksum += 1
                del self.buf[:2]
                continue
            del self.buf[: n + 3]
            out.append(body)


def _arg(body: bytes) -> int | None:
    """The signed integer argument of a command body, None if it has none."""
    if len(body) >= 4 and body[1] in (0x3B, 0x1B):
        magnitude = body[2] | (body[3] << 8)
        return magnitude if body[1] == 0x3B else -magnitude
    return None


# command numbers (fact sheet 1.5)
SYNC0, SYNC1, SYNC2 = 0, 1, 2
PULSE, OPEN, CLOSE = 0, 1, 2
ENABLE, SETA, SETV, SETO, ROTATE, SETRV, VEL, CONFIG, ENCODER = 4, 5, 6, 7, 9, 10, 11, 18, 19
RVEL, SETRA, SONAR, STOP, VEL2, HOSTBAUD, E_STOP, BATTERYINFO, RESET = 21, 23, 28, 29, 32, 50, 55, 62, 253
IOREQUEST = 40
_KNOWN_OTHERS = {3, 8, 12, 13, 15, 17, 22, 30, 44, 56, 58, 90, 92}
_BAUDS = {0: 9600, 1: 19200, 2: 38400, 3: 57600, 4: 115200}


@dataclass
class PioneerConfig:
    """Fake robot parameters. Unit-named; counts are the controller's raw units."""

    name: str = "fakebot"
    robot_class: str = "Pioneer"
    subclass: str = "p3dx"
    serial_number: str = "FAKE0001"
    firmware: str = "fake-arcos-1.0"
    sip_cycle_s: float = 0.1
    watchdog_s: float = 2.0
    #: resume the old setpoint when commands return after a watchdog stop (manual wording; [?] on hardware)
    watchdog_resume: bool = True
    motors_enabled_at_start: bool = False
    #: raw odometry at power-up (counts of DistConvFactor mm, 4096ths of a revolution)
    start_x_counts: int = 0
    start_y_counts: int = 0
    start_th_units: int = 0
    #: THPOS sent as -2048..2047 (AMRISim) instead of 0..4095
    heading_signed: bool = False
    odometry_noise: OdometryNoise = field(default_factory=OdometryNoise)
    #: new sonar readings per SIP (cycling through 0..15); 0 disables sonar data
    sonars_per_sip: int = 16
    sonar_max_range_m: float = 5.0
    #: SIP tail: "none" (ends after the sonar readings), "digout" (old firmware) or "arcos" (to FAULTFLAGS)
    sip_tail: str = "arcos"
    battery_dv: int = 125
    # CONFIGpac "Top" values and working limits at start (fact sheet 1.7 / p3dx defaults)
    rot_vel_top_degps: int = 360
    trans_vel_top_mmps: int = 1500
    rot_accel_top_degps2: int = 300
    trans_accel_top_mmps2: int = 2000
    trans_vel_max_mmps: int = 1500
    rot_vel_max_degps: int = 360
    trans_accel_mmps2: int = 300
    trans_decel_mmps2: int = 300
    rot_accel_degps2: int = 100
    rot_decel_degps2: int = 100
    reset_baud: int = 2  # 2 = the controller can switch baud (HOSTBAUD)
    ticks_mm: int = 128
    #: start with an open session streaming SIPs, as if an earlier client never closed it
    start_open: bool = False
    #: keep the session open when the client goes away (a real robot does not notice a cable pull)
    keep_session_on_disconnect: bool = True
    #: the host port's rate at power-up (the FLASH HostBaud; reported in the CONFIGpac)
    host_baud: int = 9600
    #: False: HOSTBAUD is ignored (the controller stays at its rate)
    hostbaud_supported: bool = True

    @property
    def dist_conv_mm(self) -> float:
        return DIST_CONV_MM.get(self.subclass.lower(), 1.0)


@dataclass
class PioneerStats:
    commands: dict[int, int] = field(default_factory=dict)
    bad_checksum: int = 0
    unknown_commands: int = 0
    sips_sent: int = 0
    configs_sent: int = 0
    encoder_packets: int = 0
    watchdog_trips: int = 0
    sessions_opened: int = 0
    sessions_closed: int = 0
    sync_restarts: int = 0
    #: wraps of the sent counters (ground truth for the wrap tests)
    x_wraps: int = 0
    y_wraps: int = 0
    th_wraps: int = 0


class FakePioneer(DeviceModel):
    """The controller model. Thread-safe for the test-side accessors."""

    def __init__(
        self,
        config: PioneerConfig | None = None,
        plant: Plant | None = None,
        sonar_world: SonarWorld | None = None,
    ) -> None:
        super().__init__()
        self.config = cfg = config or PioneerConfig()
        self.plant: Plant = plant or UnicyclePlant()
        self.sonar_world: SonarWorld = sonar_world or RectangularRoom()
        self.stats = PioneerStats()
        self._lock = threading.RLock()
        self._rx = _HostFrames()
        conv_m = cfg.dist_conv_mm / 1000.0
        self._odo = WheelOdometry(
            cfg.odometry_noise,
            x_m=cfg.start_x_counts * conv_m,
            y_m=cfg.start_y_counts * conv_m,
            theta_rad=cfg.start_th_units * _ANGLE_UNIT_RAD,
        )
        self._prev_truth: tuple[float, float, float] | None = None
        self._prev_sent: tuple[int, int, int] | None = None
        self._wheel_mm = [0.0, 0.0]
        self.state = "open" if cfg.start_open else "sync0"
        self.motors_enabled = cfg.motors_enabled_at_start
        self.sonar_on = True
        self.encoder_stream = False
        self.io_stream = False
        self.host_baud = cfg.host_baud
        #: returns the rate the host set on its end of the line (None: unknown, e.g. TCP); see serve()
        self.line_baud: Callable[[], int | None] | None = None
        self.garbled_in_bytes = 0
        self.garbled_out_bytes = 0
        self._v_set_mmps = 0.0
        self._w_set_degps = 0.0
        self._trans_vel_max = float(cfg.trans_vel_max_mmps)
        self._rot_vel_max = float(cfg.rot_vel_max_degps)
        self._trans_accel = float(cfg.trans_accel_mmps2)
        self._rot_accel = float(cfg.rot_accel_degps2)
        set_acc = getattr(self.plant, "set_accelerations", None)
        if set_acc is not None:
            set_acc(self._trans_accel / 1000.0, math.radians(self._rot_accel))
        self._last_cmd_s: float | None = None
        self.watchdog_stopped = False
        self._next_sip_s: float | None = None
        self._sonar_next = 0
        self._misorder_left = 0
        self._misorder_skip = 0
        self._junk_every = 0
        self._junk_data = b""
        self._sip_index = 0
        self._now_s = 0.0
        self.e_stopped = False

    def _rates_differ(self) -> bool:
        line = self.line_baud() if self.line_baud is not None else None
        return line is not None and line != self.host_baud

    def emit(self, data: bytes) -> None:
        if self._rates_differ():
            # what a UART at another rate makes of our bytes: noise (kept free of 0xFA so it can
            # never be read as a frame header)
            self.garbled_out_bytes += len(data)
            data = bytes(0 if (b ^ 0x5A) == 0xFA else (b ^ 0x5A) for b in data)
        super().emit(data)

    # -- faults and test accessors -------------------------------------------------------------

    def send_reset_packet(self, code: int = 0xFF) -> None:
        """The microcontroller resets: emit a 0xFF/0xFE packet, drop the session, stop, lose the odometry."""
        with self._lock:
            self._halt(self._now_s)
            self.state = "sync0"
            self.motors_enabled = self.config.motors_enabled_at_start
            self.encoder_stream = self.io_stream = False
            self.host_baud = self.config.host_baud
            self._odo.reset(0.0, 0.0, 0.0)
            self.emit(arcos_packet(bytes([code])))

    def make_session_stale(self) -> None:
        """Open a session as if a previous client had left it open (SIPs start flowing)."""
        with self._lock:
            self._open_session(self._now_s)

    def misorder_sync(self, count: int = 1, skip: int = 0) -> None:
        """After ``skip`` correct SYNC replies, the next ``count`` carry the wrong id (the step after the
        one asked for; for SYNC2 that is a late-looking echo 0)."""
        with self._lock:
            self._misorder_skip = skip
            self._misorder_left += count

    def junk_before_sips(self, every: int, data: bytes = b"\x00\xfa\x13\xfa\xfb\x05junk") -> None:
        """Emit ``data`` before every ``every``-th SIP (0 stops); the default is the fact sheet's pattern."""
        with self._lock:
            self._junk_every = every
            self._junk_data = data

    def truth(self, now_s: float) -> tuple[float, float, float, float, float]:
        """Ground truth (x_m, y_m, theta_rad, v_mps, w_radps) in the world frame."""
        return self.plant.state(now_s)

    def raw_odometry_pose(self) -> tuple[float, float, float]:
        """The controller's odometry (m, m, rad) in its raw frame, as integrated so far."""
        with self._lock:
            return self._odo.pose()

    @property
    def setpoint(self) -> tuple[float, float]:
        """Commanded (v mm/s, w deg/s) setpoint (what resumes after a watchdog stop)."""
        with self._lock:
            return (self._v_set_mmps, self._w_set_degps)

    # -- DeviceModel -----------------------------------------------------------------------------

    def on_client_change(self, connected: bool, now_s: float) -> None:
        with self._lock:
            if not connected and not self.config.keep_session_on_disconnect:
                self._close_session(now_s)

    def on_bytes(self, data: bytes, now_s: float) -> None:
        with self._lock:
            self._now_s = now_s
            if self._rates_differ():
                self.garbled_in_bytes += len(data)
                return
            for body in self._rx.feed(data):
                self._on_command(body, now_s)
            self.stats.bad_checksum = self._rx.bad_checksum

    def poll(self, now_s: float) -> float | None:
        with self._lock:
            self._now_s = now_s
            self._integrate(now_s)
            if self.state != "open":
                return None
            cfg = self.config
            if self._last_cmd_s is not None and not self.watchdog_stopped and now_s - self._last_cmd_s > cfg.watchdog_s:
                self.watchdog_stopped = True
                self.stats.watchdog_trips += 1
                self.plant.command(0.0, 0.0, now_s)
            if self._next_sip_s is None:
                self._next_sip_s = now_s
            if now_s >= self._next_sip_s:
                self._send_sip(now_s)
                self._next_sip_s += cfg.sip_cycle_s
                if self._next_sip_s < now_s:  # fell behind (stall): do not burst
                    self._next_sip_s = now_s + cfg.sip_cycle_s
            return self._next_sip_s

    # -- session and commands ----------------------------------------------------------------

    def _open_session(self, now_s: float) -> None:
        if self.state != "open":
            self.stats.sessions_opened += 1
        self.state = "open"
        self._next_sip_s = now_s + self.config.sip_cycle_s
        self._last_cmd_s = now_s

    def _close_session(self, now_s: float) -> None:
        if self.state == "open":
            self.stats.sessions_closed += 1
        self.host_baud = self.config.host_baud  # back to the FLASH rate (assumed; [?] on hardware)
        self._halt(now_s)
        self.state = "sync0"
        self.encoder_stream = self.io_stream = False
        self._next_sip_s = None

    def _halt(self, now_s: float) -> None:
        self._v_set_mmps = self._w_set_degps = 0.0
        self.plant.command(0.0, 0.0, now_s)

    def _apply_motion(self, now_s: float) -> None:
        if not self.motors_enabled or self.e_stopped:
            self._v_set_mmps = self._w_set_degps = 0.0
        v = max(-self._trans_vel_max, min(self._trans_vel_max, self._v_set_mmps))
        w = max(-self._rot_vel_max, min(self._rot_vel_max, self._w_set_degps))
        self.plant.command(v / 1000.0, math.radians(w), now_s)

    def _sync_reply(self, step: int) -> None:
        reply_id = step
        if self._misorder_skip > 0:
            self._misorder_skip -= 1
        elif self._misorder_left > 0:
            self._misorder_left -= 1
            reply_id = (step + 1) % 3
        if reply_id == 2:
            cfg = self.config
            text = b"".join(s.encode("latin-1") + b"\x00" for s in (cfg.name, cfg.robot_class, cfg.subclass))
            self.emit(arcos_packet(bytes([2]) + text))
        else:
            self.emit(arcos_packet(bytes([reply_id])))

    def _on_command(self, body: bytes, now_s: float) -> None:
        cmd = body[0]
        self.stats.commands[cmd] = self.stats.commands.get(cmd, 0) + 1
        if self.state != "open":
            self._on_sync_state_command(cmd, now_s)
            return
        # any command in an open session feeds the watchdog
        self._last_cmd_s = now_s
        if self.watchdog_stopped:
            self.watchdog_stopped = False
            if self.config.watchdog_resume:
                self._apply_motion(now_s)
            else:
                self._v_set_mmps = self._w_set_degps = 0.0
        arg = _arg(body)
        if cmd == PULSE or cmd == OPEN:
            return
        if cmd == CLOSE:
            self._close_session(now_s)
            return
        if cmd == ENABLE:
            self.motors_enabled = bool(arg)
            if self.motors_enabled:
                self.e_stopped = False
            self._apply_motion(now_s)
        elif cmd == VEL and arg is not None:
            self._v_set_mmps = float(arg)
            self.e_stopped = False
            self._apply_motion(now_s)
        elif cmd in (RVEL, ROTATE) and arg is not None:
            self._w_set_degps = float(arg)
            self.e_stopped = False
            self._apply_motion(now_s)
        elif cmd == VEL2 and arg is not None:
            raw = arg & 0xFFFF
            left_b, right_b = raw >> 8, raw & 0xFF
            left = (left_b - 256 if left_b >= 128 else left_b) * 20.0
            right = (right_b - 256 if right_b >= 128 else right_b) * 20.0
            self._v_set_mmps = (left + right) / 2.0
            self._w_set_degps = math.degrees((right - left) / 2.0 * 0.0056)
            self.e_stopped = False
            self._apply_motion(now_s)
        elif cmd == STOP:
            self._halt(now_s)
        elif cmd == E_STOP:
            self._v_set_mmps = self._w_set_degps = 0.0
            self.e_stopped = True
            self.plant.e_stop(now_s)
        elif cmd == SETV and arg is not None:
            self._trans_vel_max = float(min(abs(arg), self.config.trans_vel_top_mmps))
            self._apply_motion(now_s)
        elif cmd == SETRV and arg is not None:
            self._rot_vel_max = float(min(abs(arg), self.config.rot_vel_top_degps))
            self._apply_motion(now_s)
        elif cmd in (SETA, SETRA) and arg is not None:
            # The plant has one limit per axis: positive values (acceleration) set it; the
            # deceleration (negative argument) is accepted and stored only.
            if cmd == SETA and arg > 0:
                self._trans_accel = float(min(arg, self.config.trans_accel_top_mmps2))
            elif cmd == SETRA and arg > 0:
                self._rot_accel = float(min(arg, self.config.rot_accel_top_degps2))
            set_acc = getattr(self.plant, "set_accelerations", None)
            if set_acc is not None:
                set_acc(self._trans_accel / 1000.0, math.radians(self._rot_accel))
        elif cmd == SETO:
            self._integrate(now_s)
            self._odo.reset(0.0, 0.0, 0.0)
        elif cmd == CONFIG:
            self.emit(arcos_packet(self._config_payload()))
            self.stats.configs_sent += 1
        elif cmd == ENCODER and arg is not None:
            self.encoder_stream = arg > 0
        elif cmd == IOREQUEST and arg is not None:
            self.io_stream = arg == 2
            if arg == 1:
                self.emit(self._io_packet())
        elif cmd == SONAR and arg is not None:
            self.sonar_on = arg != 0
        elif cmd == HOSTBAUD and arg is not None:
            if self.config.hostbaud_supported:
                self.host_baud = _BAUDS.get(arg, self.host_baud)
        elif cmd == RESET:
            self.send_reset_packet()
        elif cmd == BATTERYINFO or cmd in _KNOWN_OTHERS:
            pass
        else:
            self.stats.unknown_commands += 1

    def _on_sync_state_command(self, cmd: int, now_s: float) -> None:
        expected = {"sync0": 0, "sync1": 1, "sync2": 2}.get(self.state)
        if self.state == "ready":
            if cmd == OPEN:
                self._open_session(now_s)
            elif cmd == CLOSE:
                self.state = "sync0"
            elif cmd == SYNC0:
                self.state = "sync1"
                self._sync_reply(0)
            return
        if cmd not in (0, 1, 2):
            return  # not synced: other commands are ignored
        if cmd != expected:
            # real ARCOS restarts at SYNC0 on an out-of-order SYNC (fact sheet 1.4)
            self.stats.sync_restarts += 1
            self.state = "sync0"
            if cmd != SYNC0:
                return
        self._sync_reply(cmd)
        self.state = {0: "sync1", 1: "sync2", 2: "ready"}[cmd]

    # -- odometry, SIP, CONFIGpac ----------------------------------------------------------------

    def _integrate(self, now_s: float) -> None:
        x, y, th, _, _ = self.plant.state(now_s)
        prev = self._prev_truth
        self._prev_truth = (x, y, th)
        if prev is None:
            return
        px, py, pth = prev
        dth = math.remainder(th - pth, 2 * math.pi)
        mid = pth + dth / 2
        along = (x - px) * math.cos(mid) + (y - py) * math.sin(mid)
        ds = along if abs(dth) < 1e-9 else along * (dth / 2) / math.sin(dth / 2)
        if ds == 0.0 and dth == 0.0:
            return
        self._odo.step(ds, dth)
        half_track_mm = 1.0 / 0.0056  # ARIA's DiffConvFactor geometry
        self._wheel_mm[0] += ds * 1000.0 - dth * half_track_mm
        self._wheel_mm[1] += ds * 1000.0 + dth * half_track_mm

    def _send_sip(self, now_s: float) -> None:
        cfg = self.config
        self._integrate(now_s)
        _, _, _, v_mps, w_radps = self.plant.state(now_s)
        ox, oy, oth = self._odo.pose()
        conv = cfg.dist_conv_mm
        x_counts = round(ox * 1000.0 / conv) & 0xFFFF  # 16-bit accumulator: only 15 bits valid
        y_counts = round(oy * 1000.0 / conv) & 0xFFFF
        th_units = round(oth / _ANGLE_UNIT_RAD) % 4096
        if cfg.heading_signed and th_units >= 2048:
            th_units -= 4096
        self._count_wraps(x_counts & 0x7FFF, y_counts & 0x7FFF, th_units)
        v_mmps = v_mps * 1000.0
        w_term = w_radps / 0.0056
        left = round(v_mmps - w_term)
        right = round(v_mmps + w_term)
        moving = abs(v_mps) > 1e-6 or abs(w_radps) > 1e-6
        flags = (0x01 if self.motors_enabled else 0) | (0x1E if self.sonar_on else 0)
        if self.e_stopped:
            flags |= 0x20
        sonar = self._sonar_readings(now_s) if self.sonar_on else []
        payload = bytearray()
        payload += struct.pack(
            "<BHHhhhBHhHBB",
            0x33 if moving else 0x32,
            x_counts,
            y_counts,
            th_units,
            max(-32768, min(32767, left)),
            max(-32768, min(32767, right)),
            cfg.battery_dv,
            0,
            th_units if th_units < 2048 else th_units - 4096,
            flags,
            0,
            len(sonar),
        )
        for index, range_mm in sonar:
            payload += struct.pack("<BH", index, range_mm)
        if cfg.sip_tail in ("digout", "arcos"):
            payload += bytes([0, 0, 0, 0, 0])  # grip, anport, analog, digin, digout
        if cfg.sip_tail == "arcos":
            rotvel = max(-32768, min(32767, round(math.degrees(w_radps) * 10)))
            payload += struct.pack("<HBhH", cfg.battery_dv, 0, rotvel, 0)
        self._sip_index += 1
        if self._junk_every and self._sip_index % self._junk_every == 0:
            self.emit(self._junk_data)
        self.emit(arcos_packet(bytes(payload)))
        self.stats.sips_sent += 1
        if self.io_stream:
            self.emit(self._io_packet())
        if self.encoder_stream:
            ticks = cfg.ticks_mm
            self.emit(
                arcos_packet(
                    struct.pack(
                        "<Bii",
                        0x90,
                        max(-(2**31), min(2**31 - 1, round(self._wheel_mm[0] * ticks))),
                        max(-(2**31), min(2**31 - 1, round(self._wheel_mm[1] * ticks))),
                    )
                )
            )
            self.stats.encoder_packets += 1

    def _io_packet(self) -> bytes:
        """IOpac (0xF0): one digital-in byte, one digital-out byte, the battery on one analog port."""
        analog = round(self.config.battery_dv / 10.0 / 5.0 * 255) & 0xFFFF  # nominal 0..5 V scale
        return arcos_packet(bytes([0xF0, 1, 0x00, 1, 0x00, 1]) + struct.pack("<H", analog))

    def _count_wraps(self, x15: int, y15: int, th: int) -> None:
        prev = self._prev_sent
        self._prev_sent = (x15, y15, th)
        if prev is None:
            return
        if abs(x15 - prev[0]) > 16384:
            self.stats.x_wraps += 1
        if abs(y15 - prev[1]) > 16384:
            self.stats.y_wraps += 1
        if abs(th - prev[2]) > 2048:
            self.stats.th_wraps += 1

    def _sonar_readings(self, now_s: float) -> list[tuple[int, int]]:
        cfg = self.config
        n = min(16, max(0, cfg.sonars_per_sip))
        if n == 0:
            return []
        x, y, th, _, _ = self.plant.state(now_s)
        out = []
        for _ in range(n):
            i = self._sonar_next
            self._sonar_next = (self._sonar_next + 1) % 16
            sx_mm, sy_mm, sth_deg = SONAR_POSES_MM_DEG[i]
            c, s = math.cos(th), math.sin(th)
            wx = x + (c * sx_mm - s * sy_mm) / 1000.0
            wy = y + (s * sx_mm + c * sy_mm) / 1000.0
            r = self.sonar_world.ray_range_m(wx, wy, th + math.radians(sth_deg), cfg.sonar_max_range_m)
            range_mm = round(cfg.sonar_max_range_m * 1000.0) if math.isnan(r) else round(r * 1000.0)
            out.append((i, max(0, min(0xFFFF, range_mm))))
        return out

    def _config_payload(self) -> bytes:
        """CONFIGpac in ARIA's reader order (fact sheet 1.7)."""
        cfg = self.config

        def s(text: str) -> bytes:
            return text.encode("latin-1") + b"\x00"

        p = bytearray([0x20])
        p += s(cfg.robot_class) + s(cfg.subclass) + s(cfg.serial_number)
        p += bytes([0])  # 4MOTS
        p += struct.pack(
            "<HHHHH",
            cfg.rot_vel_top_degps,
            cfg.trans_vel_top_mmps,
            cfg.rot_accel_top_degps2,
            cfg.trans_accel_top_mmps2,
            500,
        )
        p += s(cfg.name)
        host_code = {v: k for k, v in _BAUDS.items()}.get(cfg.host_baud, 0)
        p += bytes([round(cfg.sip_cycle_s * 1000) & 0xFF, host_code, 0])  # SipCycle, HostBaud (FLASH), Aux1Baud
        p += struct.pack("<HHB", 0, 1, 1)  # gripper, front sonar, rear sonar
        p += struct.pack("<HHH", 110, 16570, round(cfg.watchdog_s * 1000))  # LowBattery, RevCount, Watchdog ms
        p += struct.pack("<BHHHH", 0, 0, 0, 300, 50)  # NormalMPacs, StallVal, StallCount, JoyVel, JoyRotVel
        p += struct.pack(
            "<HHHH",
            round(self._rot_vel_max),
            round(self._trans_vel_max),
            cfg.rot_accel_degps2,
            cfg.rot_decel_degps2,
        )
        p += struct.pack("<HHH", 40, 20, 0)  # RotKP, RotKV, RotKI
        p += struct.pack("<HH", cfg.trans_accel_mmps2, cfg.trans_decel_mmps2)
        p += struct.pack("<HHH", 40, 30, 0)  # TransKP, TransKV, TransKI
        p += bytes([1, 1, 0, 50, cfg.reset_baud, 0])  # FrontBumps, RearBumps, Charger, SonarCycle, ResetBaud, GyroType
        p += struct.pack("<hBBHH", 0, 0, 0, cfg.ticks_mm, 105)  # DriftFactor, Aux2, Aux3, TicksMM, ShutdownVoltage
        p += s(cfg.firmware)
        p += struct.pack("<HHB", 0, 0, 0)  # GyroCW, GyroCCW, KinematicsDelay
        p += struct.pack("<HHHHH", 0, 0, 0, 0, 0)  # lateral (not on a P3-DX)
        p += struct.pack("<HBH", 0, 0, 0)  # PowerbotChargeThreshold, PDBPort, GyroRateLimit
        p += struct.pack("<bHBHH", -128, 0, 0, 0, 0)  # HighTempShutdown .. SoCShutdown
        p += s("fake-boot-1.0") + struct.pack("<Ih", 0, 0)
        return bytes(p)


# ---------------------------------------------------------------------------------------------
# serving


def serve(model: FakePioneer, *, tcp: str | None = None, pty: bool = False, link: str | None = None) -> DeviceServer:
    """Start a fake on ``tcp`` (``HOST:PORT``) or a pty (optionally behind ``link``)."""
    if tcp is not None:
        host, _, port = tcp.rpartition(":")
        endpoint: TcpEndpoint | PtyEndpoint = TcpEndpoint(host or "127.0.0.1", int(port))
    elif pty:
        endpoint = PtyEndpoint(link)
        model.line_baud = lambda: pty_line_baud(endpoint)
    else:
        raise ValueError("serve needs tcp=HOST:PORT or pty=True")
    return DeviceServer(model, endpoint).start()


_ARCOS_RATES = (9600, 19200, 38400, 57600, 115200)


def pty_line_baud(endpoint: PtyEndpoint) -> int | None:
    """The rate the host set on its end of a pty; None when it is closed or the rate is not an ARCOS one."""
    bps = endpoint.line_speed_bps()
    return bps if bps in _ARCOS_RATES else None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--tcp", metavar="HOST:PORT", help="serve on loopback TCP, e.g. 127.0.0.1:8101")
    where.add_argument("--pty", action="store_true", help="serve on a pseudo-terminal")
    parser.add_argument("--link", metavar="PATH", help="with --pty: stable symlink to the pty (like /dev/pioneer)")
    parser.add_argument("--name", default="fakebot")
    parser.add_argument("--subclass", default="p3dx", choices=sorted(DIST_CONV_MM))
    parser.add_argument("--sip-cycle-s", type=float, default=0.1)
    parser.add_argument("--watchdog-s", type=float, default=2.0)
    parser.add_argument("--no-watchdog-resume", action="store_true", help="stay stopped after a watchdog stop")
    parser.add_argument("--motors-enabled", action="store_true", help="start with motors enabled (AMRISim-like)")
    parser.add_argument("--start-x-counts", type=int, default=0, help="raw X at power-up (15-bit counter)")
    parser.add_argument("--start-y-counts", type=int, default=0)
    parser.add_argument("--start-th-units", type=int, default=0, help="raw heading at power-up (4096ths)")
    parser.add_argument("--heading-signed", action="store_true", help="send THPOS as -2048..2047")
    parser.add_argument("--sigma-trans-frac", type=float, default=0.0, help="odometry distance noise per metre")
    parser.add_argument("--sigma-rot-rad-per-m", type=float, default=0.0)
    parser.add_argument("--scale-error", type=float, default=0.0)
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--start-open", action="store_true", help="start with a stale open session")
    parser.add_argument("--junk-every", type=int, default=0, help="junk before every N-th SIP")
    parser.add_argument(
        "--host-baud",
        type=int,
        default=9600,
        choices=sorted(_BAUDS.values()),
        help="the controller's FLASH host rate (a pty client at another rate sees noise)",
    )
    parser.add_argument("--no-hostbaud", action="store_true", help="ignore HOSTBAUD (stay at --host-baud)")


def config_from_args(args: argparse.Namespace) -> PioneerConfig:
    return PioneerConfig(
        name=args.name,
        subclass=args.subclass,
        sip_cycle_s=args.sip_cycle_s,
        watchdog_s=args.watchdog_s,
        watchdog_resume=not args.no_watchdog_resume,
        motors_enabled_at_start=args.motors_enabled,
        start_x_counts=args.start_x_counts,
        start_y_counts=args.start_y_counts,
        start_th_units=args.start_th_units,
        heading_signed=args.heading_signed,
        odometry_noise=OdometryNoise(
            scale_error=args.scale_error,
            sigma_trans_frac=args.sigma_trans_frac,
            sigma_rot_rad_per_m=args.sigma_rot_rad_per_m,
            seed=args.seed,
        ),
        start_open=args.start_open,
        host_baud=args.host_baud,
        hostbaud_supported=not args.no_hostbaud,
    )


def run_from_args(args: argparse.Namespace) -> int:
    model = FakePioneer(config_from_args(args))
    if args.junk_every:
        model.junk_before_sips(args.junk_every)
    server = serve(model, tcp=args.tcp, pty=args.pty, link=args.link)

    def on_sigterm(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, on_sigterm)
    try:
        print(server.address, flush=True)
        wait_forever([server])  # stops the server (and removes a --link) on Ctrl-C or SIGTERM
    except KeyboardInterrupt:
        pass  # the signal came before wait_forever was listening
    finally:
        signal.signal(signal.SIGTERM, previous)
        server.stop()  # idempotent; covers the early-signal case
    return 0
