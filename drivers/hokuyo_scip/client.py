"""UTM-30LX client: owns the port, the handshake, one reader thread, reconnects. Thin over the codec.

Usage::

    with Utm30lxClient("/dev/hokuyo") as lidar:          # or a pty path, or socket://host:10940
        print(lidar.info.params.n_steps)
        scan = lidar.get_scan()                           # one GD scan (laser switched on)
        lidar.start_stream()                              # MD, newest-wins buffer
        scan = lidar.next_scan(timeout_s=1.0)

Threads: commands (VV/PP/II/BM/QT/GD/TM...) run on the caller's thread while nothing streams; while
a stream runs, one reader thread owns the port, puts scans into a :class:`~drivers.common.LatestBuffer`
and reconnects on its own after an unplug or ``silent_windows_before_reconnect`` windows of
``frame_timeout_s`` without a valid frame. A reader thread that gives up surfaces its error through
the buffer (raised by the next :meth:`Utm30lxClient.next_scan`) and :attr:`Utm30lxClient.last_error`.

Clocks: every scan carries the host's ``time.monotonic()`` at receipt and the device's 24-bit ms
stamp, unwrapped (resets after RS or a reconnect start a new epoch, they are not wraps). The offset
between them comes from TM round trips at open and after each reconnect; while streaming,
:class:`~drivers.hokuyo_scip.timebase.DriftTracker` follows the drift between syncs.
"""

from __future__ import annotations

import enum
import logging
import math
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import serial

from drivers.common import Backoff, LatestBuffer, close_quietly, open_port, read_some, write_all
from drivers.errors import DisconnectedError, DriverError, DriverTimeoutError

from .codec import (
    DecodeError,
    DecodeErrorKind,
    Event,
    ParametersReply,
    Reply,
    ScanFrame,
    ScanRequest,
    ScipDecoder,
    SensorParameters,
    SensorState,
    StateReply,
    StatusMeaning,
    StatusReply,
    TimeReply,
    VersionInfo,
    VersionReply,
    build_scan,
    build_simple,
    build_time_mode,
    parse_scan_echo,
)
from .errors import (
    ScipConfigError,
    ScipDisconnectedError,
    ScipError,
    ScipProtocolError,
    ScipStateError,
    ScipStatusError,
    ScipTimeoutError,
)
from .timebase import ClockOffset, ClockOffsetEstimator, DriftTracker, TimestampUnwrapper

Clock = Callable[[], float]

DEFAULT_TCP_PORT = 10940

log = logging.getLogger(__name__)


class ConnectionState(enum.Enum):
    CLOSED = "closed"
    CONNECTING = "connecting"
    IDLE = "idle"  # open, not streaming
    STREAMING = "streaming"
    RECONNECTING = "reconnecting"
    FAILED = "failed"  # the reader thread gave up; see last_error


@dataclass(frozen=True)
class ClientConfig:
    """Client parameters (SI units). Defaults suit the USB UTM-30LX at 40 Hz."""

    #: per-read port timeout; bounds how long the reader blocks between checks
    read_timeout_s: float = 0.02
    write_timeout_s: float = 1.0
    #: longest wait for one command's reply (the real sensor answers within about one revolution)
    reply_timeout_s: float = 1.0
    #: silence that ends the drain at open (about 2 scan periods, as the fact sheet advises)
    drain_idle_s: float = 0.06
    #: the drain at open gives up waiting for silence after this long (a streaming sensor is never silent)
    drain_max_s: float = 0.3
    #: a window without any valid frame; urg_library uses about 16 scan periods (0.39 s)
    frame_timeout_s: float = 0.4
    #: consecutive silent windows before the port is closed and reopened (peers use 4)
    silent_windows_before_reconnect: int = 4
    #: reconnect attempts before the reader gives up (0: keep trying until stopped)
    max_reconnect_attempts: int = 0
    backoff_initial_s: float = 0.1
    backoff_max_s: float = 2.0
    #: scans kept for a slow consumer (newest wins)
    buffer_capacity: int = 4
    #: step window; None = the PP AMIN/AMAX
    start_step: int | None = None
    end_step: int | None = None
    cluster: int = 1
    #: TM1 round trips at open and after each reconnect (0 = no time sync; stamps then come from arrival)
    time_sync_rounds: int = 10
    #: device-step vs host-elapsed mismatch beyond which a timestamp jump counts as a reset, not a wrap
    unwrap_tolerance_ms: float = 2000.0
    #: follow clock drift between TM syncs from the lower envelope of frame arrival latencies
    track_drift: bool = True
    #: window of that envelope, and the frames it needs
    drift_window_s: float = 10.0
    drift_min_frames: int = 20
    exclusive: bool = True
    #: irrelevant over CDC-ACM and TCP; kept for real RS-232 URG models
    baudrate: int = 115200

    def __post_init__(self) -> None:
        positive = {
            "read_timeout_s": self.read_timeout_s,
            "write_timeout_s": self.write_timeout_s,
            "reply_timeout_s": self.reply_timeout_s,
            "drain_idle_s": self.drain_idle_s,
            "drain_max_s": self.drain_max_s,
            "frame_timeout_s": self.frame_timeout_s,
            "backoff_initial_s": self.backoff_initial_s,
            "backoff_max_s": self.backoff_max_s,
        }
        for name, value in positive.items():
            if not (value > 0 and math.isfinite(value)):
                raise ScipConfigError(f"{name} must be finite and > 0, got {value}")
        if self.silent_windows_before_reconnect < 1:
            raise ScipConfigError("silent_windows_before_reconnect must be >= 1")
        if not (self.drift_window_s > 0 and math.isfinite(self.drift_window_s)) or self.drift_min_frames < 1:
            raise ScipConfigError("drift_window_s must be finite and > 0, drift_min_frames >= 1")
        if self.max_reconnect_attempts < 0 or self.time_sync_rounds < 0 or self.buffer_capacity < 1:
            raise ScipConfigError("max_reconnect_attempts and time_sync_rounds >= 0, buffer_capacity >= 1")
        if not 0 <= self.cluster <= 99:
            raise ScipConfigError(f"cluster must be 0..99, got {self.cluster}")


@dataclass(frozen=True)
class SensorInfo:
    version: VersionInfo
    params: SensorParameters
    state: SensorState
    #: II keys whose checksum matched only over the text before '<-' (old firmware quirk)
    checksum_fallback_keys: tuple[str, ...] = ()
    #: the raw KEY:value pairs of each reply: {"VV": {...}, "PP": {...}, "II": {...}}
    values: Mapping[str, Mapping[str, str]] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class LaserScan:
    """One sweep in SI units with both clocks.

    ``ranges_m`` is NaN where the sensor returned an error code (any value below DMIN) or a value
    above DMAX; ``raw_mm`` keeps the device values (error codes included). ``stamp_s`` is the
    host-clock (``time.monotonic``) time of the first beam (the window's first step; step 0 with the
    default window): device stamp (latched at step 0) + start x step time + TM offset when
    ``stamp_from_time_sync``, else arrival time minus the sweep duration. Beam i was taken at
    ``stamp_s + i * beam_dt_s``.
    """

    ranges_m: np.ndarray
    raw_mm: np.ndarray
    intensities: np.ndarray | None
    bearings_rad: np.ndarray
    device_stamp_raw_ms: int
    device_stamp_ms: int
    device_epoch: int
    host_stamp_s: float
    stamp_s: float
    stamp_from_time_sync: bool
    beam_dt_s: float
    seq: int
    remaining: int | None = None
    #: the sensor's limits (PP's DMIN/DMAX) the ranges were judged by
    dmin_mm: int = 0
    dmax_mm: int = 0

    @property
    def valid(self) -> np.ndarray:
        return ~np.isnan(self.ranges_m)

    @property
    def n_valid(self) -> int:
        return int(np.count_nonzero(self.valid))

    def rep117_ranges_m(self) -> np.ndarray:
        """The ranges with ROS REP 117's meanings for invalid readings: +inf no return within range
        (error code 1, or beyond DMAX), -inf too close (code 2), NaN erroneous (codes 3-5 and other
        values below DMIN)."""
        out = np.array(self.ranges_m, dtype=np.float64)
        raw = self.raw_mm
        out[(raw == 1) | ((raw > self.dmax_mm) & (self.dmax_mm > 0))] = np.inf
        out[raw == 2] = -np.inf
        return out


@dataclass(frozen=True)
class ClientStats:
    frames: int = 0  # scans delivered (put into the buffer or returned)
    corrupted_frames: int = 0  # replies dropped for a failed checksum or layout
    garbage_events: int = 0  # junk runs skipped before an echo, or overflowed buffers
    buffer_drops: int = 0  # scans the consumer never read (newest won)
    status_errors: int = 0  # scan frames replaced by an error status while streaming
    stray_replies: int = 0  # replies nobody asked for (left over from an earlier stream)
    silent_windows: int = 0
    reconnects: int = 0  # successful reconnections
    reconnect_failures: int = 0
    time_resets: int = 0  # device clock resets seen by the unwrapper
    last_status: str = ""  # last error status seen in a stream


@dataclass
class _Counters:
    frames: int = 0
    corrupted_frames: int = 0
    garbage_events: int = 0
    status_errors: int = 0
    stray_replies: int = 0
    silent_windows: int = 0
    reconnects: int = 0
    reconnect_failures: int = 0
    last_status: str = ""
    lock: threading.Lock = field(default_factory=threading.Lock)


@dataclass(frozen=True)
class _Stream:
    request_bytes: bytes
    request: ScanRequest
    echo_prefix: str  # the echo without the count field: frames carry the remaining count there
    finite: bool


class Utm30lxClient:
    """A UTM-30LX (SCIP 2.0) over a pyserial URL: tty/pty path or ``socket://host:10940``."""

    def __init__(self, url: str, config: ClientConfig | None = None, *, clock: Clock = time.monotonic) -> None:
        self.url = url
        self.config = config or ClientConfig()
        self._clock = clock
        self._port: serial.SerialBase | None = None
        self._decoder = ScipDecoder()
        self._unwrapper = TimestampUnwrapper(self.config.unwrap_tolerance_ms)
        self._offset: ClockOffset | None = None
        self._drift = DriftTracker(self.config.drift_window_s, self.config.drift_min_frames)
        self._info: SensorInfo | None = None
        self._state = ConnectionState.CLOSED
        self._state_lock = threading.Lock()
        self._cmd_lock = threading.RLock()
        self._buffer: LatestBuffer[LaserScan] = LatestBuffer(self.config.buffer_capacity)
        self._counters = _Counters()
        self._reader: threading.Thread | None = None
        self._stop = threading.Event()
        self._stream: _Stream | None = None
        self._bearings_cache: dict[tuple[int, int, int], np.ndarray] = {}
        self._seq = 0
        self._last_error: BaseException | None = None
        self._stream_finished = False
        self._leftover: list[tuple[Event, float]] = []

    # ---------------------------------------------------------------- properties

    @property
    def state(self) -> ConnectionState:
        return self._state

    def _set_state(self, state: ConnectionState) -> None:
        with self._state_lock:
            self._state = state

    @property
    def info(self) -> SensorInfo:
        if self._info is None:
            raise ScipStateError("the client is not open")
        return self._info

    @property
    def clock_offset(self) -> ClockOffset | None:
        """host_s = device_ms / 1000 + offset_s (None until a TM sync succeeded in this clock epoch)."""
        return self._offset

    @property
    def drift_correction_s(self) -> float:
        """What the drift tracker has added to the TM offset since the last sync or stream start."""
        return self._drift.correction_s

    @property
    def last_error(self) -> BaseException | None:
        """The last error the reader thread met (kept even when it recovered)."""
        return self._last_error

    @property
    def stats(self) -> ClientStats:
        c = self._counters
        with c.lock:
            return ClientStats(
                frames=c.frames,
                corrupted_frames=c.corrupted_frames,
                garbage_events=c.garbage_events,
                buffer_drops=self._buffer.dropped,
                status_errors=c.status_errors,
                stray_replies=c.stray_replies,
                silent_windows=c.silent_windows,
                reconnects=c.reconnects,
                reconnect_failures=c.reconnect_failures,
                time_resets=self._unwrapper.resets,
                last_status=c.last_status,
            )

    @property
    def streaming(self) -> bool:
        return self._reader is not None and self._reader.is_alive()

    # ---------------------------------------------------------------- open / close

    def open(self) -> Utm30lxClient:
        if self._state not in (ConnectionState.CLOSED, ConnectionState.FAILED):
            raise ScipStateError(f"open() while {self._state.value}")
        self._set_state(ConnectionState.CONNECTING)
        try:
            with self._cmd_lock:
                self._connect()
        except BaseException:
            self._close_port()
            self._set_state(ConnectionState.CLOSED)
            raise
        self._set_state(ConnectionState.IDLE)
        return self

    def close(self) -> None:
        """Stop streaming, switch the laser off (best effort) and release the port."""
        self._stop_reader()
        with self._cmd_lock:
            if self._port is not None:
                try:
                    self._command(build_simple("QT"), "QT")
                except DriverError:
                    pass
            self._close_port()
        self._stream = None
        self._set_state(ConnectionState.CLOSED)

    def __enter__(self) -> Utm30lxClient:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _close_port(self) -> None:
        close_quietly(self._port)
        self._port = None
        self._decoder.reset()
        self._leftover = []

    def _connect(self) -> None:
        """Open the port and bring the sensor to a known idle state; read VV/PP/II; sync the clock."""
        cfg = self.config
        self._close_port()
        try:
            port = open_port(
                self.url,
                baudrate=cfg.baudrate,
                timeout_s=cfg.read_timeout_s,
                write_timeout_s=cfg.write_timeout_s,
                exclusive=cfg.exclusive,
            )
        except DisconnectedError as exc:
            raise ScipDisconnectedError(str(exc)) from exc
        self._port = port
        try:
            port.reset_input_buffer()
        except (serial.SerialException, OSError):
            pass
        self._decoder.reset()
        # A bare LF ends whatever half command a previous client left; then drain what is in flight.
        self._write(b"\n")
        self._drain()
        self._quit_to_idle()
        version = self._command(build_simple("VV"), "VV")
        params = self._command(build_simple("PP"), "PP")
        state = self._command(build_simple("II"), "II")
        assert isinstance(version, VersionReply) and isinstance(params, ParametersReply)
        assert isinstance(state, StateReply)
        self._info = SensorInfo(
            version.info,
            params.info,
            state.info,
            state.checksum_fallback_keys,
            {"VV": dict(version.values), "PP": dict(params.values), "II": dict(state.values)},
        )
        if state.checksum_fallback_keys:
            log.warning(
                "%s: II line(s) %s matched their checksum only before '<-' (old firmware quirk)",
                self.url,
                ", ".join(state.checksum_fallback_keys),
            )
        self._bearings_cache.clear()
        # A new connection may be a power-cycled sensor: its clock is a new epoch.
        self._unwrapper.reset()
        self._offset = None
        self._drift.reset(None)
        if cfg.time_sync_rounds:
            self._sync_time_locked(cfg.time_sync_rounds)

    def _quit_to_idle(self) -> None:
        """QT; if the sensor refuses it because it is stuck in time-adjust mode, TM2 then QT again."""
        try:
            self._command(build_simple("QT"), "QT")
            return
        except ScipStatusError as exc:
            if exc.code not in ("0E", "0B", "0L", "10"):
                raise
        self._command(build_time_mode(2), "TM")
        self._command(build_simple("QT"), "QT")

    # ---------------------------------------------------------------- low-level I/O

    def _require_port(self) -> serial.SerialBase:
        if self._port is None:
            raise ScipDisconnectedError(f"{self.url} is not open")
        return self._port

    def _write(self, data: bytes) -> None:
        self._decoder.sent(data)  # what was sent tells an echo from junk that looks like one
        try:
            write_all(self._require_port(), data)
        except DriverTimeoutError as exc:
            raise ScipTimeoutError(str(exc)) from exc
        except DisconnectedError as exc:
            raise ScipDisconnectedError(f"{self.url}: {exc}") from exc

    def _read(self) -> bytes:
        try:
            return read_some(self._require_port())
        except DisconnectedError as exc:
            raise ScipDisconnectedError(f"{self.url}: {exc}") from exc

    def _drain(self) -> None:
        cfg = self.config
        start = last_data = self._clock()
        while True:
            now = self._clock()
            if now - last_data >= cfg.drain_idle_s or now - start >= cfg.drain_max_s:
                return
            data = self._read()
            if data:
                last_data = self._clock()
                self._count_events(self._decoder.feed(data), expected=None)

    def _count_events(self, events: list[Event], expected: str | None) -> None:
        c = self._counters
        with c.lock:
            for ev in events:
                if isinstance(ev, DecodeError):
                    if ev.kind in (DecodeErrorKind.GARBAGE, DecodeErrorKind.OVERFLOW):
                        c.garbage_events += 1
                    else:
                        c.corrupted_frames += 1
                elif expected is None or not (isinstance(ev, Reply) and ev.echo == expected):
                    c.stray_replies += 1

    def _transact(self, request: bytes, timeout_s: float | None = None) -> tuple[Reply, float, float]:
        """Send ``request`` and wait for the reply that echoes it; returns (reply, t_sent, t_received).

        Replies that echo something else (scan frames still in flight, replies to an earlier client)
        are skipped and counted. A reply to this request that fails its checksums raises the typed
        error at once.
        """
        expected = request.rstrip(b"\r\n").decode("ascii")
        command = expected[:3] if expected.startswith("%") else expected[:2]
        deadline_s = timeout_s if timeout_s is not None else self.config.reply_timeout_s
        if self._leftover:  # replies decoded after an earlier request's reply: nobody waits for them now
            self._count_events([ev for ev, _ in self._leftover], expected=None)
            self._leftover = []
        t_sent = self._clock()
        self._write(request)
        deadline = t_sent + deadline_s
        while True:
            data = self._read()
            now = self._clock()
            if data:
                events = self._decoder.feed(data)
                for i, ev in enumerate(events):
                    if isinstance(ev, Reply) and ev.echo == expected:
                        self._count_events(events[:i], expected=None)
                        # e.g. the first MD frame read in the same chunk as the acknowledgement
                        self._leftover = [(later, now) for later in events[i + 1 :]]
                        return ev, t_sent, now
                    if isinstance(ev, DecodeError) and ev.command == command and ev.raw.startswith(expected.encode()):
                        self._count_events(events[:i] + events[i + 1 :], expected=None)
                        raise ev.error
                self._count_events(events, expected=None)
            if now >= deadline:
                raise ScipTimeoutError(f"no reply to {expected!r} from {self.url} within {deadline_s:.3f} s")

    def _command(self, request: bytes, command: str, timeout_s: float | None = None) -> Reply:
        reply, _, _ = self._transact(request, timeout_s)
        if not reply.status.success:
            raise ScipStatusError(
                f"{reply.echo!r} answered {reply.status.description}",
                code=reply.status.code,
                command=command,
                raw=reply.echo.encode(),
            )
        return reply

    def _idle_command(self, request: bytes, command: str, timeout_s: float | None = None) -> Reply:
        if self.streaming:
            raise ScipStateError(f"{command} while streaming: call stop_stream() first")
        if self._state in (ConnectionState.CLOSED, ConnectionState.CONNECTING):
            raise ScipStateError(f"{command}: the client is not open")
        with self._cmd_lock:
            if self._port is None:  # the reader gave up earlier (FAILED), or an earlier reopen failed
                self._reopen_idle()
            try:
                return self._command(request, command, timeout_s)
            except ScipDisconnectedError:
                # Unplugged while idle: reopen (same handshake) and retry the command once.
                self._reopen_idle()
                return self._command(request, command, timeout_s)

    def _reopen_idle(self) -> None:
        self._reopen_with_backoff(max_attempts=max(1, self.config.max_reconnect_attempts or 3))
        self._set_state(ConnectionState.IDLE)

    # ---------------------------------------------------------------- commands

    def refresh_state(self) -> SensorState:
        """II again (laser state, sensor clock, status text)."""
        reply = self._idle_command(build_simple("II"), "II")
        assert isinstance(reply, StateReply)
        values = {**self.info.values, "II": dict(reply.values)}
        self._info = replace(
            self.info, state=reply.info, checksum_fallback_keys=reply.checksum_fallback_keys, values=values
        )
        return reply.info

    def laser_on(self) -> bool:
        """BM; returns False when the laser was already on (status 02, a success)."""
        reply = self._idle_command(build_simple("BM"), "BM")
        return reply.status.meaning is not StatusMeaning.ALREADY_SET

    def laser_off(self) -> None:
        self._idle_command(build_simple("QT"), "QT")

    def reset_sensor(self) -> None:
        """RS: laser off, settings to default, and the sensor clock restarts at 0 (a new epoch)."""
        self._idle_command(build_simple("RS"), "RS")
        self._unwrapper.reset()
        self._offset = None
        self._drift.reset(None)

    def sync_time(self, rounds: int = 10) -> ClockOffset:
        """TM0, ``rounds`` x TM1, TM2; the offset is the median of the round-trip midpoints.

        Time-adjust mode switches the laser off (the next stream switches it on again).
        """
        if rounds < 1:
            raise ScipConfigError("rounds must be >= 1")
        if self.streaming:
            raise ScipStateError("sync_time while streaming: call stop_stream() first")
        with self._cmd_lock:
            return self._sync_time_locked(rounds)

    def _sync_time_locked(self, rounds: int) -> ClockOffset:
        estimator = ClockOffsetEstimator()
        self._command(build_time_mode(0), "TM")
        try:
            for _ in range(rounds):
                reply, t_sent, t_recv = self._transact(build_time_mode(1))
                if not isinstance(reply, TimeReply):
                    raise ScipStatusError(
                        f"TM1 answered {reply.status.description}", code=reply.status.code, command="TM"
                    )
                stamp = self._unwrapper.update(reply.timestamp_ms, 0.5 * (t_sent + t_recv))
                estimator.add(t_sent, t_recv, stamp.unwrapped_ms)
        finally:
            self._command(build_time_mode(2), "TM")
        self._offset = estimator.estimate(self._unwrapper.epoch)
        self._drift.reset(self._offset)
        return self._offset

    def get_scan(self, intensity: bool = False, timeout_s: float | None = None) -> LaserScan:
        """One scan: BM (laser on), then GD (or GE with intensities) over the configured window."""
        self.laser_on()
        request = self._scan_request(stream=False, intensity=intensity)
        reply = self._idle_command(request, "GE" if intensity else "GD", timeout_s)
        if not isinstance(reply, ScanFrame):
            raise ScipProtocolError(f"{reply.echo!r} returned no scan data", code=reply.status.code)
        scan = self._to_scan(reply, self._clock())
        with self._counters.lock:
            self._counters.frames += 1
        return scan

    def _scan_request(self, *, stream: bool, intensity: bool, interval: int = 0, count: int = 0) -> bytes:
        p = self.info.params
        start = p.amin if self.config.start_step is None else self.config.start_step
        end = p.amax if self.config.end_step is None else self.config.end_step
        if not p.amin <= start <= end <= p.amax:
            raise ScipConfigError(f"step window {start}..{end} outside the sensor's {p.amin}..{p.amax}")
        return build_scan(
            start, end, self.config.cluster, intensity=intensity, stream=stream, interval=interval, count=count
        )

    # ---------------------------------------------------------------- streaming

    def start_stream(self, intensity: bool = False, interval: int = 0, count: int = 0) -> None:
        """MD (or ME with intensities): ``count`` 0 streams until :meth:`stop_stream`."""
        if self.streaming:
            raise ScipStateError("already streaming")
        if self._state is not ConnectionState.IDLE:
            raise ScipStateError(f"start_stream() while {self._state.value}")
        request = self._scan_request(stream=True, intensity=intensity, interval=interval, count=count)
        text = request.rstrip(b"\n").decode("ascii")
        parsed = parse_scan_echo(text[:2], request.rstrip(b"\n"))
        self._stream = _Stream(request, parsed, text.partition(";")[0][:-2], finite=count > 0)
        self._stream_finished = False
        self._drift.reset(self._offset)  # the fixed latency depends on the step window
        try:
            with self._cmd_lock:
                self._command(request, text[:2])
        except BaseException:
            self._stream = None
            raise
        self._buffer.clear()
        self._buffer.set_error(None)
        self._stop.clear()
        self._set_state(ConnectionState.STREAMING)
        self._reader = threading.Thread(target=self._reader_body, name="utm30lx-reader", daemon=True)
        self._reader.start()

    def stop_stream(self) -> None:
        """End the stream: stop the reader, QT, and discard frames until the QT echo."""
        self._stop_reader()
        self._stream = None
        if self._state in (ConnectionState.CLOSED, ConnectionState.FAILED):
            return
        with self._cmd_lock:
            if self._port is None:
                self._reopen_idle()
            self._command(build_simple("QT"), "QT")
        self._set_state(ConnectionState.IDLE)

    def _stop_reader(self) -> None:
        reader = self._reader
        if reader is not None:
            self._stop.set()
            reader.join(timeout=max(5.0, 4 * self.config.reply_timeout_s))
            if reader.is_alive():
                raise ScipTimeoutError("the reader thread did not stop")
        self._reader = None

    def next_scan(self, timeout_s: float = 1.0) -> LaserScan:
        """The oldest unread scan, waiting at most ``timeout_s``; raises the reader's error if it gave up."""
        return self._buffer.get(timeout_s)

    def wait_for_scan(self, timeout_s: float) -> bool:
        """Whether an unread scan is (or arrives within ``timeout_s``) in the buffer, without taking it."""
        return self._buffer.wait_nonempty(timeout_s)

    def latest_scan(self) -> LaserScan | None:
        """The newest scan without waiting (older unread ones are counted as dropped)."""
        return self._buffer.latest()

    def _reader_body(self) -> None:
        try:
            self._stream_loop()
        except BaseException as exc:  # noqa: BLE001 - surfaced through the buffer and last_error
            if self._stop.is_set():
                return  # stop_stream() interrupted a reconnect; it takes over from here
            self._last_error = exc
            self._set_state(ConnectionState.FAILED)
            self._buffer.set_error(exc if isinstance(exc, ScipError) else ScipError(f"reader failed: {exc!r}"))

    def _stream_loop(self) -> None:
        cfg = self.config
        last_valid = self._clock()
        silent = 0
        while not self._stop.is_set():
            # replies decoded together with the (re)start acknowledgement come first
            pending, self._leftover = self._leftover, []
            for ev, t in pending:
                if self._handle_stream_event(ev, t):
                    last_valid, silent = t, 0
            try:
                data = self._read()
            except ScipDisconnectedError as exc:
                self._last_error = exc
                self._recover(f"port lost: {exc}")
                last_valid, silent = self._clock(), 0
                continue
            now = self._clock()
            if data:
                for ev in self._decoder.feed(data):
                    if self._handle_stream_event(ev, now):
                        last_valid, silent = now, 0
            if self._stream is not None and self._stream_finished:
                self._set_state(ConnectionState.IDLE)
                return
            if now - last_valid > cfg.frame_timeout_s:
                silent += 1
                last_valid = now
                with self._counters.lock:
                    self._counters.silent_windows += 1
                if silent >= cfg.silent_windows_before_reconnect:
                    self._last_error = ScipTimeoutError(
                        f"no valid frame for {silent} x {cfg.frame_timeout_s:.3f} s from {self.url}"
                    )
                    self._recover(str(self._last_error))
                    last_valid, silent = self._clock(), 0

    def _handle_stream_event(self, ev: Event, now: float) -> bool:
        """Deliver a frame of our stream; count everything else. True when a valid frame arrived."""
        stream = self._stream
        c = self._counters
        if isinstance(ev, ScanFrame) and stream is not None and ev.echo.partition(";")[0][:-2] == stream.echo_prefix:
            scan = self._to_scan(ev, now, streaming=True)
            self._buffer.put(scan)
            with c.lock:
                c.frames += 1
            if stream.finite and ev.remaining == 0:
                self._stream_finished = True
            return True
        with c.lock:
            if isinstance(ev, DecodeError):
                if ev.kind in (DecodeErrorKind.GARBAGE, DecodeErrorKind.OVERFLOW):
                    c.garbage_events += 1
                else:
                    c.corrupted_frames += 1
            elif isinstance(ev, StatusReply) and stream is not None and ev.command == stream.request.command:
                if not ev.status.success:
                    c.status_errors += 1
                    c.last_status = ev.status.code
                else:
                    c.stray_replies += 1
            else:
                c.stray_replies += 1
        return False

    def _recover(self, reason: str) -> None:
        """Close, reopen with backoff, handshake, restart the stream. Raises when attempts run out."""
        log.warning("%s: reconnecting (%s)", self.url, reason)
        self._set_state(ConnectionState.RECONNECTING)
        with self._cmd_lock:
            self._reopen_with_backoff(self.config.max_reconnect_attempts, restart_stream=True)
        self._set_state(ConnectionState.STREAMING)

    def _reopen_with_backoff(self, max_attempts: int, restart_stream: bool = False) -> None:
        """Reopen until it works (or ``max_attempts`` failed). From the reader thread (``restart_stream``)
        a stop request aborts the wait; from the caller's thread it is a plain backoff sleep."""
        cfg = self.config
        backoff = Backoff(cfg.backoff_initial_s, cfg.backoff_max_s)
        attempts = 0
        self._close_port()
        while True:
            delay = backoff.next_delay()
            if restart_stream:
                if self._stop.wait(delay):
                    raise ScipDisconnectedError(f"{self.url}: stopped while reconnecting")
            else:
                time.sleep(delay)
            try:
                self._connect()
                if restart_stream and self._stream is not None:
                    self._command(self._stream.request_bytes, self._stream.request.command)
                with self._counters.lock:
                    self._counters.reconnects += 1
                return
            except (ScipError, DriverError) as exc:
                attempts += 1
                self._last_error = exc
                with self._counters.lock:
                    self._counters.reconnect_failures += 1
                self._close_port()
                if max_attempts and attempts >= max_attempts:
                    raise ScipDisconnectedError(f"{self.url}: reconnect failed {attempts} times: {exc}") from exc

    # ---------------------------------------------------------------- conversion

    def _bearings(self, request: ScanRequest) -> np.ndarray:
        key = (request.start, request.end, request.cluster)
        cached = self._bearings_cache.get(key)
        if cached is None:
            cached = self.info.params.bearings_rad(request.start, request.end, request.cluster)
            cached.setflags(write=False)
            self._bearings_cache[key] = cached
        return cached

    def _to_scan(self, frame: ScanFrame, host_s: float, streaming: bool = False) -> LaserScan:
        params = self.info.params
        raw = frame.distances
        ranges = raw.astype(np.float64) * 0.001
        ranges[(raw < params.dmin_mm) | (raw > params.dmax_mm)] = np.nan
        ranges.setflags(write=False)
        intensities = None
        if frame.intensities is not None:
            intensities = frame.intensities.astype(np.float64)
            intensities.setflags(write=False)
        stamp = self._unwrapper.update(frame.timestamp_ms, host_s)
        beam_dt_s = params.step_dt_s * max(frame.request.cluster, 1)
        offset = self._offset
        if offset is not None and offset.epoch == stamp.epoch:
            offset_s = offset.offset_s
            if streaming and self.config.track_drift:
                corrected = self._drift.update(stamp.unwrapped_ms, host_s)
                if corrected is not None:
                    offset_s = corrected
            # the counter is latched at step 0; the window's first beam comes start steps later
            stamp_s = stamp.unwrapped_ms / 1000.0 + offset_s + frame.request.start * params.step_dt_s
            synced = True
        else:
            if offset is not None:
                self._offset = None  # the device clock was reset: the old offset no longer holds
                self._drift.reset(None)
            sweep_s = (frame.request.end - frame.request.start + 1) * params.step_dt_s
            stamp_s = host_s - sweep_s
            synced = False
        self._seq += 1
        return LaserScan(
            ranges_m=ranges,
            raw_mm=raw,
            intensities=intensities,
            bearings_rad=self._bearings(frame.request),
            device_stamp_raw_ms=stamp.raw_ms,
            device_stamp_ms=stamp.unwrapped_ms,
            device_epoch=stamp.epoch,
            host_stamp_s=host_s,
            stamp_s=stamp_s,
            stamp_from_time_sync=synced,
            beam_dt_s=beam_dt_s,
            seq=self._seq,
            dmin_mm=params.dmin_mm,
            dmax_mm=params.dmax_mm,
            remaining=frame.remaining,
        )


def tcp_url(host: str, port: int = DEFAULT_TCP_PORT) -> str:
    """The pyserial URL of an Ethernet UTM-30LX-EW (or the TCP fake)."""
    return f"socket://{host}:{port}"
