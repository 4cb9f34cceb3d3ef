"""The control loop: every 0.1 s on monotonic deadlines, newest scan + odometry + frame -> estimator
-> field log, status, base command.

Devices reach the loop through three small ports (``ScannerPort``, ``BasePort``, ``CameraPort``,
implemented over the driver clients in ``app.devices``), so the loop is the same against real
hardware, the byte-level fakes and tests. Degraded modes, each logged on ``/log`` and visible in the
status registers:

* no camera (absent, failed, stale frames): plain PSM for the cycle, flagged ``plain_psm``;
* no scanner, or scans older than ``loop.max_scan_age_s`` (scan periods, :func:`scan_age_limit_s`): base
  stopped (``device_stop``);
* no odometry newer than ``loop.max_odometry_age_s``: base stopped;
* the loop itself stalled: the base driver's own command timeout zeroes the velocity, and the
  base firmware's watchdog stops it after that;
* a device that comes back is used again at once (the clients reconnect on their own).
"""

from __future__ import annotations

import dataclasses
import gc
import math
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from vipsm.estimator import Estimator
from vipsm.types import Estimate, EstimateFlag, Frame, Odometry, Scan

from . import logmessages as lm
from .config import Config
from .fieldlog import FieldLog
from .health import LoopHealth, OdometryHistory, SafetyMonitor
from .sdnotify import SystemdNotifier
from .status import ObstacleStatus, StatusServer, StatusSnapshot

if TYPE_CHECKING:
    from foxglove.messages import LaserScan

# ---------------------------------------------------------------------------------------------
# what the loop consumes


@dataclass(frozen=True)
class ScanSample:
    scan: Scan
    device_stamp_ms: int | None = None
    #: the ranges with REP 117's meanings for invalid readings (+inf, -inf, NaN), for ``/scan``;
    #: None: the scan's NaN stands for every invalid reading
    rep117_ranges_m: np.ndarray | None = None
    #: when the host read the scan's last byte (the driver's clock, the loop's clock); None: unknown
    host_stamp_s: float | None = None


@dataclass(frozen=True)
class OdomSample:
    odometry: Odometry
    battery_v: float = 0.0
    stalled: bool = False
    motors_enabled: bool = True


@dataclass(frozen=True)
class FrameSample:
    frame: Frame
    jpeg: bytes
    zoom_pos: int = 0


class ScannerPort(Protocol):
    def state(self) -> str: ...
    def poll(self) -> list[ScanSample]: ...
    def wait_scan(self, timeout_s: float) -> bool: ...
    def counters(self) -> dict[str, int]: ...
    def close(self) -> None: ...


class BasePort(Protocol):
    def state(self) -> str: ...
    def poll(self) -> list[OdomSample]: ...
    def command(self, v_mps: float, w_radps: float) -> None: ...
    def stop(self) -> None: ...
    def counters(self) -> dict[str, int]: ...
    def close(self) -> None: ...


class CameraPort(Protocol):
    def state(self) -> str: ...
    def latest(self) -> FrameSample | None: ...
    def counters(self) -> dict[str, int]: ...
    def close(self) -> None: ...


TruthFn = Callable[[float], dict[str, Any] | None]


# ---------------------------------------------------------------------------------------------
# log payloads (built on the writer thread)


def scan_message(sample: ScanSample, wall_s: float) -> LaserScan:
    scan = sample.scan
    ranges = scan.ranges_m if sample.rep117_ranges_m is None else sample.rep117_ranges_m
    b = scan.bearings_rad
    intensities = None if scan.intensities is None else scan.intensities.tolist()
    return lm.laser_scan(ranges.tolist(), float(b[0]) if len(b) else 0.0, float(b[-1]) if len(b) else 0.0,
                         intensities, wall_s)


def estimate_to_dict(est: Estimate) -> dict[str, Any]:
    return {
        "stamp_s": est.stamp_s,
        "pose": [est.pose.x_m, est.pose.y_m, est.pose.theta_rad],
        "covariance": np.asarray(est.covariance, float).ravel().tolist(),
        "flags": int(est.flags.value),
        "quality": {
            "beams_used": est.quality.beams_used,
            "iterations": est.quality.iterations,
            "residual_m": est.quality.residual_m,
            "converged": est.quality.converged,
        },
        "obstacles": [
            {
                "track_id": o.track_id,
                "x_m": o.x_m,
                "y_m": o.y_m,
                "vx_mps": o.vx_mps,
                "vy_mps": o.vy_mps,
                "radius_m": o.radius_m,
                "bearing_min_rad": o.bearing_min_rad,
                "bearing_max_rad": o.bearing_max_rad,
                "scan_index_start": o.scan_index_start,
                "scan_index_stop": o.scan_index_stop,
            }
            for o in est.obstacles
        ],
        "restored": [list(p) for p in est.restored_indices],
    }


def cycle_message(
    cycle: int, scan: Scan, odom: Odometry, frame: Frame | None, image_wall_s: float | None, est: Estimate
) -> dict[str, Any]:
    """Everything the estimator took and gave in one cycle: ``replay`` runs from this alone
    (plus the JPEG on ``/camera/image`` logged at ``image_log_time_ns``)."""
    b = scan.bearings_rad
    return {
        "cycle": cycle,
        "scan": {
            "seq": scan.seq,
            "stamp_s": scan.stamp_s,
            "beam_dt_s": scan.beam_dt_s,
            "first_bearing_rad": float(b[0]) if len(b) else 0.0,
            "bearing_step_rad": float(b[1] - b[0]) if len(b) > 1 else 0.0,
            "ranges_m": [None if not math.isfinite(v) else v for v in scan.ranges_m.tolist()],
        },
        "odometry": {
            "x_m": odom.x_m,
            "y_m": odom.y_m,
            "theta_rad": odom.theta_rad,
            "v_mps": odom.v_mps,
            "w_radps": odom.w_radps,
            "stamp_s": odom.stamp_s,
        },
        "frame": None
        if frame is None
        else {
            "seq": frame.seq,
            "stamp_s": frame.stamp_s,
            "pan_rad": frame.pan_rad,
            "tilt_rad": frame.tilt_rad,
            "intrinsics": [
                frame.intrinsics.fx_px,
                frame.intrinsics.fy_px,
                frame.intrinsics.cx_px,
                frame.intrinsics.cy_px,
                frame.intrinsics.width_px,
                frame.intrinsics.height_px,
            ],
            "distortion": list(frame.intrinsics.distortion),
            "image_log_time_ns": lm.stamp_ns(image_wall_s) if image_wall_s is not None else -1,
        },
        "estimate": estimate_to_dict(est),
    }


def normalised_bearings(first_rad: float, step_rad: float, n: int) -> np.ndarray:
    """The one formula for bearings used live and in replay, so both feed the estimator identical arrays."""
    return first_rad + step_rad * np.arange(n, dtype=float)


def scan_age_limit_s(loop: Any, scan: Scan) -> float:
    """How old the newest scan may be before the scanner counts as stalled: ``loop.max_scan_age_s`` if
    set, else ``loop.max_scan_age_periods`` of the scanner's own period (from the scan's beam timing;
    unknown: the loop's period) plus one loop period (the loop samples the newest scan up to a period
    late). 0.25 s at 40 Hz with the 0.1 s loop, 0.9 s at 7.5 Hz."""
    from vipsm.sensor import scan_geometry

    if loop.max_scan_age_s > 0.0:
        return float(loop.max_scan_age_s)
    period = scan_geometry(scan).period_s or loop.period_s
    return float(loop.max_scan_age_periods * period + loop.period_s)


def freeze_startup_objects() -> None:
    """Collect once, then move every object alive now (modules, numba's and LLVM's compiled state,
    the estimator: about 136 k tracked objects) out of the garbage collector's reach. A full
    collection over them took 50-58 ms on the development machine, two deadline misses at 40 Hz
    whenever Python's oldest generation came due in the loop; afterwards it takes about 0.01 ms.
    Objects made later are collected as usual."""
    gc.collect()
    gc.freeze()


# ---------------------------------------------------------------------------------------------
# the loop


@dataclass
class RunStats:
    scans_in: int = 0
    odometry_in: int = 0
    frames_in: int = 0
    frames_used: int = 0
    estimates: int = 0
    plain_psm_cycles: int = 0
    fallback_cycles: int = 0
    device_stop_cycles: int = 0
    safety_stop_cycles: int = 0
    #: the most recent state changes (bounded: a flapping device must not grow memory)
    state_changes: deque[str] = field(default_factory=lambda: deque(maxlen=200))


class ControlLoop:
    def __init__(
        self,
        config: Config,
        *,
        scanner: ScannerPort | None,
        base: BasePort | None,
        camera: CameraPort | None,
        estimator: Estimator,
        field_log: FieldLog | None = None,
        status: StatusServer | None = None,
        notifier: SystemdNotifier | None = None,
        truth: TruthFn | None = None,
        live_view: Any = None,
        clock: Callable[[], float] = time.monotonic,
        wall_clock: Callable[[], float] = time.time,
    ) -> None:
        self.config = config
        self.scanner = scanner
        self.base = base
        self.camera = camera
        self.estimator = estimator
        self.log = field_log
        self.status = status
        self.notifier = notifier or SystemdNotifier({})
        self.truth = truth
        #: the live view serving the log's channels (``app.liveview.LiveView``), stopped at shutdown
        self.live_view = live_view
        self.clock = clock
        self._wall_offset = wall_clock() - clock()
        self.health = LoopHealth(config.loop.period_s)
        m = config.mission
        self.safety = SafetyMonitor(m.safety_radius_m, m.safety_horizon_s, m.resume_after_clear_s)
        self.odom = OdometryHistory()
        self.stats = RunStats()
        self.last_scan: ScanSample | None = None
        self.last_frame: FrameSample | None = None
        self.last_estimate: Estimate | None = None
        self.last_odom_sample: OdomSample | None = None
        self.mission_state = "hold"
        self._last_scan_seq_used: int | None = None
        self._states: dict[str, str] = {}
        self._ready_sent = False
        self._last_watchdog_s = -1e9
        self.cycle = 0
        e = config.estimator
        self._mounts = lm.Mounts(e.laser_x_m, e.laser_y_m, e.laser_theta_rad, e.camera_x_m, e.camera_y_m, e.camera_z_m)
        self._last_pan_tilt = (0.0, 0.0)
        if field_log is not None:
            field_log.on_event = lambda level, message: self.say(level, message, self.clock())
            field_log.log("/vipsm/config", wall_clock(), {"log_version": lm.LOG_VERSION, **dataclasses.asdict(config)})
        if status is not None:
            status.on_event = lambda level, message: self.say(level, message, self.clock())
        #: device counters taken at shutdown (the clients are closed afterwards)
        self.final_counters: dict[str, dict[str, int]] = {}
        #: per-cycle records for the run summary: (stamp_s, estimate, truth)
        self.on_estimate: Callable[[Estimate, float], None] | None = None

    # -- helpers --------------------------------------------------------------------------------

    def wall(self, t_mono_s: float) -> float:
        return t_mono_s + self._wall_offset

    def say(self, level: str, message: str, now_s: float) -> None:
        """A state change: one line on stderr (the journal under systemd), on ``/log`` and in the summary."""
        self.stats.state_changes.append(message)
        print(f"vipsm-robot: {level}: {message}", file=sys.stderr, flush=True)
        if self.log is not None:
            self.log.log("/log", self.wall(now_s), lm.log_line(level, message, self.wall(now_s)))

    def _track_state(self, device: str, state: str, now_s: float) -> None:
        old = self._states.get(device)
        if old != state:
            self._states[device] = state
            dev = getattr(self, device, None)
            detail = dev.detail() if dev is not None and hasattr(dev, "detail") else ""
            level = "info" if state in ("ok", "absent") else "warning"
            change = state if old is None else f"{old} -> {state}"
            self.say(level, f"{device}: {change}" + (f" ({detail})" if detail else ""), now_s)

    # -- one cycle ------------------------------------------------------------------------------

    def step(self, now_s: float) -> None:
        """One loop cycle: drain the devices, judge their health, estimate on a new scan, command the
        base, publish, and tell the service manager."""
        self.cycle += 1
        wall = self.wall(now_s)
        self._drain()
        scanner_state, base_state, camera_state, frame = self._device_states(now_s)
        est = self._estimate(now_s, frame, wall)
        healthy = scanner_state == "ok" and base_state == "ok" and est is not None
        coil = self.status is not None and self.status.stop_requested
        safety_stop = self._command(now_s, scanner_state == "ok" and base_state == "ok", coil)
        self._publish(now_s, scanner_state, base_state, camera_state, healthy, est, coil, safety_stop)
        if est is not None and self.last_scan is not None:  # obstacles are out (status registers, log queue)
            sc = self.last_scan.scan
            now = self.clock()
            received = self.last_scan.host_stamp_s
            self.health.record_latency(now - (sc.stamp_s + max(len(sc.ranges_m) - 1, 0) * sc.beam_dt_s),
                                       None if received is None else now - received)
        if healthy:
            self._notify(now_s)

    def _drain(self) -> None:
        """Every sample the devices delivered since the last cycle: logged, the newest kept."""
        if self.scanner is not None:
            for s in self.scanner.poll():
                self.stats.scans_in += 1
                self.last_scan = s
                if self.log is not None:
                    w = self.wall(s.scan.stamp_s)
                    self.log.log("/scan", w, lambda s=s, w=w: scan_message(s, w))
        if self.base is not None:
            for o in self.base.poll():
                self.stats.odometry_in += 1
                self.odom.add(o.odometry)
                self.last_odom_sample = o
                if self.log is not None:
                    od, w = o.odometry, self.wall(o.odometry.stamp_s)
                    self.log.log("/odom", w, lm.pose_in_frame(od.x_m, od.y_m, od.theta_rad, w))
        frame_sample = self.camera.latest() if self.camera is not None else None
        if frame_sample is not None:
            self.stats.frames_in += 1
            self.last_frame = frame_sample
            if self.log is not None and self.config.log.frames:
                fs, fw = frame_sample, self.wall(frame_sample.frame.stamp_s)
                self.log.log("/camera/image", fw, lambda fs=fs, fw=fw: lm.compressed_image(fs.jpeg, fw))

    def _device_states(self, now_s: float) -> tuple[str, str, str, Frame | None]:
        """Each device's state ("ok" turns "stalled" when its newest sample is too old) and the frame
        fresh enough to use."""
        cfg = self.config.loop
        scanner_state = self.scanner.state() if self.scanner is not None else "absent"
        base_state = self.base.state() if self.base is not None else "absent"
        camera_state = self.camera.state() if self.camera is not None else "absent"
        newest_odom = self.odom.newest
        odom_fresh = newest_odom is not None and now_s - newest_odom.stamp_s <= cfg.max_odometry_age_s
        if scanner_state == "ok" and not self._scan_fresh(now_s):
            scanner_state = "stalled"
        if base_state == "ok" and not odom_fresh:
            base_state = "stalled"
        frame = None
        if self.last_frame is not None and now_s - self.last_frame.frame.stamp_s <= cfg.max_frame_age_s:
            frame = self.last_frame.frame
        elif camera_state == "ok":
            camera_state = "stalled"
        for dev, st in (("scanner", scanner_state), ("base", base_state), ("camera", camera_state)):
            self._track_state(dev, st, now_s)
        return scanner_state, base_state, camera_state, frame

    def _scan_fresh(self, now_s: float) -> bool:
        last = self.last_scan
        return last is not None and now_s - last.scan.stamp_s <= scan_age_limit_s(self.config.loop, last.scan)

    def _estimate(self, now_s: float, frame: Frame | None, wall: float) -> Estimate | None:
        """The estimator run on the newest scan, once per scan (None: no new fresh scan, or no
        odometry at its stamp)."""
        scan_sample = self.last_scan
        if not self._scan_fresh(now_s) or scan_sample is None or scan_sample.scan.seq == self._last_scan_seq_used:
            return None
        odom_at_scan = self.odom.at(scan_sample.scan.stamp_s)
        if odom_at_scan is None:
            return None
        self._last_scan_seq_used = scan_sample.scan.seq
        est = self.estimator.step(scan_sample.scan, odom_at_scan, frame)
        self.last_estimate = est
        self.stats.estimates += 1
        if frame is not None:
            self.stats.frames_used += 1
        if est.flags & (EstimateFlag.NO_FRAME | EstimateFlag.PLAIN_PSM):
            self.stats.plain_psm_cycles += 1
        if est.flags & EstimateFlag.ODOMETRY_FALLBACK:
            self.stats.fallback_cycles += 1
        if self.on_estimate is not None:
            self.on_estimate(est, scan_sample.scan.stamp_s)
        if self.log is not None:
            self._log_estimate(est, scan_sample.scan, odom_at_scan, frame, wall)
        return est

    def _command(self, now_s: float, device_ok: bool, coil: bool) -> bool:
        """The mission state (device stop, stop coil, safety stop on the newest estimate's confirmed
        obstacles, cruise or hold) and the base's command; returns whether the safety stop holds."""
        cfg = self.config
        obstacles = self.last_estimate.obstacles if self.last_estimate is not None else ()
        pose = self.last_estimate.pose if self.last_estimate is not None else None
        newest_odom = self.odom.newest
        v_now = newest_odom.v_mps if newest_odom is not None else 0.0
        safety_stop = pose is not None and self.safety.update(
            now_s, pose.x_m, pose.y_m, pose.theta_rad, max(v_now, 0.0), obstacles
        )
        if not device_ok:
            state = "device_stop"
        elif coil:
            state = "coil_stop"
        elif safety_stop:
            state = "safety_stop"
        elif cfg.mission.mode == "cruise":
            state = "moving"
        else:
            state = "hold"
        if state != self.mission_state:
            self.say(
                "warning" if state.endswith("stop") else "info", f"mission: {self.mission_state} -> {state}", now_s
            )
            self.mission_state = state
        if state == "device_stop":
            self.stats.device_stop_cycles += 1
        if state == "safety_stop":
            self.stats.safety_stop_cycles += 1
        if self.base is not None:
            if state == "moving":
                self.base.command(cfg.mission.cruise_speed_mps, 0.0)
            else:
                self.base.command(0.0, 0.0)
        return safety_stop

    def _notify(self, now_s: float) -> None:
        """READY once the loop is first healthy, then the watchdog at its interval."""
        if not self._ready_sent:
            self.notifier.ready()
            self._ready_sent = True
        interval = self.notifier.watchdog_interval_s
        if interval is not None and now_s - self._last_watchdog_s >= interval:
            self.notifier.watchdog()
            self._last_watchdog_s = now_s

    def _log_estimate(self, est: Estimate, scan: Scan, odom: Odometry, frame: Frame | None, wall: float) -> None:
        assert self.log is not None
        p = est.pose
        self.log.log("/pose", wall, lm.pose_in_frame(p.x_m, p.y_m, p.theta_rad, wall))
        life_s = max(3 * self.config.loop.period_s, 0.3)
        self.log.log("/obstacles", wall, lambda: lm.scene_update(est.obstacles, wall, life_s))
        self.log.log("/people", wall, lambda: lm.people_scene_update(est.people, wall, life_s))
        cycle = self.cycle
        image_wall = self.wall(frame.stamp_s) if frame is not None else None
        self.log.log("/vipsm/cycle", wall, lambda: cycle_message(cycle, scan, odom, frame, image_wall, est))
        truth = self.truth(scan.stamp_s) if self.truth is not None else None
        if truth is not None:
            self.log.log("/truth", wall, {"stamp_s": scan.stamp_s, **truth})
        pan_tilt = (frame.pan_rad, frame.tilt_rad) if frame is not None else self._last_pan_tilt
        self._last_pan_tilt = pan_tilt
        pose = (p.x_m, p.y_m, p.theta_rad)
        self.log.log("/tf", wall, lambda: lm.robot_transforms(pose, self._mounts, pan_tilt, wall, truth))

    def _publish(
        self,
        now_s: float,
        scanner_state: str,
        base_state: str,
        camera_state: str,
        healthy: bool,
        est: Estimate | None,
        coil: bool,
        safety_stop: bool,
    ) -> None:
        flags = set()
        if scanner_state == "ok":
            flags.add("scanner_ok")
        if base_state == "ok":
            flags.add("base_ok")
        if camera_state == "ok":
            flags.add("camera_ok")
        if est is not None and est.flags & (EstimateFlag.NO_FRAME | EstimateFlag.PLAIN_PSM):
            flags.add("plain_psm")
        if est is not None and est.flags & EstimateFlag.ODOMETRY_FALLBACK:
            flags.add("odometry_fallback")
        if safety_stop:
            flags.add("safety_stop")
        if coil:
            flags.add("coil_stop")
        log_failed = self.log is not None and (self.log.stats.state == "disk_error" or self.log.stats.error is not None)
        if log_failed:
            flags.add("log_error")
        if healthy and not log_failed:
            flags.add("loop_healthy")
        if self.truth is not None:
            flags.add("simulated")
        last = self.last_estimate
        diag = {
            "cycle": self.cycle,
            "stamp_s": now_s,
            "compute_ms": self.health.last_compute_s * 1e3,
            "deadline_misses": self.health.deadline_misses,
            "scanner": scanner_state,
            "base": base_state,
            "camera": camera_state,
            "mission": self.mission_state,
            "log_dropped": self.log.stats.dropped if self.log is not None else 0,
            "log_state": self.log.stats.state if self.log is not None else "off",
            "flags": sorted(flags),
        }
        if self.log is not None:
            self.log.log("/diagnostics", self.wall(now_s), diag)
        if self.status is not None:
            sigma = 0.0
            if last is not None:
                cov = np.asarray(last.covariance, float)[:2, :2]
                sigma = float(math.sqrt(max(np.linalg.eigvalsh(cov).max(), 0.0))) if np.all(np.isfinite(cov)) else 0.0
            battery = self.last_odom_sample.battery_v if self.last_odom_sample is not None else 0.0
            self.status.publish(
                StatusSnapshot(
                    cycle=self.cycle,
                    flags=frozenset(flags),
                    mission_state=self.mission_state,
                    x_m=last.pose.x_m if last else 0.0,
                    y_m=last.pose.y_m if last else 0.0,
                    theta_rad=last.pose.theta_rad if last else 0.0,
                    sigma_m=sigma,
                    obstacles=tuple(
                        ObstacleStatus(o.track_id, o.x_m, o.y_m, o.vx_mps, o.vy_mps, o.radius_m)
                        for o in (last.obstacles if last else ())
                    ),
                    compute_s=self.health.last_compute_s,
                    jitter_p99_s=self.health.jitter_p99_s() if self.cycle % 10 == 0 else 0.0,
                    deadline_misses=self.health.deadline_misses,
                    log_dropped=self.log.stats.dropped if self.log is not None else 0,
                    scanner_state=scanner_state,
                    base_state=base_state,
                    camera_state=camera_state,
                    battery_v=battery,
                )
            )

    # -- the run --------------------------------------------------------------------------------

    def run(
        self,
        stop: threading.Event,
        duration_s: float | None = None,
        progress: Callable[[ControlLoop, float], None] | None = None,
    ) -> None:
        """Cycles on monotonic deadlines until ``stop`` is set or ``duration_s`` has passed.

        A cycle that overruns counts as a deadline miss; periods that passed entirely are skipped
        (counted), never run back to back to catch up. With ``loop.trigger = "scan"`` a cycle runs as
        each scan arrives instead (:meth:`run_on_scans`).
        """
        freeze_startup_objects()
        if self.config.loop.trigger == "scan" and self.scanner is not None:
            self.run_on_scans(stop, duration_s, progress)
            return
        period = self.config.loop.period_s
        t0 = self.clock()
        k = 0
        while not stop.is_set():
            k += 1
            deadline = t0 + k * period
            delay = deadline - self.clock()
            if delay > 0 and stop.wait(delay):
                break
            wake = self.clock()
            skipped = 0
            if wake - deadline >= period:
                skipped = int((wake - deadline) // period)
                k += skipped
                deadline = t0 + k * period
            self.step(wake)
            done = self.clock()
            compute = done - wake
            self.health.record(wake - deadline, compute, missed=done > deadline + period, skipped=skipped)
            if progress is not None:
                progress(self, wake - t0)
            if duration_s is not None and wake - t0 >= duration_s:
                break

    def run_on_scans(
        self,
        stop: threading.Event,
        duration_s: float | None = None,
        progress: Callable[[ControlLoop, float], None] | None = None,
    ) -> None:
        """A cycle as soon as a scan is ready (or after ``loop.period_s`` without one, so a silent
        scanner is still noticed and the base still commanded). A cycle longer than the period is a
        deadline miss; the jitter recorded is the wait beyond the period when no scan came."""
        assert self.scanner is not None
        period = self.config.loop.period_s
        t0 = self.clock()
        last = t0
        while not stop.is_set():
            self.scanner.wait_scan(period)
            wake = self.clock()
            late = max(0.0, wake - last - period)
            self.step(wake)
            done = self.clock()
            self.health.record(late, done - wake, missed=done - wake > period)
            last = wake
            if progress is not None:
                progress(self, wake - t0)
            if duration_s is not None and wake - t0 >= duration_s:
                break

    def shutdown(self) -> None:
        """Stop the base, close devices, close the log (complete and indexed)."""
        self.notifier.stopping()
        self.final_counters = {
            name: dev.counters()
            for name, dev in (("scanner", self.scanner), ("base", self.base), ("camera", self.camera))
            if dev is not None
        }
        if self.base is not None:
            try:
                self.base.stop()
            finally:
                self.base.close()
        for dev in (self.scanner, self.camera):
            if dev is not None:
                dev.close()
        if self.status is not None:
            self.status.stop()
        if self.log is not None:
            self.log.close()
        if self.live_view is not None:
            self.live_view.stop()
        self.notifier.close()
