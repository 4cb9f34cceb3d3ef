"""Run VIPSM and plain PSM side by side on identical simulated inputs (what ``eval`` measures)."""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from hil_fakes.world import (
    RobotMount,
    Scenario,
    Truth,
    World,
    intrinsics,
)
from vipsm.types import Frame, Intrinsics, Odometry, Scan

from ..errors import AppError
from .metrics import (
    CYCLE_S,
    LOCATED_GATE_M,
    MIN_BEAMS_IN_VIEW,
    MIN_TRACK_AGE,
    FalseStopJudge,
    MethodLog,
    RunLog,
    _assign,
    count_reports,
    obstacle_in_camera,
    target_misses,
    targets_for,
)
from .person_metrics import PeopleScore
from .traces import track_point


# ---------------------------------------------------------------------------------------- estimator glue
def _replace_fields(obj: Any, values: dict[str, float]) -> Any:
    """Copy of a frozen dataclass tree with every field named in ``values`` replaced, at any depth."""
    if not dataclasses.is_dataclass(obj) or isinstance(obj, type):
        return obj
    changes: dict[str, Any] = {}
    for f in dataclasses.fields(obj):
        if not f.init:
            continue
        cur = getattr(obj, f.name)
        if f.name in values:
            changes[f.name] = values[f.name]
        elif dataclasses.is_dataclass(cur) and not isinstance(cur, type):
            new = _replace_fields(cur, values)
            if new is not cur:
                changes[f.name] = new
    return dataclasses.replace(obj, **changes) if changes else obj


def mount_values(mount: RobotMount) -> dict[str, float]:
    return {
        "laser_x_m": mount.laser_x_m,
        "laser_y_m": mount.laser_y_m,
        "laser_theta_rad": mount.laser_theta_rad,
        "camera_x_m": mount.camera_x_m,
        "camera_y_m": mount.camera_y_m,
        "camera_z_m": mount.camera_z_m,
    }


def make_estimators(mount: RobotMount) -> tuple[Any, Any]:
    """(VIPSM, plain PSM) estimators configured with the world's sensor mount."""
    try:
        from vipsm.estimator import Estimator, EstimatorConfig

        from ..legmodel import default_leg_model
    except ModuleNotFoundError as exc:  # the estimator is another area's work
        raise AppError(f"the estimator is not available: {exc}") from exc
    config = _replace_fields(EstimatorConfig(), mount_values(mount))
    model = default_leg_model()
    return (Estimator(config, plain_psm=False, leg_model=model),
            Estimator(config, plain_psm=True, leg_model=model))


def _score_reports(
    mlog: MethodLog, judge: FalseStopJudge, e: Any, t: float, scenario: Scenario, t_est: Any, truth: Any, v_mps: float
) -> None:
    """False moving obstacles, false safety stops and the delay to the first report of each body."""
    count_reports(mlog, t_est, e.obstacles)
    stopped, false_stop = judge.update(t, (e.pose.x_m, e.pose.y_m, e.pose.theta_rad), v_mps, e.obstacles, truth)
    mlog.stop_cycles += int(stopped)
    mlog.false_stop_cycles += int(false_stop)
    for i, delay in mlog.report_delays_s.items():
        start_s = scenario.obstacles[i].start_s
        if delay is not None or t < start_s:
            continue
        o = t_est.obstacles[i]
        if any(math.hypot(eo.x_m - o.x_m, eo.y_m - o.y_m) <= LOCATED_GATE_M for eo in e.obstacles):
            mlog.report_delays_s[i] = round(t - start_s, 3)


@dataclass(frozen=True)
class _CameraTiming:
    """Which frame the estimator gets in a cycle, and when it was exposed.

    Realistic world: the camera's own free-running clock (:class:`hil_fakes.world.camera_effects.CameraClock`);
    the frame is the newest *delivered* one (exposed 40-100 ms earlier), stamped with its delivery time
    as the daemon stamps frames (host receipt), JPEG at the camera's quality. Ideal world: the first
    build's timing (``frame_lag_s``, ``camera_fps``, ``jpeg_quality``), exposure time = stamp."""

    frame_lag_s: float
    camera_fps: float
    jpeg_quality: int

    def frame(
        self, world: World, scenario: Scenario, t: float, k: int, last: Frame | None, intr: Intrinsics, hfov: float
    ) -> tuple[Frame | None, float]:
        fx = scenario.camera_effects
        if fx.enabled:
            timing = world.camera_clock.newest(t)
            if timing is None:
                return None, t
            n_frame, t_capture, stamp, quality = timing.seq, timing.capture_s, timing.delivery_s, fx.jpeg_quality
        else:
            if self.camera_fps > 0:  # free-running camera: the newest frame captured frame_lag_s before the scan
                n_frame = math.floor((t - self.frame_lag_s) * self.camera_fps + 1e-9)
                t_capture = n_frame / self.camera_fps
            else:  # one frame per cycle
                n_frame, t_capture = k, t - self.frame_lag_s
            stamp, quality = t_capture, self.jpeg_quality
            if t_capture < 0:
                return None, t_capture
        if last is not None and last.seq == n_frame:
            return last, t_capture  # the camera is slower than the cycle: the same frame again
        img = world.render(t_capture, 0.0, 0.0, hfov)
        if quality > 0:
            ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
            if not ok:
                raise AppError("OpenCV could not encode a JPEG frame")
            img = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        return Frame(img, stamp, intr, pan_rad=0.0, tilt_rad=0.0, seq=n_frame), t_capture


def run_scenario(
    scenario: Scenario,
    *,
    frame_lag_s: float = 0.04,
    camera_fps: float = 0.0,
    jpeg_quality: int = 80,
    hfov_deg: float = 54.0,
    keep_scans: bool = False,
    mount: RobotMount | None = None,
) -> RunLog:
    """Run VIPSM and plain PSM side by side over the scenario and collect what the metrics need."""
    if not (math.isfinite(frame_lag_s) and frame_lag_s >= 0):
        raise AppError(f"--frame-lag-s must be >= 0, got {frame_lag_s}")
    if not (math.isfinite(camera_fps) and camera_fps >= 0):
        raise AppError(f"--camera-fps must be >= 0, got {camera_fps}")
    if not 0 <= jpeg_quality <= 100:
        raise AppError(f"--jpeg-quality must be 0..100, got {jpeg_quality}")
    mount = mount or RobotMount()
    world = World(scenario, mount=mount)
    vipsm_est, plain_est = make_estimators(mount)
    methods = {"vipsm": (vipsm_est, MethodLog("vipsm")), "plain_psm": (plain_est, MethodLog("plain_psm"))}
    log = RunLog(scenario, methods={k: v[1] for k, v in methods.items()}, mount=mount)
    hfov = math.radians(hfov_deg)
    w_px, h_px = world.camera.width_px, world.camera.height_px
    fx, fy, cx, cy = intrinsics(w_px, h_px, hfov)
    intr = Intrinsics(fx, fy, cx, cy, w_px, h_px)
    bearings = world.laser.angles_rad()
    log.bearings_rad = bearings
    command = scenario.command_at(0.0)
    world.command(*command, 0.0)
    n_cycles = int(math.floor(scenario.duration_s / CYCLE_S + 1e-9)) + 1
    t_world = 0.0
    last_frame: Frame | None = None
    judges = {name: FalseStopJudge() for name in methods}
    people = {name: PeopleScore(scenario) for name in methods}
    for _est, mlog in methods.values():
        mlog.report_delays_s = {i: None for i, o in enumerate(scenario.obstacles) if o.start_s < scenario.duration_s}
        mlog.people_score = people[mlog.name]
    for k in range(n_cycles):
        t = k * CYCLE_S
        w0 = time.perf_counter()
        if scenario.command_at(t) != command:  # the scenario's driver turns (a curve)
            command = scenario.command_at(t)
            world.command(*command, t)
        sweep = world.sweep(t)
        scan = Scan(sweep.ranges_m, bearings, t, seq=k, beam_dt_s=sweep.beam_dt_s, intensities=sweep.intensities)
        ox, oy, oth, ov, ow = world.odometry(t)
        odo = Odometry(ox, oy, oth, ov, ow, t)
        cam = _CameraTiming(frame_lag_s, camera_fps, jpeg_quality)
        frame, t_frame = cam.frame(world, scenario, t, k, last_frame, intr, hfov)
        last_frame = frame if frame is not None else last_frame
        truth = world.truth(t)
        truth_frame = world.truth(max(t_frame, 0.0))
        t_prev = max(t - CYCLE_S, 0.0)
        moving_prev = [float(np.hypot(*o.velocities(t_prev))) > 0.0 for o in scenario.obstacles]
        t_world += time.perf_counter() - w0

        views = _in_view(truth, truth_frame, moving_prev, sweep.hit_obstacle, frame is not None, mount, hfov)
        beams = np.bincount(sweep.hit_obstacle[sweep.hit_obstacle >= 0], minlength=len(truth.obstacles))
        log.times_s.append(t)
        log.true_poses.append((truth.x_m, truth.y_m, truth.theta_rad))
        log.true_obstacles.append([(o.x_m, o.y_m) for o in truth.obstacles])
        log.in_view.append(views)
        if keep_scans:
            log.scans.append(sweep.ranges_m)

        for est, mlog in methods.values():
            s0 = time.perf_counter()
            e = est.step(scan, odo, frame)
            mlog.step_s.append(time.perf_counter() - s0)
            t_est = world.truth(e.stamp_s) if abs(e.stamp_s - t) > 1e-9 else truth
            _record(mlog, e, t_est, views)
            _score_reports(mlog, judges[mlog.name], e, t, scenario, t_est, truth, odo.v_mps)
            people[mlog.name].update(t, e, t_est, beams)
    for _est, mlog in methods.values():
        mlog.minutes = n_cycles * CYCLE_S / 60.0
        ex, ey, eth = mlog.poses[-1]
        tx, ty, tth = log.true_poses[-1]
        mlog.final_pose_err_m = math.hypot(ex - tx, ey - ty)
        mlog.final_heading_err_deg = abs(math.degrees(math.atan2(math.sin(eth - tth), math.cos(eth - tth))))
    log.world_s = t_world
    return log


def _in_view(truth: Truth, truth_frame: Truth, moving_prev: list[bool], hit_obstacle: np.ndarray, have_frame: bool,
             mount: RobotMount, hfov_rad: float) -> list[bool]:
    """Per true obstacle: scored this cycle (moving now and a cycle ago, half in the camera's view at
    the frame's instant, and hit by at least ``MIN_BEAMS_IN_VIEW`` beams)."""
    c, s = math.cos(truth_frame.theta_rad), math.sin(truth_frame.theta_rad)
    cam_x = truth_frame.x_m + c * mount.camera_x_m - s * mount.camera_y_m
    cam_y = truth_frame.y_m + s * mount.camera_x_m + c * mount.camera_y_m
    beams = np.bincount(hit_obstacle[hit_obstacle >= 0], minlength=len(truth.obstacles))
    views = []
    for i, ob in enumerate(truth.obstacles):
        fo = truth_frame.obstacles[i]
        views.append(
            ob.moving
            and moving_prev[i]
            and have_frame
            and obstacle_in_camera(cam_x, cam_y, truth_frame.theta_rad, hfov_rad, fo.x_m, fo.y_m, fo.radius_m)
            and int(beams[i]) >= MIN_BEAMS_IN_VIEW
        )
    return views


def _record(mlog: MethodLog, e: Any, t_est: Truth, views: list[bool]) -> None:
    """One method's estimate of a cycle: its pose, restoration and obstacles, and for each true body
    in view the nearest estimate's position error (located within ``LOCATED_GATE_M``) and, for tracks
    old enough, its velocity error."""
    mlog.poses.append((e.pose.x_m, e.pose.y_m, e.pose.theta_rad))
    mlog.restored.append(tuple(e.restored_indices))
    est_xy = [(o.x_m, o.y_m) for o in e.obstacles]
    mlog.obstacles.append(est_xy)
    mlog.tracks.append(tuple(track_point(o) for o in e.obstacles))
    vis = [(i, o.x_m, o.y_m) for i, o in enumerate(t_est.obstacles) if views[i]]
    assigned = _assign(est_xy, vis)
    for i, _, _ in vis:
        mlog.in_view += 1
        if i not in assigned:
            continue
        eo = e.obstacles[assigned[i]]
        to = t_est.obstacles[i]
        err = math.hypot(eo.x_m - to.x_m, eo.y_m - to.y_m)
        mlog.errors_m.append(err)
        if err <= LOCATED_GATE_M:
            mlog.located += 1
        if eo.age_cycles >= MIN_TRACK_AGE:
            mlog.vel_errors_mps.append(math.hypot(eo.vx_mps - to.vx_mps, eo.vy_mps - to.vy_mps))


def scenario_result(log: RunLog) -> dict[str, Any]:
    """One scenario's JSON: both methods' metrics and the targets VIPSM misses (``targets_missed``;
    in the realistic world with the paper's cylinder, "vipsm_worse_than_plain_psm" when its mean error is
    the larger one)."""
    vipsm, plain = log.methods["vipsm"].metrics(), log.methods["plain_psm"].metrics()
    params = dict(log.scenario.params)
    missed = target_misses(vipsm, targets=targets_for(params))
    ev, ep = vipsm["obstacle_err_mean_m"], plain["obstacle_err_mean_m"]
    cylinder = params.get("obstacle_kind") == "cylinder" and params.get("obstacles", 1) > 0
    if params.get("world") == "realistic" and cylinder and ev is not None and ep is not None and ev > ep + 1e-3:
        missed.append("vipsm_worse_than_plain_psm")
    return {
        "name": log.scenario.name,
        "params": params,
        "cycles": len(log.times_s),
        "vipsm": vipsm,
        "plain_psm": plain,
        "targets_missed": missed,
    }


def tune_allocator() -> bool:
    """Keep freed memory in the process (glibc): a fixed 32 MB mmap threshold and no heap trimming.

    Each cycle allocates and frees many arrays of a few hundred kB (images, scans); glibc's default
    returns them to the kernel and faults them in again, which cost the evaluation about 1.3 million
    page faults and 3 s of system time for the two scenarios. Returns whether the tuning applied
    (False off glibc)."""
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        m_trim_threshold, m_mmap_threshold = -1, -3
        ok = libc.mallopt(m_mmap_threshold, 32 * 1024 * 1024) == 1
        return bool(ok and libc.mallopt(m_trim_threshold, 512 * 1024 * 1024) == 1)
    except (OSError, AttributeError):
        return False


def bench(args: argparse.Namespace) -> dict[str, Any]:
    """World speed: ms per UTM-30LX sweep, per 320x240 frame, and per evaluation cycle of world work
    (sweep + odometry + frame + JPEG round trip + truth), median of 50."""
    from hil_fakes.world import paper_scenario

    world = World(paper_scenario("1"))
    world.command(0.2, 0.0, 0.0)
    world.render(7.9)  # build the texture once, outside the timing
    sweep_ms, render_ms, cycle_ms = [], [], []
    for k in range(50):
        t = 8.0 + 0.1 * k
        a = time.perf_counter()
        world.sweep(t)
        b = time.perf_counter()
        img = world.render(t - 0.04)
        c = time.perf_counter()
        world.odometry(t)
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 80])
        cv2.imdecode(buf, cv2.IMREAD_COLOR)
        world.truth(t)
        world.truth(t - 0.04)
        world.truth(t - 0.1)
        d = time.perf_counter()
        sweep_ms.append(1000 * (b - a))
        render_ms.append(1000 * (c - b))
        cycle_ms.append(1000 * (d - a))
    return {
        "world_sweep_ms_median": round(float(np.median(sweep_ms)), 3),
        "world_render_320x240_ms_median": round(float(np.median(render_ms)), 3),
        "world_eval_cycle_ms_median": round(float(np.median(cycle_ms)), 3),
    }
