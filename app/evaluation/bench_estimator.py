"""The estimator's benchmarks (``vipsm-robot bench --only estimator``): PSM and the whole step on the
simulated paper scenario 2, and the step on every scenario of the realistic suite."""

from __future__ import annotations

import argparse
import math
import statistics
import time
from typing import Any

import numpy as np

from vipsm.geometry import between
from vipsm.psm import match
from vipsm.types import Scan


def bench(args: argparse.Namespace) -> dict[str, Any]:
    """PSM ms per 1081-beam match and the whole estimator step with a 320x240 frame, on the simulated
    paper scenario 2 (inputs generated first; only the estimator is timed)."""
    import cv2

    from hil_fakes.world import RobotMount, World, build_scenario, intrinsics, paper_params
    from vipsm.estimator import Estimator, EstimatorConfig
    from vipsm.psm import match_prepared, prepare
    from vipsm.types import Frame, Intrinsics, Odometry

    from ..legmodel import default_leg_model

    scenario = build_scenario(paper_params("2", {"duration_s": 20.0}))
    mount = RobotMount()
    world = World(scenario, mount=mount)
    world.command(scenario.robot_speed_mps, 0.0, 0.0)
    hfov = math.radians(54.0)
    fx, fy, cx, cy = intrinsics(320, 240, hfov)
    intr = Intrinsics(fx, fy, cx, cy, 320, 240)
    bearings = world.laser.angles_rad()
    inputs = []
    for k in range(int(scenario.duration_s / 0.1) + 1):
        t = 0.1 * k
        sw = world.sweep(t)
        o = world.odometry(t)
        img = world.render(max(t - 0.04, 0.0), 0.0, 0.0, hfov)
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 80])
        if ok:
            img = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        frame = Frame(img, max(t - 0.04, 0.0), intr, seq=k)
        inputs.append((Scan(sw.ranges_m, bearings, t, seq=k, beam_dt_s=sw.beam_dt_s), Odometry(*o, t), frame))
    ecfg = EstimatorConfig(
        laser_x_m=mount.laser_x_m,
        laser_y_m=mount.laser_y_m,
        laser_theta_rad=mount.laser_theta_rad,
        camera_x_m=mount.camera_x_m,
        camera_y_m=mount.camera_y_m,
        camera_z_m=mount.camera_z_m,
    )
    # PSM alone: consecutive scans (0.1 s apart) seeded with odometry, the estimator's PSM config
    psm_cfg = ecfg.psm
    mount_pose = ecfg.laser_mount
    from vipsm.geometry import compose, inverse

    match_ms, match_cpu_ms, prepared_ms = [], [], []
    for (s0, o0, _), (s1, o1, _) in zip(inputs[:-1], inputs[1:]):
        guess = compose(compose(inverse(mount_pose), between(o0.pose, o1.pose)), mount_pose)
        t0 = time.perf_counter()
        c0 = time.process_time()
        match(s0, s1, guess, psm_cfg)
        match_cpu_ms.append(1000.0 * (time.process_time() - c0))
        match_ms.append(1000.0 * (time.perf_counter() - t0))
        ref = prepare(s0, psm_cfg)
        t0 = time.perf_counter()
        cur = prepare(s1, psm_cfg)
        match_prepared(ref, cur, guess, psm_cfg)
        prepared_ms.append(1000.0 * (time.perf_counter() - t0))
    step_ms, step_cpu_ms = [], []
    est = Estimator(ecfg, leg_model=default_leg_model())
    for scan, odo, frame in inputs:
        t0 = time.perf_counter()
        c0 = time.process_time()
        est.step(scan, odo, frame)
        step_cpu_ms.append(1000.0 * (time.process_time() - c0))
        step_ms.append(1000.0 * (time.perf_counter() - t0))
    plain_ms = []
    est = Estimator(ecfg, plain_psm=True, leg_model=default_leg_model())
    for scan, odo, frame in inputs:
        t0 = time.perf_counter()
        est.step(scan, odo, frame)
        plain_ms.append(1000.0 * (time.perf_counter() - t0))
    return {
        "data": "simulated paper scenario 2 (hil_fakes.world), 1081-beam UTM-30LX sweeps, 320x240 JPEG frames",
        "psm_matches": len(match_ms),
        "psm_ms_per_match_median": round(statistics.median(match_ms), 3),
        "psm_ms_per_match_p99": round(float(np.percentile(match_ms, 99)), 3),
        "psm_cpu_ms_per_match_median": round(statistics.median(match_cpu_ms), 3),
        "psm_ms_per_match_one_prepare_median": round(statistics.median(prepared_ms), 3),
        "estimator_steps": len(step_ms),
        "estimator_step_ms_median": round(statistics.median(step_ms), 3),
        "estimator_step_ms_p99": round(float(np.percentile(step_ms, 99)), 3),
        "estimator_step_cpu_ms_median": round(statistics.median(step_cpu_ms), 3),
        "estimator_step_cpu_ms_p99": round(float(np.percentile(step_cpu_ms, 99)), 3),
        "note": "wall-clock (perf_counter) and process CPU time (process_time; includes OpenCV worker threads)",
        "plain_psm_step_ms_median": round(statistics.median(plain_ms), 3),
        **_real_scans(),
        **_realistic_suite_steps(),
    }


def _real_scans() -> dict[str, Any]:
    """PSM on the real recorded scans in ``../shared/data`` (or ``$VIPSM_SHARED_DATA``)."""
    import os
    from pathlib import Path

    from app.evaluation.psm_real import bench_real

    data = Path(os.environ.get("VIPSM_SHARED_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))
    if not data.is_dir():
        return {"psm_real_skipped": f"no real data at {data} (set VIPSM_SHARED_DATA)"}
    return bench_real(data)


def _realistic_suite_steps(duration_s: float = 10.0) -> dict[str, Any]:
    """The VIPSM step on every scenario of the realistic suite (first ``duration_s`` of each): people,
    furniture, a real laser's artefacts; wall-clock per step, with the machine's load."""
    import os

    from app.evaluation.runner import run_scenario
    from hil_fakes.world.scenarios import REALISTIC_SUITE, suite_scenario

    steps: list[float] = []
    for name in REALISTIC_SUITE:
        log = run_scenario(suite_scenario(name, overrides={"duration_s": duration_s}))
        steps += log.methods["vipsm"].step_s
    ms = 1000.0 * np.asarray(steps)
    return {
        "realistic_suite_steps": int(ms.size),
        "realistic_suite_step_ms_median": round(float(np.median(ms)), 3),
        "realistic_suite_step_ms_p99": round(float(np.percentile(ms, 99)), 3),
        "realistic_suite_step_ms_max": round(float(np.max(ms)), 3),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }
