"""Adapters from the driver clients to the control loop's ports, and the loop's assembly.

Each adapter opens its client on a background thread and keeps trying with backoff, so a device
that is absent at start-up, or fails for good, is picked up when it (re)appears without restarting
the daemon; while open, the clients reconnect on their own. Driver samples become estimator types
here (SI units throughout): ``LaserScan`` -> ``vipsm.types.Scan`` (bearings normalised by the one
formula replay uses), ``OdometrySample`` -> ``Odometry``, ``CameraFrame`` (JPEG) -> ``Frame``
(decoded with OpenCV, intrinsics from the camera calibration at the zoom in force).
"""

from __future__ import annotations

import math
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, Generic, TypeVar
from urllib.parse import urlsplit, urlunsplit

from drivers.common import Backoff
from drivers.errors import DriverError
from drivers.hokuyo_scip.client import ClientConfig as ScipConfig
from drivers.hokuyo_scip.client import ConnectionState as ScipState
from drivers.hokuyo_scip.client import LaserScan, Utm30lxClient
from drivers.p2os.client import ArcosClient, ArcosClientConfig
from drivers.p2os.client import ConnectionState as ArcosState
from drivers.ptz_cam.client import ViscaClient
from drivers.ptz_cam.config import HttpConfig, ViscaConfig
from drivers.ptz_cam.frames import CameraFrame, MjpegFrameSource
from vipsm.estimator import Estimator
from vipsm.types import Odometry, Scan

from . import logmessages as lm
from .cmd_camera import to_vipsm_frame
from .config import Config
from .daemon import ControlLoop, FrameSample, OdomSample, ScanSample, TruthFn, normalised_bearings
from .errors import AppError
from .fieldlog import FieldLog
from .legmodel import default_leg_model
from .liveview import LiveLimits, LiveView, check_exposure, layout_path, parse_listen
from .replay import deterministic_opencv
from .sdnotify import SystemdNotifier
from .status import StatusServer

C = TypeVar("C")
T = TypeVar("T")


class Opener(Generic[C]):
    """Opens a client on a background thread, retrying with backoff until it works or we stop."""

    def __init__(
        self, name: str, open_fn: Callable[[], C], close_fn: Callable[[C], None], max_backoff_s: float
    ) -> None:
        self.name = name
        self._open_fn = open_fn
        self._close_fn = close_fn
        self._backoff = Backoff(initial_s=0.1, max_s=max_backoff_s)
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self.client: C | None = None
        self.attempts = 0
        self.last_error: str = ""
        self._thread = threading.Thread(target=self._run, name=f"open-{name}", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            self.attempts += 1
            try:
                client = self._open_fn()
            except (DriverError, OSError) as exc:
                self.last_error = f"{type(exc).__name__}: {exc}"
                self._stop.wait(self._backoff.next_delay())
                continue
            with self._lock:
                if self._stop.is_set():
                    self._close_fn(client)
                    return
                self.client = client
            return

    def reopen(self) -> None:
        """The client failed for good: close it and start opening again."""
        with self._lock:
            client, self.client = self.client, None
        if client is not None:
            try:
                self._close_fn(client)
            except (DriverError, OSError):
                pass
        if not self._thread.is_alive() and not self._stop.is_set():
            self._thread = threading.Thread(target=self._run, name=f"open-{self.name}", daemon=True)
            self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)
        with self._lock:
            client, self.client = self.client, None
        if client is not None:
            try:
                self._close_fn(client)
            except (DriverError, OSError):
                pass


def drain(get: Callable[[float], T]) -> list[T]:
    """Everything a client's buffer holds now, without waiting; stops quietly when the client's
    reader has failed (the adapter's ``state`` reports that and reopens)."""
    out: list[T] = []
    while True:
        try:
            out.append(get(0.0))
        except DriverError:  # DriverTimeoutError: empty; anything else: the reader gave up
            return out


class ClientAdapter(Generic[C]):
    """What the scanner and base adapters share: the opener, counters, state mapping, close."""

    url: str = ""
    STAT_KEYS: tuple[str, ...] = ()
    OK: tuple[Any, ...] = ()
    CONNECTING: tuple[Any, ...] = ()
    FAILED: tuple[Any, ...] = ()
    opener: Opener[C]

    def detail(self) -> str:
        """The device's URL and the last reason it could not be opened (for the state-change lines)."""
        err = self.opener.last_error
        return self.url + (f"; last error: {err}" if err and self.opener.client is None else "")

    def state(self) -> str:
        """The loop's device state from the client's connection state; a failed client is reopened."""
        c = self.opener.client
        st = getattr(c, "state", None)
        if c is None or st in self.CONNECTING:
            return "connecting"
        if st in self.OK:
            return "ok"
        if st in self.FAILED:
            self.opener.reopen()
            return "failed"
        return "stalled"

    def counters(self) -> dict[str, int]:
        c = self.opener.client
        d: dict[str, int] = {"open_attempts": self.opener.attempts}
        if c is not None:
            st = c.stats  # type: ignore[attr-defined]
            d.update({k: int(getattr(st, k)) for k in self.STAT_KEYS})
        return d

    def close(self) -> None:
        self.opener.close()


# ---------------------------------------------------------------------------------------------
# scanner


def scan_from_driver(s: LaserScan) -> Scan:
    b = s.bearings_rad
    n = len(b)
    step = float(b[1] - b[0]) if n > 1 else 0.0
    return Scan(
        ranges_m=s.ranges_m.astype(float, copy=False),
        bearings_rad=normalised_bearings(float(b[0]) if n else 0.0, step, n),
        stamp_s=s.stamp_s,
        seq=s.seq,
        beam_dt_s=s.beam_dt_s,
        intensities=None if s.intensities is None else s.intensities.astype(float, copy=False),
    )


class ScannerAdapter(ClientAdapter[Utm30lxClient]):
    STAT_KEYS = ("frames", "corrupted_frames", "buffer_drops", "reconnects", "status_errors", "garbage_events")
    OK = (ScipState.STREAMING,)
    CONNECTING = (ScipState.CONNECTING, ScipState.RECONNECTING)
    FAILED = (ScipState.FAILED,)

    def __init__(self, url: str, intensity: bool, max_backoff_s: float) -> None:
        self.url = url
        self.intensity = intensity

        def open_fn() -> Utm30lxClient:
            client = Utm30lxClient(url, ScipConfig(buffer_capacity=16))  # the loop drains ~4 scans per cycle
            client.open()
            try:
                client.start_stream(intensity=intensity)
            except BaseException:
                client.close()
                raise
            return client

        self.opener: Opener[Utm30lxClient] = Opener("scanner", open_fn, lambda c: c.close(), max_backoff_s)

    def wait_scan(self, timeout_s: float) -> bool:
        """Blocks until a scan is ready or ``timeout_s`` passed (the loop's scan-triggered mode)."""
        start = time.monotonic()
        c = self.opener.client
        ready = c is not None and c.wait_for_scan(timeout_s)
        if not ready:  # no client, or its reader failed (returns at once): never spin
            time.sleep(max(0.0, timeout_s - (time.monotonic() - start)))
        return ready

    def poll(self) -> list[ScanSample]:
        c = self.opener.client
        if c is None:
            return []
        return [ScanSample(scan_from_driver(s), s.device_stamp_ms, s.rep117_ranges_m(), s.host_stamp_s,
                           (s.dmin_mm / 1000.0, s.dmax_mm / 1000.0) if s.dmax_mm > s.dmin_mm else None)
                for s in drain(c.next_scan)]


# ---------------------------------------------------------------------------------------------
# base


class BaseAdapter(ClientAdapter[ArcosClient]):
    STAT_KEYS = (
        "sessions",
        "checksum_errors",
        "bad_frames",
        "reconnects",
        "keepalives_sent",
        "command_timeouts",
        "controller_resets",
    )
    OK = (ArcosState.CONNECTED,)
    CONNECTING = (ArcosState.CONNECTING, ArcosState.RECONNECTING)
    FAILED = (ArcosState.LOST,)

    def __init__(self, url: str, baudrate: int, command_timeout_s: float, max_backoff_s: float,
                 command_period_s: float = 0.0) -> None:
        self.url = url
        self.command_period_s = command_period_s
        self._sent: tuple[float, float, float, ArcosClient] | None = None  # v, w, when, to which client
        def open_fn() -> ArcosClient:
            client = ArcosClient(ArcosClientConfig(url=url, baudrate=baudrate, command_timeout_s=command_timeout_s))
            client.connect()
            return client

        self.opener: Opener[ArcosClient] = Opener("base", open_fn, lambda c: c.close(), max_backoff_s)

    def poll(self) -> list[OdomSample]:
        c = self.opener.client
        if c is None:
            return []
        return [
            OdomSample(
                Odometry(s.x_m, s.y_m, s.theta_rad, s.v_mps, s.w_radps, s.stamp_s),
                battery_v=s.battery_v,
                stalled=s.left_stall or s.right_stall,
                motors_enabled=s.motors_enabled,
            )
            for s in drain(c.get_sample)
        ]

    def command(self, v_mps: float, w_radps: float) -> None:
        """Every cycle: the loop is alive (heartbeat). The velocity goes out when it changed, when the
        client is new, or when ``command_period_s`` passed since it was last written."""
        c = self.opener.client
        if c is None:
            return
        now = time.monotonic()
        sent = self._sent
        if sent is not None and sent[3] is c and sent[:2] == (v_mps, w_radps) and now - sent[2] < self.command_period_s:
            c.heartbeat()
            return
        try:
            c.heartbeat()
            c.set_velocity(v_mps, w_radps)
            self._sent = (v_mps, w_radps, now, c)
        except DriverError:
            self._sent = None  # the client reconnects; state() shows it, the firmware watchdog stops the wheels

    def stop(self) -> None:
        self._sent = None
        c = self.opener.client
        if c is not None:
            try:
                c.stop()
            except DriverError:
                pass

    def counters(self) -> dict[str, int]:
        d = super().counters()
        if self.opener.client is not None:
            d["samples"] = self.opener.client.samples.put_count
        return d


# ---------------------------------------------------------------------------------------------
# camera


class CameraAdapter:
    """Frames over HTTP; PTZ over VISCA when a VISCA URL is given (else pan/tilt/zoom from the config)."""

    def __init__(self, config: Config) -> None:
        d = config.devices
        self._fixed_pan = math.radians(d.camera_pan_deg)
        self._fixed_tilt = math.radians(d.camera_tilt_deg)
        self._zoom = d.camera_zoom
        self._visca_cfg = ViscaConfig(baudrate=d.camera_baud)
        self._last_seq: int | None = None
        self.decode_errors = 0
        self.visca: Opener[ViscaClient] | None = None
        if d.camera_url:

            def open_visca() -> ViscaClient:
                client = ViscaClient(d.camera_url, self._visca_cfg)
                client.open()
                try:
                    client.move_to(self._fixed_pan, self._fixed_tilt, wait=True)
                    client.zoom_to(self._zoom, wait=True)  # a camera can power on zoomed
                    client.start_state_poller(0.2)
                except BaseException:
                    client.close()
                    raise
                return client

            self.visca = Opener("camera-visca", open_visca, lambda c: c.close(), d.reconnect_max_s)

        def ptz() -> Any:
            c = self.visca.client if self.visca is not None else None
            return c.last_state if c is not None else None

        self._distortion = (d.camera_k1, d.camera_k2, d.camera_p1, d.camera_p2)
        self._http_url = d.camera_http_url
        http_cfg = HttpConfig(base_url=d.camera_http_url, frame_rate=d.camera_fps)
        self.source = MjpegFrameSource(http_cfg, ptz=ptz).start()

    def frame_from_driver(self, f: CameraFrame) -> FrameSample:
        frame = to_vipsm_frame(
            f, self._visca_cfg.calibration, fallback_ptz=(self._fixed_pan, self._fixed_tilt, self._zoom), grey=True,
            distortion=self._distortion,
        )
        return FrameSample(frame, f.jpeg, f.ptz.zoom_position if f.ptz is not None else self._zoom)

    def detail(self) -> str:
        """The frame URL without its password, and the last error while not connected."""
        parts = urlsplit(self._http_url)
        host = parts.hostname or ""
        netloc = (f"{parts.username}:***@" if parts.password else "") + host + (f":{parts.port}" if parts.port else "")
        url = urlunsplit((parts.scheme, netloc, parts.path, "", ""))
        err = self.source.last_error
        return url + (f"; last error: {err}" if err is not None and not self.source.connected else "")

    def state(self) -> str:
        """"ok" once the stream is connected and its first frame came through (the HTTP answer comes
        before the first frame, when frames are not flowing yet), else "connecting"."""
        return "ok" if self.source.connected and self.source.stats.frames > 0 else "connecting"

    def latest(self) -> FrameSample | None:
        f = self.source.latest()
        if f is None or f.seq == self._last_seq:
            return None
        self._last_seq = f.seq
        try:
            return self.frame_from_driver(f)
        except DriverError:  # a JPEG OpenCV cannot decode: counted, the cycle runs without it
            self.decode_errors += 1
            return None

    def counters(self) -> dict[str, int]:
        st = self.source.stats
        d = {
            "frames": st.frames,
            "truncated": st.truncated,
            "reconnects": st.reconnects,
            "bytes_received": st.bytes_received,
            "decode_errors": self.decode_errors,
            "buffer_drops": self.source.buffer.dropped,
        }
        if self.visca is not None and self.visca.client is not None:
            vs = self.visca.client.stats
            d.update({"visca_requests": vs.requests, "visca_timeouts": vs.timeouts, "visca_reconnects": vs.reconnects})
        return d

    def close(self) -> None:
        self.source.stop()
        if self.visca is not None:
            self.visca.close()


# ---------------------------------------------------------------------------------------------


def _new_field_log(config: Config, path: str) -> FieldLog | None:
    """The field log (to ``path``, and/or feeding the live view), not yet started (no file yet); None
    when neither is wanted."""
    if not path and not config.live.listen:
        return None
    lc = config.log
    return FieldLog(path or None, compression=lc.compression, rotate_bytes=lc.rotate_bytes, rotate_s=lc.rotate_s,
                    flush_s=lc.flush_s, queue_size=lc.queue_size)


def _start_field_log(log: FieldLog, path: str) -> None:
    """Opens the first file and starts the writer."""
    try:
        log.start()
    except OSError as exc:  # unwritable folder, name too long, no such folder, disk full
        raise AppError(f"config key 'log.path': cannot open {path!r} for writing: {exc.strerror or exc}") from exc


def _start_status_server(config: Config) -> StatusServer | None:
    if not config.status.enabled:
        return None
    s = config.status
    return StatusServer(s.host, s.port, s.allow_stop_coil, s.max_connections, s.idle_timeout_s).start()


def _live_address(config: Config) -> tuple[str, int] | None:
    if not config.live.listen:
        return None
    host, port = parse_listen(config.live.listen)
    warning = check_exposure(host, config.live.allow_remote)
    if warning:
        print(f"vipsm-robot: warning: {warning}", file=sys.stderr, flush=True)
    return host, port


def _start_live_view(address: tuple[str, int] | None, field_log: FieldLog | None,
                     limits: LiveLimits) -> LiveView | None:
    if address is None:
        return None
    assert field_log is not None
    try:
        live = LiveView(field_log.context, *address, limits=limits).start()
    except AppError as exc:  # name the usual cause (a second instance) and the fix
        raise AppError(f"{exc} (port in use by another instance? give another with --live [HOST:]PORT or "
                       "live.listen, port 0 = any free port)") from exc
    print(f"vipsm-robot: info: live view on {live.url} (Foxglove or Lichtblick: open connection, Foxglove "
          f"WebSocket; layout: {layout_path()})", file=sys.stderr, flush=True)
    return live


def _ros2_publisher(config: Config) -> Any:
    """The ROS 2 publisher when ``ros2.enabled``, not started (its DDS start-up runs on its own thread:
    a failure there is a state the loop reports, not an error here; a bad setting is a ConfigError)."""
    if not config.ros2.enabled:
        return None
    from .ros2.publisher import Ros2Publisher

    e = config.estimator
    mounts = lm.Mounts(e.laser_x_m, e.laser_y_m, e.laser_theta_rad, e.camera_x_m, e.camera_y_m, e.camera_z_m)
    return Ros2Publisher(config.ros2, mounts, config.loop.period_s)


def _warm_up_matcher(config: Config) -> None:
    """The estimator's compiled kernels are loaded (compiled and cached the first time) here, not in
    the control loop's first cycle; how long it took is said on stderr."""
    from vipsm.estimator import warm_up

    t0 = time.monotonic()
    warm_up(config.estimator)
    print(f"vipsm-robot: info: scan matcher ready in {time.monotonic() - t0:.2f} s (compiled kernels loaded; "
          "compiled and cached on the first run after an install)", file=sys.stderr, flush=True)


def build_loop(
    config: Config,
    *,
    log_path: str | None = None,
    truth: TruthFn | None = None,
    wait_for_devices_s: float | None = None,
) -> ControlLoop:
    """Devices, estimator, field log, status server and systemd notifier, wired into one loop."""
    deterministic_opencv()
    ros2 = _ros2_publisher(config)  # its settings checked before anything is opened
    d = config.devices
    scanner = ScannerAdapter(d.scanner_url, d.scanner_intensity, d.reconnect_max_s) if d.scanner_url else None
    base = (BaseAdapter(d.robot_url, d.robot_baud, d.robot_command_timeout_s, d.reconnect_max_s,
                        d.robot_command_period_s) if d.robot_url else None)
    camera = CameraAdapter(config) if d.camera_http_url else None
    path = log_path if log_path is not None else config.log.path
    field_log: FieldLog | None = None
    live: LiveView | None = None
    status: StatusServer | None = None
    try:
        # the ports first, the file last: a start that fails on a port in use leaves no empty log behind
        live_at = _live_address(config)
        field_log = _new_field_log(config, path)
        live = _start_live_view(live_at, field_log, LiveLimits.from_config(config.live))
        status = _start_status_server(config)
        if field_log is not None:
            _start_field_log(field_log, path)
    except (AppError, OSError):
        for server in (status, live):
            if server is not None:
                server.stop()
        for dev in (scanner, base, camera):
            if dev is not None:
                dev.close()
        raise
    _warm_up_matcher(config)
    if ros2 is not None:
        ros2.start()
    loop = ControlLoop(
        config,
        scanner=scanner,
        base=base,
        camera=camera,
        estimator=Estimator(config.estimator, leg_model=default_leg_model()),
        field_log=field_log,
        status=status,
        notifier=SystemdNotifier(),
        truth=truth,
        live_view=live,
        ros2=ros2,
    )
    # give the devices a moment to open so the first cycles are not spent in device_stop
    wait_s = config.devices.startup_wait_s if wait_for_devices_s is None else wait_for_devices_s
    deadline = time.monotonic() + wait_s
    said = False
    while time.monotonic() < deadline:
        if all(dev is None or dev.state() == "ok" for dev in (scanner, base, camera)):
            break
        if not said:
            print(f"vipsm-robot: info: waiting up to {wait_s:g} s for the devices to open "
                  "(devices.startup_wait_s)", file=sys.stderr, flush=True)
            said = True
        time.sleep(0.05)
    return loop
