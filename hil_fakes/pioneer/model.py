"""The fake Pioneer 3-DX: the controller's state machine, odometry, watchdog, sonar and the SIPs it
sends."""

from __future__ import annotations

import math
import struct
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

from ..transport import DeviceModel
from ..wheel_odometry import OdometryNoise, WheelOdometry
from .plant import _ANGLE_UNIT_RAD, SONAR_POSES_MM_DEG, Plant, RectangularRoom, SonarWorld, UnicyclePlant
from .protocol import (
    _KNOWN_OTHERS,
    BATTERYINFO,
    CLOSE,
    CONFIG,
    DIST_CONV_MM,
    E_STOP,
    ENABLE,
    ENCODER,
    HOSTBAUD,
    IOREQUEST,
    OPEN,
    PULSE,
    RESET,
    ROTATE,
    RVEL,
    SETA,
    SETO,
    SETRA,
    SETRV,
    SETV,
    SONAR,
    STOP,
    SYNC0,
    VEL,
    VEL2,
    _arg,
    _HostFrames,
    arcos_packet,
)

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
