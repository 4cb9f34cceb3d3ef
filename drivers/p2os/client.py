"""The Pioneer 3-DX client: owns the port, runs the ARCOS handshake, streams odometry samples.

One reader thread per client reads SIPs continuously (never lock-stepped to writes), turns them into
:class:`~drivers.p2os.odometry.OdometrySample` through the sans-I/O codec and odometry tracker, and
hands them out through a :class:`~drivers.common.LatestBuffer`. The same thread keeps the link safe:

* **keep-alive:** it sends PULSE when nothing was sent for ``keepalive_interval_s`` *only while the
  application is alive*, i.e. called :meth:`ArcosClient.heartbeat` (or any command) within
  ``heartbeat_timeout_s``. A hung application therefore stops feeding the firmware watchdog, and the
  robot halts by itself (fact sheet 1.8);
* **command timeout:** when the caller stops commanding a non-zero velocity for
  ``command_timeout_s``, it commands VEL 0 / RVEL 0 itself (the rosaria#51 / p2os2 lesson);
* **connection loss:** no SIP for ``sip_silence_timeout_s``, a port error or a controller reset
  packet ends the session; with ``reconnect`` on, it re-opens with backoff, runs the handshake
  again and continues the odometry from the last pose (the sample says ``rebaselined``).

:meth:`ArcosClient.close` sends VEL 0, RVEL 0, ENABLE 0 and CLOSE, then lets the port go.
"""

from __future__ import annotations

import collections
import dataclasses
import enum
import math
import threading
import time
from dataclasses import dataclass, field

import serial

from drivers.common import Backoff, LatestBuffer, close_quietly, open_port, read_some, run_guarded, write_all
from drivers.errors import DisconnectedError, DriverError, DriverTimeoutError

from . import codec
from .codec import ArcosDecoder, BadFrame, ConfigPacket, EncoderPacket, ResetPacket, RobotIdentity, Sip, SyncEcho
from .errors import (
    ArcosConfigError,
    ArcosDisconnectedError,
    ArcosError,
    ArcosTimeoutError,
    ControllerResetError,
    HandshakeError,
)
from .odometry import OdometrySample, OdometryTracker, RobotParams, params_for_subclass

#: the simulator port (MobileSim/AMRISim) and a serial default
DEFAULT_TCP_URL = "socket://127.0.0.1:8101"
DEFAULT_BAUDRATE = 9600


class ConnectionState(enum.Enum):
    IDLE = "idle"
    CONNECTING = "connecting"
    CONNECTED = "connected"
    RECONNECTING = "reconnecting"
    LOST = "lost"  # gone for good (reconnect off, or a bug in the reader)
    CLOSED = "closed"


@dataclass(frozen=True)
class ArcosClientConfig:
    """Client parameters; times in seconds, SI units. See docs/robot.md for the defaults' reasons."""

    url: str = DEFAULT_TCP_URL
    baudrate: int = DEFAULT_BAUDRATE
    #: after CONFIG, switch the host port to this rate with HOSTBAUD (serial only; None: stay)
    switch_baudrate: int | None = None
    #: serial only: when nothing answers at ``baudrate``, try these rates in turn (ROS p2os order:
    #: 38400, 19200, 115200, 57600); empty: no hunting
    baud_candidates: tuple[int, ...] = ()
    #: handshake attempts per hunted rate
    hunt_attempts: int = 2
    baud_switch_timeout_s: float = 0.9
    port_timeout_s: float = 0.05
    write_timeout_s: float = 1.0
    sync_step_timeout_s: float = 1.0
    sync_attempts: int = 6
    #: after CLOSE to a stale session: how long to wait before flushing and restarting at SYNC0
    stale_close_wait_s: float = 0.3
    config_timeout_s: float = 1.0
    require_config: bool = False
    enable_motors: bool = True
    #: working limits sent at connect (None: keep the controller's)
    max_v_mps: float | None = None
    max_w_radps: float | None = None
    accel_mps2: float | None = None
    decel_mps2: float | None = None
    rot_accel_radps2: float | None = None
    rot_decel_radps2: float | None = None
    keepalive_interval_s: float = 0.5
    heartbeat_timeout_s: float = 1.0
    #: None disables the client-side command timeout (the firmware watchdog still applies)
    command_timeout_s: float | None = 1.0
    sip_silence_timeout_s: float = 2.0
    partial_frame_timeout_s: float = 0.1
    reconnect: bool = True
    reconnect_initial_s: float = 0.2
    reconnect_max_s: float = 2.0
    #: unknown SYNC2 subclasses: use this table instead of failing (e.g. "p3dx")
    subclass_fallback: str | None = None
    dist_conv_mm_per_count: float | None = None
    angle_conv_rad_per_unit: float | None = None
    gap_factor: float = 2.5
    buffer_capacity: int = 8

    def __post_init__(self) -> None:
        positive = (
            "port_timeout_s", "write_timeout_s", "sync_step_timeout_s", "config_timeout_s", "keepalive_interval_s",
            "heartbeat_timeout_s", "sip_silence_timeout_s", "partial_frame_timeout_s", "reconnect_initial_s",
            "baud_switch_timeout_s",
        )  # fmt: skip
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ArcosConfigError(f"{name} must be finite and > 0, got {value}")
        if self.command_timeout_s is not None and not self.command_timeout_s > 0:
            raise ArcosConfigError(f"command_timeout_s must be > 0 or None, got {self.command_timeout_s}")
        if self.sync_attempts < 1:
            raise ArcosConfigError("sync_attempts must be >= 1")
        if self.baudrate not in codec.HOSTBAUD_CODES:
            raise ArcosConfigError(f"baudrate must be one of {sorted(codec.HOSTBAUD_CODES)}, got {self.baudrate}")
        if self.switch_baudrate is not None and self.switch_baudrate not in codec.HOSTBAUD_CODES:
            raise ArcosConfigError(f"switch_baudrate must be one of {sorted(codec.HOSTBAUD_CODES)}")
        bad = [b for b in self.baud_candidates if b not in codec.HOSTBAUD_CODES]
        if bad:
            raise ArcosConfigError(f"baud_candidates must be among {sorted(codec.HOSTBAUD_CODES)}, got {bad}")
        if self.hunt_attempts < 1:
            raise ArcosConfigError("hunt_attempts must be >= 1")

    @property
    def is_socket(self) -> bool:
        return "://" in self.url


@dataclass
class ClientStats:
    sessions: int = 0
    sync_restarts: int = 0
    stale_sessions: int = 0
    sync_duplicates: int = 0
    bad_frames: int = 0
    checksum_errors: int = 0
    keepalives_sent: int = 0
    command_timeouts: int = 0
    reconnects: int = 0
    controller_resets: int = 0
    baud_fallbacks: int = 0
    baud_hunts: int = 0  # rates tried beyond the configured one
    unexpected_packets: int = 0
    #: the most recent errors met by the reader (bounded, newest last)
    errors: collections.deque[str] = field(default_factory=lambda: collections.deque(maxlen=32))


@dataclass(frozen=True)
class RobotInfo:
    """What the handshake and CONFIGpac told us about the robot."""

    name: str
    robot_class: str
    subclass: str
    params: RobotParams
    config: ConfigPacket | None
    baudrate: int | None  # None on TCP


class ArcosClient:
    """A Pioneer on ARCOS. Use as a context manager or call :meth:`connect` and :meth:`close`."""

    def __init__(self, config: ArcosClientConfig | None = None, **overrides: object) -> None:
        if config is None:
            config = ArcosClientConfig(**overrides)  # type: ignore[arg-type]
        elif overrides:
            raise ArcosConfigError("pass either a config or keyword overrides, not both")
        self.config = config
        self.samples: LatestBuffer[OdometrySample] = LatestBuffer(config.buffer_capacity)
        self.stats = ClientStats()
        self._lock = threading.RLock()  # port writes, tracker, command state
        self._port: serial.SerialBase | None = None
        self._decoder = ArcosDecoder()
        self._tracker: OdometryTracker | None = None
        self._info: RobotInfo | None = None
        self._state = ConnectionState.IDLE
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_error: BaseException | None = None
        self._last_sample: OdometrySample | None = None
        self._last_encoder: EncoderPacket | None = None
        self._last_io: codec.IoPacket | None = None
        #: after close(): whether the controller went quiet after CLOSE (None: close never reached it)
        self.close_confirmed: bool | None = None
        self._baudrate: int | None = None
        now = time.monotonic()
        self._last_write_s = now
        self._last_heartbeat_s = now
        self._last_command_s = now
        self._command_active = False  # a non-zero velocity is in force
        self._last_sip_s = now
        self._last_rx_s = now

    # -- properties -----------------------------------------------------------------------------

    @property
    def state(self) -> ConnectionState:
        return self._state

    @property
    def info(self) -> RobotInfo:
        if self._info is None:
            raise ArcosDisconnectedError("not connected")
        return self._info

    @property
    def last_error(self) -> BaseException | None:
        """The most recent error the reader thread met (also raised by ``samples.get`` while down)."""
        return self._last_error

    @property
    def last_sample(self) -> OdometrySample | None:
        """The newest sample ever received (not consumed, unlike ``samples.latest()``)."""
        return self._last_sample

    @property
    def keepalive_interval_s(self) -> float:
        """The keep-alive period in force: the configured one, but at most a quarter of the controller's watchdog."""
        interval = self.config.keepalive_interval_s
        info = self._info
        watchdog_ms = info.config.int_value("watchdog_ms") if info is not None and info.config is not None else None
        if watchdog_ms:
            interval = min(interval, watchdog_ms / 4000.0)
        return interval

    @property
    def last_encoder(self) -> EncoderPacket | None:
        return self._last_encoder

    @property
    def last_io(self) -> codec.IoPacket | None:
        return self._last_io

    @property
    def decoder_stats(self) -> codec.DeframerStats:
        return self._decoder.deframer.stats

    # -- life cycle -----------------------------------------------------------------------------

    def connect(self) -> RobotInfo:
        """Open the port, run the handshake, OPEN, read CONFIG, ENABLE; start the reader thread."""
        if self._state not in (ConnectionState.IDLE, ConnectionState.CLOSED, ConnectionState.LOST):
            raise ArcosConfigError(f"connect() in state {self._state.value}")
        if self._thread is not None:  # a reader that ended after a loss
            self._thread.join(timeout=5.0)
            self._thread = None
        self.samples.set_error(None)
        self._stop.clear()
        self._state = ConnectionState.CONNECTING
        try:
            self._open_session()
        except BaseException:
            self._state = ConnectionState.CLOSED
            self._drop_port()
            raise
        self._state = ConnectionState.CONNECTED
        self._thread = threading.Thread(
            target=run_guarded(self._reader, self._on_reader_crash), name="p2os-reader", daemon=True
        )
        self._thread.start()
        return self.info

    def close(self) -> None:
        """Stop the robot (VEL 0, RVEL 0, ENABLE 0), CLOSE the session, release the port."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        with self._lock:
            port = self._port
            if port is not None:
                for packet in (
                    codec.vel_command(0),
                    codec.rvel_command(0),
                    codec.enable_command(False),
                    codec.close_command(),
                ):
                    try:
                        write_all(port, packet)
                    except DriverError:
                        break
                else:
                    self.close_confirmed = self._await_silence(port)
            self._drop_port()
        self._command_active = False
        self._state = ConnectionState.CLOSED

    def _await_silence(self, port: serial.SerialBase) -> bool:
        """After CLOSE: wait (bounded) until the controller stops streaming; True if it did.

        This also keeps the port open long enough for the last bytes to leave it (a pty drops what
        its reader has not taken when the writer closes).
        """
        cycle_s = self._tracker.sip_cycle_s if self._tracker is not None else 0.1
        quiet_s = 1.5 * cycle_s + 0.05
        deadline = time.monotonic() + max(0.5, 3 * quiet_s)
        last_data = time.monotonic()
        while time.monotonic() < deadline:
            try:
                data = read_some(port)
            except DisconnectedError:
                return True
            if data:
                last_data = time.monotonic()
            elif time.monotonic() - last_data >= quiet_s:
                return True
        return False

    def __enter__(self) -> ArcosClient:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- commands (any thread) ------------------------------------------------------------------

    def heartbeat(self) -> None:
        """The application is alive: keep the firmware watchdog fed for another ``heartbeat_timeout_s``."""
        self._last_heartbeat_s = time.monotonic()

    def _send(self, *packets: bytes) -> None:
        with self._lock:
            port = self._port
            if port is None or self._state != ConnectionState.CONNECTED:
                raise ArcosDisconnectedError(f"robot not connected (state {self._state.value})")
            for packet in packets:
                try:
                    write_all(port, packet)
                except DriverTimeoutError as exc:
                    raise ArcosTimeoutError(str(exc)) from exc
                except DisconnectedError as exc:
                    raise ArcosDisconnectedError(str(exc)) from exc
            self._last_write_s = time.monotonic()

    def set_velocity(self, v_mps: float, w_radps: float) -> None:
        """VEL + RVEL: translation (m/s, + forward) and rotation (rad/s, + CCW; whole deg/s on the wire)."""
        if not (math.isfinite(v_mps) and math.isfinite(w_radps)):
            raise ArcosConfigError(f"velocities must be finite, got {v_mps}, {w_radps}")
        packets = (codec.vel_command(v_mps * 1000.0), codec.rvel_command(math.degrees(w_radps)))
        with self._lock:
            self._send(*packets)
            now = time.monotonic()
            self._last_command_s = self._last_heartbeat_s = now
            self._command_active = abs(v_mps) >= 0.0005 or abs(math.degrees(w_radps)) >= 0.5

    def set_wheel_velocities(self, left_mps: float, right_mps: float) -> None:
        """VEL2: independent wheel speeds (resolution ``vel2_divisor_mmps``, 20 mm/s on a P3-DX)."""
        divisor = self.info.params.vel2_divisor_mmps
        packet = codec.vel2_command(left_mps * 1000.0, right_mps * 1000.0, divisor)
        with self._lock:
            self._send(packet)
            now = time.monotonic()
            self._last_command_s = self._last_heartbeat_s = now
            self._command_active = codec.vel2_value(left_mps * 1000.0, right_mps * 1000.0, divisor) != 0

    def stop(self) -> None:
        """STOP: halt with the normal deceleration."""
        with self._lock:
            self._send(codec.stop_command())
            self._command_active = False
            self._last_heartbeat_s = time.monotonic()

    def e_stop(self) -> None:
        """E_STOP: halt at once, overriding the deceleration."""
        with self._lock:
            self._send(codec.e_stop_command())
            self._command_active = False

    def enable_motors(self, on: bool) -> None:
        self._send(codec.enable_command(on))
        self.heartbeat()

    def set_limits(
        self,
        *,
        max_v_mps: float | None = None,
        accel_mps2: float | None = None,
        decel_mps2: float | None = None,
        max_w_radps: float | None = None,
        rot_accel_radps2: float | None = None,
        rot_decel_radps2: float | None = None,
    ) -> None:
        """SETV / SETA (+accel, -decel) / SETRV / SETRA (+accel, -decel); None leaves a limit unchanged."""
        packets: list[bytes] = []
        if max_v_mps is not None:
            packets.append(codec.setv_command(max_v_mps * 1000.0))
        if accel_mps2 is not None:
            packets.append(codec.seta_command(abs(accel_mps2) * 1000.0))
        if decel_mps2 is not None:
            packets.append(codec.seta_command(-abs(decel_mps2) * 1000.0))
        if max_w_radps is not None:
            packets.append(codec.setrv_command(math.degrees(max_w_radps)))
        if rot_accel_radps2 is not None:
            packets.append(codec.setra_command(abs(math.degrees(rot_accel_radps2))))
        if rot_decel_radps2 is not None:
            packets.append(codec.setra_command(-abs(math.degrees(rot_decel_radps2))))
        if packets:
            self._send(*packets)

    def reset_odometry(self) -> None:
        """SETO: the controller's origin becomes the odometry frame (from the first SIP after it)."""
        with self._lock:
            self._send(codec.seto_command())
            if self._tracker is not None:
                self._tracker.request_seto()

    def request_encoder(self, on: bool) -> None:
        """Start (ENCODER 2) or stop the 0x90 stream; mind the bandwidth at 9600 baud."""
        self._send(codec.encoder_command(2 if on else 0))

    def request_io(self, mode: int) -> None:
        """IOREQUEST: IOpac 0 stop / 1 once / 2 continuous; the newest is ``last_io``."""
        self._send(codec.io_request_command(mode))

    def send_raw(self, packet: bytes) -> None:
        """Send a pre-built frame (any command of :mod:`drivers.p2os.codec`)."""
        self._send(packet)

    def get_sample(self, timeout_s: float = 1.0) -> OdometrySample:
        """Oldest unread sample; raises the reader's error while the link is down."""
        return self.samples.get(timeout_s)

    # -- session --------------------------------------------------------------------------------

    def _drop_port(self) -> None:
        close_quietly(self._port)
        self._port = None

    def _interruptible_sleep(self, seconds: float) -> None:
        if self._stop.wait(seconds):
            raise ArcosDisconnectedError("client closing")

    def _open_session(self) -> None:
        cfg = self.config
        try:
            port = open_port(
                cfg.url,
                baudrate=cfg.baudrate,
                timeout_s=cfg.port_timeout_s,
                write_timeout_s=cfg.write_timeout_s,
            )
        except DisconnectedError as exc:
            raise ArcosDisconnectedError(str(exc)) from exc
        with self._lock:
            self._port = port
            self._decoder = ArcosDecoder()
            self._baudrate = None if cfg.is_socket else cfg.baudrate
        try:
            try:
                identity = self._handshake(port)
            except ArcosTimeoutError as silent:
                identity = self._hunt_baud(port, silent)
            params = params_for_subclass(
                identity.subclass,
                fallback=cfg.subclass_fallback,
                dist_conv_mm_per_count=cfg.dist_conv_mm_per_count,
                angle_conv_rad_per_unit=cfg.angle_conv_rad_per_unit,
            )
            with self._lock:
                if self._tracker is None:
                    self._tracker = OdometryTracker(params, gap_factor=cfg.gap_factor)
                else:
                    self._tracker.params = params
                    self._tracker.restart_session()
            self._write_direct(port, codec.open_command())
            now = time.monotonic()
            self._last_sip_s = self._last_rx_s = now
            self._last_heartbeat_s = now
            self._command_active = False
            config_packet = self._read_config(port)
            if config_packet is not None:
                self._apply_config(config_packet)
            self._info = RobotInfo(
                name=identity.name,
                robot_class=identity.robot_class,
                subclass=identity.subclass,
                params=params,
                config=config_packet,
                baudrate=self._baudrate,
            )
            if cfg.switch_baudrate is not None and not cfg.is_socket and config_packet is not None:
                self._maybe_switch_baud(port, config_packet)
            limits = self._limit_packets()
            for packet in limits:
                self._write_direct(port, packet)
            if cfg.enable_motors:
                self._write_direct(port, codec.enable_command(True))
            self.stats.sessions += 1
        except BaseException:
            with self._lock:
                self._drop_port()
            raise

    def _write_direct(self, port: serial.SerialBase, packet: bytes) -> None:
        try:
            write_all(port, packet)
        except DriverTimeoutError as exc:
            raise ArcosTimeoutError(str(exc)) from exc
        except DisconnectedError as exc:
            raise ArcosDisconnectedError(str(exc)) from exc
        self._last_write_s = time.monotonic()

    def _read_events(self, port: serial.SerialBase) -> list[codec.Event]:
        try:
            data = read_some(port)
        except DisconnectedError as exc:
            raise ArcosDisconnectedError(str(exc)) from exc
        now = time.monotonic()
        if data:
            self._last_rx_s = now
            events = self._decoder.feed(data)
        elif self._decoder.pending and now - self._last_rx_s > self.config.partial_frame_timeout_s:
            events = self._decoder.expire_partial()
        else:
            events = []
        for ev in events:
            if isinstance(ev, BadFrame):
                self.stats.bad_frames += 1
                if ev.kind is codec.BadFrameKind.CHECKSUM:
                    self.stats.checksum_errors += 1
        return events

    def _flush_input(self, port: serial.SerialBase, quiet_s: float = 0.1, max_s: float = 1.0) -> None:
        """Discard input until the line has been quiet for ``quiet_s`` (bounded by ``max_s``)."""
        try:
            port.reset_input_buffer()
        except (serial.SerialException, OSError):
            pass
        deadline = time.monotonic() + max_s
        last_data = time.monotonic()
        while time.monotonic() < deadline and time.monotonic() - last_data < quiet_s:
            if self._stop.is_set():
                raise ArcosDisconnectedError("client closing")
            try:
                if read_some(port):
                    last_data = time.monotonic()
            except DisconnectedError as exc:
                raise ArcosDisconnectedError(str(exc)) from exc
        self._decoder.clear()

    def _hunt_baud(self, port: serial.SerialBase, silent: ArcosTimeoutError) -> RobotIdentity:
        """Nothing answered at the configured rate: try ``baud_candidates`` (serial only), else re-raise."""
        cfg = self.config
        if cfg.is_socket or not cfg.baud_candidates:
            raise silent
        tried = [cfg.baudrate]
        for rate in cfg.baud_candidates:
            if rate in tried:
                continue
            tried.append(rate)
            try:
                port.baudrate = rate
            except (serial.SerialException, OSError, ValueError) as exc:
                raise ArcosDisconnectedError(f"cannot set {rate} baud: {exc}") from exc
            self._baudrate = rate
            self.stats.baud_hunts += 1
            self._flush_input(port, quiet_s=0.05, max_s=0.3)
            try:
                return self._handshake(port, attempts=cfg.hunt_attempts)
            except ArcosTimeoutError:
                continue
        raise ArcosTimeoutError(f"no answer to SYNC from {cfg.url} at {', '.join(map(str, tried))} baud")

    def _handshake(self, port: serial.SerialBase, attempts: int | None = None) -> RobotIdentity:
        """SYNC0, SYNC1, SYNC2 with a per-step timeout and a bounded number of restarts."""
        cfg = self.config
        max_attempts = cfg.sync_attempts if attempts is None else attempts
        attempts = 0
        heard_anything = False
        step = 0
        identity: RobotIdentity | None = None
        while True:
            self._write_direct(port, codec.sync_command(step))
            deadline = time.monotonic() + cfg.sync_step_timeout_s
            outcome = ""
            while not outcome:
                if self._stop.is_set():
                    raise ArcosDisconnectedError("client closing")
                if time.monotonic() >= deadline:
                    outcome = "timeout"
                    break
                for ev in self._read_events(port):
                    if isinstance(ev, BadFrame):
                        continue
                    heard_anything = True
                    if isinstance(ev, Sip | ConfigPacket | EncoderPacket):
                        outcome = "stale"
                    elif isinstance(ev, SyncEcho):
                        if ev.step == step:
                            outcome = "ok"
                        elif ev.step < step:
                            self.stats.sync_duplicates += 1  # a late echo of an earlier step: ignore
                            continue
                        else:
                            outcome = "misorder"
                    elif isinstance(ev, RobotIdentity):
                        if step == 2:
                            identity = ev
                            outcome = "ok"
                        else:
                            outcome = "misorder"
                    else:  # reset packet (id 255/254) or anything else: restart
                        outcome = "misorder"
                    if outcome:
                        break
            if outcome == "ok":
                step += 1
                if step == 3:
                    assert identity is not None
                    return identity
                continue
            attempts += 1
            self.stats.sync_restarts += 1
            if attempts >= max_attempts:
                if not heard_anything:
                    raise ArcosTimeoutError(
                        f"no answer to SYNC from {cfg.url} after {attempts} tries "
                        f"({cfg.sync_step_timeout_s:.1f} s each); check the port, baud rate and power"
                    )
                raise HandshakeError(f"handshake with {cfg.url} failed after {attempts} restarts (last: {outcome})")
            if outcome == "stale" or outcome == "timeout":
                # an open session from an earlier client (or a controller in an unknown state): close it
                if outcome == "stale":
                    self.stats.stale_sessions += 1
                self._write_direct(port, codec.close_command())
                self._interruptible_sleep(cfg.stale_close_wait_s)
            self._flush_input(port)
            step = 0

    def _read_config(self, port: serial.SerialBase) -> ConfigPacket | None:
        cfg = self.config
        self._write_direct(port, codec.config_command())
        deadline = time.monotonic() + cfg.config_timeout_s
        while time.monotonic() < deadline:
            if self._stop.is_set():
                raise ArcosDisconnectedError("client closing")
            for ev in self._read_events(port):
                if isinstance(ev, ConfigPacket):
                    return ev
                self._handle_event(ev, time.monotonic())
        if cfg.require_config:
            raise ArcosTimeoutError(f"no CONFIGpac within {cfg.config_timeout_s:.1f} s")
        return None

    def _apply_config(self, packet: ConfigPacket) -> None:
        with self._lock:
            tracker = self._tracker
            if tracker is None:
                return
            cycle_ms = packet.int_value("sip_cycle_ms")
            if cycle_ms:
                tracker.sip_cycle_s = cycle_ms / 1000.0
            vtop = packet.int_value("trans_vel_top_mmps")
            wtop = packet.int_value("rot_vel_top_degps")
            if vtop:
                tracker.max_v_mps = vtop / 1000.0
            if wtop:
                tracker.max_w_radps = math.radians(wtop)

    def _limit_packets(self) -> list[bytes]:
        cfg = self.config
        packets: list[bytes] = []
        if cfg.max_v_mps is not None:
            packets.append(codec.setv_command(cfg.max_v_mps * 1000.0))
        if cfg.accel_mps2 is not None:
            packets.append(codec.seta_command(abs(cfg.accel_mps2) * 1000.0))
        if cfg.decel_mps2 is not None:
            packets.append(codec.seta_command(-abs(cfg.decel_mps2) * 1000.0))
        if cfg.max_w_radps is not None:
            packets.append(codec.setrv_command(math.degrees(cfg.max_w_radps)))
        if cfg.rot_accel_radps2 is not None:
            packets.append(codec.setra_command(abs(math.degrees(cfg.rot_accel_radps2))))
        if cfg.rot_decel_radps2 is not None:
            packets.append(codec.setra_command(-abs(math.degrees(cfg.rot_decel_radps2))))
        return packets

    def _set_line_rate(self, port: serial.SerialBase, baud: int, what: str) -> None:
        """Switch the host side to ``baud``, drop what arrived at the old rate, poke the controller."""
        try:
            port.baudrate = baud
            # bytes that arrived at the old rate (SIPs sent before the controller switched) prove nothing
            port.reset_input_buffer()
        except (serial.SerialException, OSError, ValueError) as exc:
            raise ArcosDisconnectedError(f"cannot {what} {baud} baud: {exc}") from exc
        self._decoder.clear()
        self._write_direct(port, codec.pulse_command())

    def _maybe_switch_baud(self, port: serial.SerialBase, packet: ConfigPacket) -> None:
        """HOSTBAUD switch as ARIA does it: only if the controller allows it (ResetBaud 2), with fallback."""
        cfg = self.config
        target = cfg.switch_baudrate
        current = self._baudrate
        if target is None or current is None or target <= current or packet.int_value("reset_baud") != 2:
            return
        self._write_direct(port, codec.hostbaud_command(target))
        time.sleep(0.05)  # let the command leave the UART at the old rate
        self._set_line_rate(port, target, "set")
        deadline = time.monotonic() + cfg.baud_switch_timeout_s
        # Two SIPs at the new rate prove the switch: one may have left the controller at the old rate
        # and still come through after the flush (USB-serial adapters deliver their FIFO late).
        sips_at_new_rate = 0
        while time.monotonic() < deadline:
            for ev in self._read_events(port):
                if isinstance(ev, Sip):
                    sips_at_new_rate += 1
                    if sips_at_new_rate < 2:
                        continue
                    self._baudrate = target
                    self._handle_event(ev, time.monotonic())
                    if self._info is not None:
                        self._info = dataclasses.replace(self._info, baudrate=target)
                    return
        # no SIP at the new rate: fall back to the old one
        self.stats.baud_fallbacks += 1
        self._set_line_rate(port, current, "restore")
        self._last_sip_s = time.monotonic()  # the silence timeout starts again on the restored line

    # -- reader thread ----------------------------------------------------------------------------

    def _handle_event(self, ev: codec.Event, now: float) -> None:
        if isinstance(ev, Sip):
            with self._lock:
                tracker = self._tracker
                if tracker is None:
                    return
                sample = tracker.update(ev, now)
            self._last_sip_s = now
            self._last_sample = sample
            self.samples.put(sample)
        elif isinstance(ev, ResetPacket):
            self.stats.controller_resets += 1
            raise ControllerResetError(f"controller reset packet {ev.packet_type:#04x}: the session is gone")
        elif isinstance(ev, EncoderPacket):
            self._last_encoder = ev
        elif isinstance(ev, codec.IoPacket):
            self._last_io = ev
        elif isinstance(ev, ConfigPacket):
            if self._info is not None:
                self._info = dataclasses.replace(self._info, config=ev)
        elif isinstance(ev, BadFrame):
            pass  # counted in _read_events
        else:
            self.stats.unexpected_packets += 1

    def _housekeeping(self, now: float) -> None:
        cfg = self.config
        if now - self._last_sip_s > cfg.sip_silence_timeout_s:
            raise ArcosDisconnectedError(f"no SIP for {now - self._last_sip_s:.1f} s")
        with self._lock:
            port = self._port
            if port is None:
                return
            if (
                cfg.command_timeout_s is not None
                and self._command_active
                and now - self._last_command_s > cfg.command_timeout_s
            ):
                self._write_direct(port, codec.vel_command(0))
                self._write_direct(port, codec.rvel_command(0))
                self._command_active = False
                self.stats.command_timeouts += 1
            alive = now - self._last_heartbeat_s <= cfg.heartbeat_timeout_s
            if alive and now - self._last_write_s >= self.keepalive_interval_s:
                self._write_direct(port, codec.pulse_command())
                self.stats.keepalives_sent += 1

    def _run_session(self) -> None:
        while not self._stop.is_set():
            port = self._port
            if port is None:
                raise ArcosDisconnectedError("port closed")
            for ev in self._read_events(port):
                self._handle_event(ev, time.monotonic())
            self._housekeeping(time.monotonic())

    def _reader(self) -> None:
        cfg = self.config
        backoff = Backoff(cfg.reconnect_initial_s, max(cfg.reconnect_initial_s, cfg.reconnect_max_s))
        while not self._stop.is_set():
            try:
                self._run_session()
                return
            except ArcosError as exc:
                if self._stop.is_set():
                    return
                self._last_error = exc
                self.stats.errors.append(f"{type(exc).__name__}: {exc}")
                self.samples.set_error(exc)
                with self._lock:
                    self._drop_port()
                    self._command_active = False
                if not self.config.reconnect:
                    self._state = ConnectionState.LOST
                    return
                self._state = ConnectionState.RECONNECTING
            # reconnect with backoff until it works or we are closed
            while not self._stop.is_set():
                if self._stop.wait(backoff.next_delay()):
                    return
                try:
                    self._open_session()
                except ArcosError as exc:
                    self._last_error = exc
                    self.stats.errors.append(f"reconnect: {type(exc).__name__}: {exc}")
                    continue
                backoff.reset()
                self.stats.reconnects += 1
                self.samples.set_error(None)
                self._state = ConnectionState.CONNECTED
                break

    def _on_reader_crash(self, exc: BaseException) -> None:
        self._last_error = exc
        self.stats.errors.append(f"reader crashed: {type(exc).__name__}: {exc}")
        self.samples.set_error(exc if isinstance(exc, DriverError) else ArcosError(f"reader thread failed: {exc!r}"))
        self._state = ConnectionState.LOST
