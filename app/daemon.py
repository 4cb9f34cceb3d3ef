"""The control loop: every 0.1 s on monotonic deadlines, newest scan + odometry + frame -> estimator
-> field log, status, base command.

Devices reach the loop through three small ports (``ScannerPort``, ``BasePort``, ``CameraPort``,
implemented over the driver clients in ``app.devices``), so the loop is the same against real
hardware, the byte-level fakes and tests. Degraded modes, each logged on ``/log`` and visible in the
status registers:

* no camera (absent, failed, no frame taken within ``loop.max_frame_age_s`` of the scan): plain PSM for the
  cycle, flagged ``plain_psm`` (a scan is paired with the frame taken nearest it, not the newest frame:
  ``app.framesync``);
* no scanner, or no scan received for the stall age (:func:`scan_age_limit_s`; on receipt time, less the time the
  loop itself was busy, at most that much again: a late loop is not a stalled scanner): base
  stopped (``device_stop``);
* the estimator slower than the scans (``overloaded``, with hysteresis, one log line per change):
  the newest scan is estimated every n-th scan/period, the scans in between skipped and counted;
  the protective field still judges every scan;
* something in the path in cruise (``protective_stop``, ``app.protective_field``): base stopped
  until the corridor has been clear for ``mission.resume_after_clear_s``;
* no odometry newer than ``loop.max_odometry_age_s``: base stopped;
* the loop itself stalled: the base driver's own command timeout zeroes the velocity, and the
  base firmware's watchdog stops it after that;
* a device that comes back is used again at once (the clients reconnect on their own).
"""

from __future__ import annotations

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
from .config import Config, redact_text, redacted_config
from .fieldlog import FieldLog
from .framesync import FrameSample, RecentFrames
from .health import LoopHealth, OdometryHistory, OverloadMonitor, SafetyMonitor
from .protective_field import FieldParams, ProtectiveField
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
    #: the sensor's (min, max) valid range (the UTM-30LX's DMIN/DMAX), for ``/scan`` on ROS 2; None: unknown
    range_limits_m: tuple[float, float] | None = None


#: an estimate made without the camera: none configured or fresh, the baseline asked for, or a frame
#: the estimator could not use (too far from the scan, undecodable, or with no earlier frame to take the
#: optical flow against)
WITHOUT_CAMERA = (EstimateFlag.NO_FRAME | EstimateFlag.PLAIN_PSM | EstimateFlag.STALE_FRAME | EstimateFlag.FRAME_ERROR
                  | EstimateFlag.NO_FLOW)


@dataclass(frozen=True)
class OdomSample:
    odometry: Odometry
    battery_v: float = 0.0
    stalled: bool = False
    motors_enabled: bool = True


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


def scan_age_limit_s(loop: Any, scan: Scan, stamp_period_s: float | None = None) -> float:
    """How old the newest scan may be before the scanner counts as stalled: ``loop.max_scan_age_s`` if
    set, else ``loop.max_scan_age_periods`` of the scanner's own period (the measured spacing of its
    scans' stamps, ``stamp_period_s``, once known; before that the scan's beam timing; unknown: the loop's
    period) plus one loop period (the loop samples the newest scan up to a period late). 0.25 s at 40 Hz
    with the 0.1 s loop, 0.9 s at 7.5 Hz."""
    from vipsm.sensor import scan_geometry

    if loop.max_scan_age_s > 0.0:
        return float(loop.max_scan_age_s)
    period = scan_geometry(scan, stamp_period_s).period_s or loop.period_s
    return float(loop.max_scan_age_periods * period + loop.period_s)


def protective_field(config: Config) -> ProtectiveField | None:
    """The protective field from ``safety.*`` and the laser mount (None when ``safety.field_enabled`` is off)."""
    s, e = config.safety, config.estimator
    if not s.field_enabled:
        return None
    params = FieldParams(s.corridor_width_m, s.front_m, s.deceleration_mps2, s.latency_s, s.margin_m,
                         s.cluster_gap_m, s.min_returns)
    return ProtectiveField(params, (e.laser_x_m, e.laser_y_m, e.laser_theta_rad), config.mission.resume_after_clear_s)


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
    protective_stop_cycles: int = 0
    protective_stops: int = 0
    #: scans received but superseded by a newer one before the estimator took them
    scans_skipped: int = 0
    #: cycles with a fresh unused scan left to a later cycle by the lowered obstacle rate (overload)
    estimates_deferred: int = 0
    overload_cycles: int = 0
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
        ros2: Any = None,
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
        #: the ROS 2 publisher (``app.ros2.publisher.Ros2Publisher``): fed beside the log, closed at shutdown
        self.ros2 = ros2
        self.clock = clock
        self._wall_offset = wall_clock() - clock()
        self.health = LoopHealth(config.loop.period_s)
        m = config.mission
        self.safety = SafetyMonitor(m.safety_radius_m, m.safety_horizon_s, m.resume_after_clear_s)
        self.field = protective_field(config)
        self.overload = OverloadMonitor()
        #: (start, end) of the recent cycles: time the loop held the interpreter, not the scanner's fault
        self._busy: deque[tuple[float, float]] = deque(maxlen=64)
        self._scan_period_s: float | None = None
        self._last_estimate_s = -math.inf
        self.odom = OdometryHistory()
        self.stats = RunStats()
        self.last_scan: ScanSample | None = None
        #: ``/vipsm/scanner`` before the first scan and whenever the scanner's geometry changes
        self._scanner_info = lm.ScannerInfoLog()
        #: the last few frames, so that a scan is paired with the frame taken nearest it
        self._frames = RecentFrames()
        self.last_estimate: Estimate | None = None
        self.last_odom_sample: OdomSample | None = None
        self.mission_state = "hold"
        self._last_scan_seq_used: int | None = None
        self._states: dict[str, str] = {}
        self._opened: set[str] = set()  # devices seen past "connecting"
        self._ready_sent = False
        self._first_cycle_s: float | None = None
        self._last_watchdog_s = -1e9
        self.cycle = 0
        e = config.estimator
        self._mounts = lm.Mounts(e.laser_x_m, e.laser_y_m, e.laser_theta_rad, e.camera_x_m, e.camera_y_m, e.camera_z_m)
        self._last_pan_tilt = (0.0, 0.0)
        if field_log is not None:
            field_log.on_event = lambda level, message: self.say(level, message, self.clock())
            config_msg = {"log_version": lm.LOG_VERSION, **redacted_config(config)}
            field_log.log("/vipsm/config", wall_clock(), config_msg)
            if live_view is not None:  # latched: a viewer that connects later gets it too
                live_view.latch("/vipsm/config", wall_clock(), config_msg)
        if live_view is not None:
            live_view.on_event = lambda level, message: self.say(level, message, self.clock())
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
        """A state change: one line on stderr (the journal under systemd), on ``/log`` and in the summary;
        a password in it (a device URL in an error) is redacted."""
        message = redact_text(message)
        self.stats.state_changes.append(message)
        print(f"vipsm-robot: {level}: {message}", file=sys.stderr, flush=True)
        if self.log is not None:
            self.log.log("/log", self.wall(now_s), lm.log_line(level, message, self.wall(now_s)))

    def devices_never_opened(self) -> dict[str, str]:
        """The configured devices that never opened during the run (never past "connecting": for the
        camera, no frame ever came), each with its detail (URL and last error); for the exit code of a
        bounded run."""
        out = {}
        for name in ("scanner", "base", "camera"):
            dev = getattr(self, name)
            if dev is not None and name not in self._opened:
                out[name] = dev.detail() if hasattr(dev, "detail") else ""
        return out

    def _track_state(self, device: str, state: str, now_s: float) -> None:
        if state != "connecting":
            self._opened.add(device)
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
        scanner_state, base_state, camera_state = self._device_states(now_s)
        est = self._estimate(now_s, wall)
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
        if self.overload.overloaded:
            self.stats.overload_cycles += 1
        self._busy.append((now_s, self.clock()))

    def _log_latched(self, topic: str, wall_s: float, payload: dict[str, Any]) -> bool:
        """A field-log message that a live viewer connecting later gets too (the live view latches it)."""
        assert self.log is not None
        if self.live_view is not None:
            self.live_view.latch(topic, wall_s, payload)
        return self.log.log(topic, wall_s, payload)

    def _drain(self) -> None:
        """Every sample the devices delivered since the last cycle: logged, the newest kept."""
        if self.scanner is not None:
            for s in self.scanner.poll():
                self.stats.scans_in += 1
                self._note_scan(s)
                self.last_scan = s
                if self.log is not None:
                    w = self.wall(s.scan.stamp_s)
                    self._scanner_info.before_scan(self._log_latched, w, lm.scanner_info(s.scan, s.range_limits_m))
                    self.log.log("/scan", w, lambda s=s, w=w: scan_message(s, w))
                if self.ros2 is not None:
                    self.ros2.scan(s, self.wall(s.scan.stamp_s))
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
            self._frames.add(frame_sample)
            if self.log is not None and self.config.log.frames:
                fs, fw = frame_sample, self.wall(frame_sample.frame.stamp_s)
                self.log.log("/camera/image", fw, lambda fs=fs, fw=fw: lm.compressed_image(fs.jpeg, fw))
            if self.ros2 is not None:
                self.ros2.frame(frame_sample, self.wall(frame_sample.frame.stamp_s))

    def _device_states(self, now_s: float) -> tuple[str, str, str]:
        """Each device's state ("ok" turns "stalled" when its newest sample is too old)."""
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
        if self._first_cycle_s is None:
            self._first_cycle_s = now_s
        newest = self._frames.newest
        newest_frame_s = newest.frame.stamp_s if newest is not None else -math.inf
        if camera_state == "ok" and now_s - max(newest_frame_s, self._first_cycle_s) > cfg.max_frame_age_s:
            # stalled: no frame for max_frame_age_s while the loop ran (a frame aged by the start-up
            # itself, before the first cycle, is not used but is no stall of the camera)
            camera_state = "stalled"
        for dev, st in (("scanner", scanner_state), ("base", base_state), ("camera", camera_state)):
            self._track_state(dev, st, now_s)
        return scanner_state, base_state, camera_state

    def _frame_for(self, scan: Scan) -> Frame | None:
        """The frame taken nearest the scan, at most ``loop.max_frame_age_s`` from it (None: plain PSM)."""
        sample = self._frames.nearest(scan.stamp_s, self.config.loop.max_frame_age_s)
        return sample.frame if sample is not None else None

    def _scan_fresh(self, now_s: float) -> bool:
        return self.last_scan is not None and self._scan_quiet_s(now_s) <= self._scan_age_limit_s()

    # -- overload: the newest scan, a lower obstacle rate, stall judged on receipt --------------

    def _note_scan(self, sample: ScanSample) -> None:
        """Count a scan superseded before the estimator took it, and follow the scan period."""
        old = self.last_scan
        if old is None:
            return
        if old.scan.seq != self._last_scan_seq_used:
            self.stats.scans_skipped += 1
        dt = sample.scan.stamp_s - old.scan.stamp_s
        if 0.0 < dt < 1.0:
            p = self._scan_period_s
            self._scan_period_s = dt if p is None else p + 0.1 * (dt - p)

    def _scan_quiet_s(self, now_s: float) -> float:
        """How long the scanner has delivered nothing, on the newest scan's receipt time (its stamp when
        the receipt is unknown), less the time the loop itself was busy since: a late loop (whose
        reader thread may have waited for the interpreter) is not a stalled scanner."""
        assert self.last_scan is not None
        received = self.last_scan.host_stamp_s
        since = self.last_scan.scan.stamp_s if received is None else received
        busy = sum(max(0.0, min(end, now_s) - max(start, since)) for start, end in self._busy)
        # at most max_scan_age_s is excused: the scan the loop acts on is never older than twice that
        return now_s - since - min(busy, self._scan_age_limit_s())

    def _scan_age_limit_s(self) -> float:
        """The stall age for the newest scan's sensor (:func:`scan_age_limit_s`)."""
        assert self.last_scan is not None
        return scan_age_limit_s(self.config.loop, self.last_scan.scan, self._scan_period_s)

    def _obstacle_budget_s(self) -> float | None:
        """The time one estimate may take to keep up: the scan period when every scan triggers a cycle
        (None until two scans showed it), else the loop's period."""
        if self.config.loop.trigger == "scan" and self.scanner is not None:
            return self._scan_period_s
        return self.config.loop.period_s

    def _estimate_due(self, now_s: float) -> bool:
        """Under overload the obstacles come at a lower rate: an estimate every ``overload.every`` budgets."""
        budget = self._obstacle_budget_s()
        if not self.overload.overloaded or budget is None:
            return True
        return now_s - self._last_estimate_s >= (self.overload.every - 0.5) * budget

    def _timed_step(self, scan: Scan, odom: Odometry, frame: Frame | None, now_s: float) -> Estimate:
        """The estimator, timed against the budget; an overload change is logged once."""
        t0 = self.clock()
        est = self.estimator.step(scan, odom, frame)
        took, budget = self.clock() - t0, self._obstacle_budget_s()
        self._last_estimate_s = now_s
        if budget is not None and self.overload.record(took, budget):
            o = self.overload
            assert o.compute_s is not None
            if o.overloaded:
                self.say("warning", f"loop: overloaded: the estimator takes {o.compute_s * 1e3:.1f} ms per scan, "
                         f"budget {budget * 1e3:.1f} ms; obstacles from 1 scan in {o.every}", now_s)
            else:
                self.say("info", f"loop: overload over: the estimator takes {o.compute_s * 1e3:.1f} ms per scan; "
                         "obstacles from every scan again", now_s)
        return est

    def _estimate(self, now_s: float, wall: float) -> Estimate | None:
        """The estimator run on the newest scan, once per scan (None: no new fresh scan, or no
        odometry at its stamp)."""
        scan_sample = self.last_scan
        if not self._scan_fresh(now_s) or scan_sample is None or scan_sample.scan.seq == self._last_scan_seq_used:
            return None
        odom_at_scan = self.odom.at(scan_sample.scan.stamp_s)
        if odom_at_scan is None:
            return None
        if not self._estimate_due(now_s):
            self.stats.estimates_deferred += 1
            return None
        self._last_scan_seq_used = scan_sample.scan.seq
        frame = self._frame_for(scan_sample.scan)
        est = self._timed_step(scan_sample.scan, odom_at_scan, frame, now_s)
        self.last_estimate = est
        self.stats.estimates += 1
        if est.flags & WITHOUT_CAMERA:
            self.stats.plain_psm_cycles += 1
        elif frame is not None:
            self.stats.frames_used += 1
        if est.flags & EstimateFlag.ODOMETRY_FALLBACK:
            self.stats.fallback_cycles += 1
        if self.on_estimate is not None:
            self.on_estimate(est, scan_sample.scan.stamp_s)
        if self.log is not None:
            self._log_estimate(est, scan_sample.scan, odom_at_scan, frame, wall)
        if self.ros2 is not None:
            truth = self.truth(scan_sample.scan.stamp_s) if self.truth is not None else None
            pan_tilt = (frame.pan_rad, frame.tilt_rad) if frame is not None else None
            self.ros2.estimate(est, odom_at_scan, self.wall(est.stamp_s), pan_tilt, truth)
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
        protective_stop = self._protective(now_s, max(v_now, 0.0))
        if not device_ok:
            state = "device_stop"
        elif coil:
            state = "coil_stop"
        elif protective_stop:
            state = "protective_stop"
        elif safety_stop:
            state = "safety_stop"
        elif cfg.mission.mode == "cruise":
            state = "moving"
        else:
            state = "hold"
        if state != self.mission_state:
            # a device stop is a fault; a safety, protective or coil stop is the mission doing its job
            level = "warning" if state == "device_stop" else "info"
            self.say(level, f"mission: {self.mission_state} -> {state}", now_s)
            self.mission_state = state
        if state == "device_stop":
            self.stats.device_stop_cycles += 1
        if state == "safety_stop":
            self.stats.safety_stop_cycles += 1
        if state == "protective_stop":
            self.stats.protective_stop_cycles += 1
        if self.base is not None:
            if state == "moving":
                self.base.command(cfg.mission.cruise_speed_mps, 0.0)
            else:
                self.base.command(0.0, 0.0)
        return safety_stop

    def _protective(self, now_s: float, v_mps: float) -> bool:
        """The protective field on the newest fresh scan (cruise only; hold never moves): whether it
        holds the robot. Its changes are logged with what it saw."""
        sample = self.last_scan
        if self.field is None or self.config.mission.mode != "cruise" or sample is None or not self._scan_fresh(now_s):
            return self.field is not None and self.field.stopped
        was = self.field.stopped
        v = max(v_mps, self.config.mission.cruise_speed_mps)  # the field the robot needs once it moves
        stopped = self.field.update(now_s, sample.scan.ranges_m, sample.scan.bearings_rad, v, sample.scan.seq)
        res = self.field.last
        assert res is not None
        if stopped and not was:
            self.stats.protective_stops += 1
            self.say("info", f"protective field: object {res.nearest_m:.2f} m ahead of the robot's origin "
                     f"(field {res.length_m:.2f} m at {v:.2f} m/s)", now_s)
        elif was and not stopped:
            self.say("info", f"protective field: clear for {self.field.resume_after_clear_s:g} s", now_s)
        return stopped

    def safety_summary(self) -> dict[str, Any]:
        """The protective field's part of the run summary."""
        f = self.field
        return {
            "protective_stop_cycles": self.stats.protective_stop_cycles,
            "protective_stops": self.stats.protective_stops,
            "protective_intrusion_scans": f.intrusion_scans if f is not None else 0,
            "protective_unconfirmed_returns": f.unconfirmed_returns if f is not None else 0,
            "scans_skipped": self.stats.scans_skipped,
            "estimates_deferred": self.stats.estimates_deferred,
            "overload_cycles": self.stats.overload_cycles,
            "overload_episodes": self.overload.transitions,
        }

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
        if est is not None and est.flags & WITHOUT_CAMERA:
            flags.add("plain_psm")
        if est is not None and est.flags & EstimateFlag.ODOMETRY_FALLBACK:
            flags.add("odometry_fallback")
        if safety_stop:
            flags.add("safety_stop")
        if self.field is not None and self.field.stopped:
            flags.add("protective_stop")
        if self.overload.overloaded:
            flags.add("overloaded")
        if coil:
            flags.add("coil_stop")
        log_failed = self.log is not None and (self.log.stats.state == "disk_error" or self.log.stats.error is not None)
        if log_failed:
            flags.add("log_error")
        if healthy and not log_failed:
            flags.add("loop_healthy")
        if self.ros2 is not None:
            for level, message in self.ros2.take_events():
                self.say(level, message, now_s)
            if self.ros2.state == "failed" or self.ros2.errors:
                flags.add("ros2_error")
        if self.live_view is not None and self.live_view.state in ("degraded", "failed"):
            flags.add("live_view_error")
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
        if self.ros2 is not None:
            self.ros2.diagnostics(diag, self._device_counters, self.wall(now_s))
            self.ros2.flush()  # the cycle's work is done: the publisher may build and send now
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
                    **self._field_status(),
                )
            )

    def _field_status(self) -> dict[str, float]:
        out: dict[str, float] = {"estimate_every": float(self.overload.every)}
        res = self.field.last if self.field is not None else None
        if res is not None:
            out.update(field_length_m=res.length_m, field_nearest_m=0.0 if math.isnan(res.nearest_m) else res.nearest_m)
        return out

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
        if self.ros2 is not None:
            self.ros2.close()
        self.notifier.close()

    def _device_counters(self) -> dict[str, dict[str, int]]:
        return {name: dev.counters() for name in ("scanner", "base", "camera")
                if (dev := getattr(self, name)) is not None}
