"""``vipsm-robot sim``: the daemon's own code against the simulated robot, through the real bytes.

The world and the three byte-level fakes run in a child process (``app.simhost``); this process
runs exactly what ``run`` runs (device adapters, driver clients, estimator, field log, status
server) with the fakes' addresses as device URLs and the ``cruise`` mission at the scenario's robot
speed. The child streams the world's ground truth; the summary compares the daemon's live estimates
with it, using the evaluation's metric (``app.evaluation.metrics``: obstacle errors over the cycles where a
moving obstacle is in the camera's view, greedy nearest assignment, located within 0.5 m).

The scenario starts only when the daemon is ready: the child serves the world frozen at its time 0
while this process compiles its kernels and opens the devices, then ``start`` (``app.simhost``)
starts the world's clock just before the first cycle, however slow the machine.

Test hook: ``VIPSM_TEST_SLOW_START_S=S`` delays the daemon's start by S seconds after the simulated
devices are up (a slow or busy machine, simulated); for tests only, never set it otherwise.
"""

from __future__ import annotations

import argparse
import bisect
import dataclasses
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections import deque
from pathlib import Path
from typing import IO, Any

from hil_fakes.world import ObstacleTruth, Truth
from hil_fakes.world.scenarios import build_scenario
from hil_fakes.world.sensors import RobotMount
from vipsm.types import Estimate

from .config import Config
from .errors import AppError
from .evaluation.metrics import (
    LOCATED_GATE_M,
    MIN_TRACK_AGE,
    FalseStopJudge,
    MethodLog,
    _assign,
    count_reports,
    targets_for,
)
from .evaluation.runner import _replace_fields, mount_values
from .evaluation.scenarios import scenario_param_sets
from .procs import process_alive

SIM_LOG_PATTERN = "sim-%Y%m%d-%H%M%S.mcap"
#: the test hook delaying the daemon's start (see the module's doc)
SLOW_START_ENV = "VIPSM_TEST_SLOW_START_S"
#: how long the child may take to start the world's clock once asked
START_TIMEOUT_S = 30.0


def compose(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    c, s = math.cos(a[2]), math.sin(a[2])
    th = a[2] + b[2]
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], math.atan2(math.sin(th), math.cos(th)))


def inverse(a: tuple[float, float, float]) -> tuple[float, float, float]:
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-(c * a[0] + s * a[1]), -(-s * a[0] + c * a[1]), -a[2])


class TruthStream:
    """Reads the child's truth lines; ``at(t)`` is the sample nearest to monotonic time ``t``."""

    def __init__(self, stream: IO[str]) -> None:
        self._stream = stream
        self._times: deque[float] = deque(maxlen=3000)
        self._samples: deque[dict[str, Any]] = deque(maxlen=3000)
        self._lock = threading.Lock()
        self.final: dict[str, Any] | None = None
        self.error: str | None = None
        #: set when the child started the world's clock (its T0 in ``t0_mono``), or when the stream ended
        self.started = threading.Event()
        self.t0_mono: float | None = None
        self._thread = threading.Thread(target=self._run, name="sim-truth", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            for line in self._stream:
                msg = json.loads(line)
                if "started" in msg:
                    self.t0_mono = float(msg["started"])
                    self.started.set()
                    continue
                if "final" in msg:
                    self.final = msg["final"]
                    continue
                with self._lock:
                    self._times.append(msg["t"])
                    self._samples.append(msg)
        except (ValueError, OSError) as exc:
            self.error = f"{type(exc).__name__}: {exc}"
        finally:
            self.started.set()

    def at(self, t: float) -> dict[str, Any] | None:
        with self._lock:
            if not self._times:
                return None
            i = bisect.bisect_left(self._times, t)
            cands = [j for j in (i - 1, i) if 0 <= j < len(self._times)]
            j = min(cands, key=lambda k: abs(self._times[k] - t))
            if abs(self._times[j] - t) > 0.1:
                return None
            return self._samples[j]

    def join(self, timeout_s: float) -> None:
        self._thread.join(timeout_s)


class SimScorer:
    """Compares estimates with the world's truth in the estimator's frame (live in ``sim``, and in
    ``replay`` of a simulated run, where the truth and the frame origin come from the log)."""

    def __init__(self, truth: TruthStream | None = None, origin: tuple[float, float, float] | None = None) -> None:
        self.truth = truth
        self.method = MethodLog("vipsm")
        self.origin = origin
        self.last_pose_err: tuple[float, float] | None = None
        self.judge = FalseStopJudge()
        self._prev: tuple[float, float, float] | None = None  # stamp_s, x_m, y_m of the last estimate
        self._first_s: float | None = None

    def to_est(self, x: float, y: float) -> tuple[float, float]:
        assert self.origin is not None
        inv = inverse(self.origin)
        p = compose(inv, (x, y, 0.0))
        return p[0], p[1]

    def truth_for_log(self, t: float) -> dict[str, Any] | None:
        assert self.truth is not None
        sample = self.truth.at(t)
        if sample is None or self.origin is None:
            return None
        return {"origin": list(self.origin), "robot": sample["robot"], "obstacles": sample["obstacles"]}

    def on_estimate(self, est: Estimate, scan_stamp_s: float) -> None:
        assert self.truth is not None
        sample = self.truth.at(scan_stamp_s)
        if sample is not None:
            self.score(est, sample)

    def score(self, est: Estimate, sample: dict[str, Any]) -> None:
        """One estimate against one truth sample (``robot`` [x, y, theta] and ``obstacles`` rows
        [x, y, vx, vy, r, moving, in_view], world frame)."""
        robot = tuple(sample["robot"])
        if self.origin is None:
            # the estimator's frame is the odometry frame of its first scan: its first pose is the
            # odometry there, and the world pose there is the truth
            self.origin = compose(robot, inverse((est.pose.x_m, est.pose.y_m, est.pose.theta_rad)))  # type: ignore[arg-type]
        tr = compose(inverse(self.origin), robot)  # type: ignore[arg-type]
        dth = math.atan2(math.sin(est.pose.theta_rad - tr[2]), math.cos(est.pose.theta_rad - tr[2]))
        self.last_pose_err = (math.hypot(est.pose.x_m - tr[0], est.pose.y_m - tr[1]), abs(math.degrees(dth)))
        inv_th = -self.origin[2]
        c, s = math.cos(inv_th), math.sin(inv_th)
        vis = []
        true_v = {}
        for i, ob in enumerate(sample["obstacles"]):
            x, y, vx, vy, _r, _moving, in_view = ob
            if in_view:
                ex, ey = self.to_est(x, y)
                vis.append((i, ex, ey))
                true_v[i] = (c * vx - s * vy, s * vx + c * vy)
        self._score_reports(est, sample, tr, (c, s))
        est_xy = [(o.x_m, o.y_m) for o in est.obstacles]
        assigned = _assign(est_xy, vis)
        m = self.method
        for i, tx, ty in vis:
            m.in_view += 1
            if i not in assigned:
                continue
            eo = est.obstacles[assigned[i]]
            err = math.hypot(eo.x_m - tx, eo.y_m - ty)
            m.errors_m.append(err)
            if err <= LOCATED_GATE_M:
                m.located += 1
            if eo.age_cycles >= MIN_TRACK_AGE:
                m.vel_errors_mps.append(math.hypot(eo.vx_mps - true_v[i][0], eo.vy_mps - true_v[i][1]))

    def _score_reports(
        self, est: Estimate, sample: dict[str, Any], robot_est: tuple[float, float, float], rot: tuple[float, float]
    ) -> None:
        """False moving obstacles and false safety stops (``app.evaluation.metrics``' definitions), with
        the truth moved into the estimator's frame."""
        c, s = rot
        bodies = []
        for i, (x, y, vx, vy, r, moving, _in_view) in enumerate(sample["obstacles"]):
            ex, ey = self.to_est(x, y)
            bodies.append(ObstacleTruth(i, ex, ey, c * vx - s * vy, s * vx + c * vy, r, bool(moving)))
        t = est.stamp_s
        v_true = 0.0
        if self._prev is not None and t > self._prev[0]:
            v_true = math.hypot(est.pose.x_m - self._prev[1], est.pose.y_m - self._prev[2]) / (t - self._prev[0])
        self._prev = (t, est.pose.x_m, est.pose.y_m)
        self._first_s = t if self._first_s is None else self._first_s
        truth = Truth(t, robot_est[0], robot_est[1], robot_est[2], v_true, 0.0, tuple(bodies))
        m = self.method
        count_reports(m, truth, est.obstacles)
        stopped, false_stop = self.judge.update(
            t, (est.pose.x_m, est.pose.y_m, est.pose.theta_rad), v_true, est.obstacles, truth
        )
        m.stop_cycles += int(stopped)
        m.false_stop_cycles += int(false_stop)
        m.minutes = (t - self._first_s + 0.1) / 60.0

    def metrics(self) -> dict[str, Any]:
        if self.last_pose_err is not None:
            self.method.final_pose_err_m, self.method.final_heading_err_deg = self.last_pose_err
        out = self.method.metrics()
        out.pop("ms_per_cycle", None)
        return out


def _slow_start_for_tests() -> None:
    """The test hook: sleeps ``$VIPSM_TEST_SLOW_START_S`` seconds (unset: none)."""
    text = os.environ.get(SLOW_START_ENV, "")
    if text:
        try:
            delay_s = float(text)
        except ValueError as exc:
            raise AppError(f"{SLOW_START_ENV}={text!r}: not a number of seconds") from exc
        time.sleep(max(0.0, delay_s))


def start_world(child: subprocess.Popen[str], truth: TruthStream) -> float:
    """Tells the child the daemon is ready and waits for the world's clock to start; returns its T0
    (monotonic)."""
    assert child.stdin is not None
    child.stdin.write("start\n")
    child.stdin.flush()
    if not truth.started.wait(START_TIMEOUT_S) or truth.t0_mono is None:
        raise AppError(f"the simulated world did not start within {START_TIMEOUT_S:g} s"
                       + (f" ({truth.error})" if truth.error else ""))
    return truth.t0_mono


def _sim_config(config: Config, addresses: dict[str, Any], speed_mps: float, mode: str = "cruise") -> Config:
    d = dataclasses.replace(
        config.devices,
        scanner_url=addresses["scanner"],
        robot_url=addresses["robot"],
        camera_url=addresses["camera"],
        camera_http_url=addresses["camera_http"],
    )
    mission = dataclasses.replace(config.mission, mode=mode, cruise_speed_mps=speed_mps)
    estimator = _replace_fields(config.estimator, mount_values(RobotMount()))
    return dataclasses.replace(config, devices=d, mission=mission, estimator=estimator)


#: what a user ran ``sim`` for, first in its summary: metric -> the target when no scenario sets one
HEADLINE: dict[str, tuple[float, str] | None] = {
    "obstacle_err_mean_m": None,
    "obstacle_detected_fraction": None,
    "false_tracks_per_min": None,
    "pose_err_final_m": None,
    "deadline_misses": (0, "max"),
}


def headline(summary: dict[str, Any], targets: dict[str, tuple[float, str]]) -> dict[str, dict[str, Any]]:
    """The headline figures with their targets (the evaluation's, for this scenario) and met/missed."""
    out = {}
    for key, default in HEADLINE.items():
        target = targets.get(key, default)
        value = summary.get(key)
        met = None
        if target is not None:
            bound, kind = target
            met = value is not None and (value <= bound if kind == "max" else value >= bound)
        text = None if target is None else ("<= " if target[1] == "max" else ">= ") + f"{target[0]:g}"
        out[key] = {"value": value, "target": text, "met": met}
    return out


_HEADLINE_TEXT = {
    "obstacle_err_mean_m": ("obstacle error, mean", 1.0, "m", 3),
    "obstacle_detected_fraction": ("obstacle located", 100.0, "%", 1),
    "false_tracks_per_min": ("false moving obstacles", 1.0, "/min", 1),
    "pose_err_final_m": ("final pose error", 1.0, "m", 3),
    "deadline_misses": ("deadline misses", 1.0, "", 0),
}


def headline_lines(summary: dict[str, Any]) -> list[str]:
    """The headline as a small table for a terminal: figure, value, target, met or MISSED."""
    sc = summary.get("scenario", {})
    lines = [f"sim: {sc.get('name', '?')}, {summary.get('cycles', 0)} cycles"]
    for key, row in summary["headline"].items():
        label, scale, unit, digits = _HEADLINE_TEXT[key]
        v = row["value"]
        value = "n/a" if v is None else f"{v * scale:.{digits}f} {unit}".strip()
        target = ""
        if row["target"] is not None:
            op, bound = row["target"].split()
            target = f"target {op} {float(bound) * scale:g} {unit}".rstrip()
        verdict = {True: "met", False: "MISSED", None: ""}[row["met"]]
        lines.append(f"  {label:<24} {value:>12}   {target:<20} {verdict}")
    return lines


def summary_lines(summary: dict[str, Any]) -> list[str]:
    """``sim``'s short summary for a terminal: what ran, where its log and status server are, and the
    headline table last (so it is what stays on the screen)."""
    devices = summary.get("devices") or {}
    counts = (f"{summary.get('scans', 0)} scans, {summary.get('odometry_samples', 0)} odometry samples, "
              f"{summary.get('frames_used', 0)} frames used")
    lines = [f"devices: {counts}" + ("" if len(devices) == 3 else f" ({', '.join(sorted(devices))} only)")]
    log = summary.get("log_path")
    lines.append(f"log:     {log}   (vipsm-robot replay {log})" if log else "log:     none")
    status = summary.get("status_server")
    if status is not None:
        lines.append(f"status:  Modbus TCP on {status['host']}:{status['port']}")
    if summary.get("live_url"):
        lines.append(f"live:    {summary['live_url']}")
    lines.append("more:    --verbose (every figure), --json (the same as one JSON object)")
    scanner = (summary.get("fakes") or {}).get("scanner") or {}
    if scanner.get("scans_late"):
        lines.append(f"warning: the simulated world fell behind real time (this machine was too busy): "
                     f"{scanner['scans_late']} of {scanner['scans_late'] + scanner['scans_sent']} scans late or "
                     "skipped; the figures are of a starved run")
    return lines + headline_lines(summary)


SIM_DIR_PREFIX = "vipsm-sim-"
OWNER_FILE = "owner.pid"


def remove_stale_sim_dirs(tmp_root: str | None = None) -> list[str]:
    """Removes the folders of earlier ``sim`` runs that were killed (SIGKILL skips the cleanup): those
    of this user whose owner process is gone. Returns what was removed."""
    removed = []
    for d in Path(tmp_root or tempfile.gettempdir()).glob(SIM_DIR_PREFIX + "*"):
        try:
            if d.stat().st_uid != os.getuid():
                continue
            pid = int((d / OWNER_FILE).read_text(encoding="ascii"))
        except (OSError, ValueError):
            continue
        if pid == os.getpid() or process_alive(pid):
            continue
        shutil.rmtree(d, ignore_errors=True)
        removed.append(str(d))
    return removed




def run_sim(config: Config, args: argparse.Namespace) -> dict[str, Any]:
    from .devices import build_loop
    from .runtime import Progress, loop_summary, process_usage

    params = scenario_param_sets(args, getattr(args, "scenario", None) or "1")[0]
    try:
        scenario = build_scenario(params)  # checked here, so a bad flag is a one-line error
    except ValueError as exc:
        raise AppError(str(exc)) from exc
    duration_s = float(scenario.duration_s)
    remove_stale_sim_dirs()
    tmp = tempfile.mkdtemp(prefix=SIM_DIR_PREFIX)
    Path(tmp, OWNER_FILE).write_text(str(os.getpid()), encoding="ascii")
    err_path = os.path.join(tmp, "simhost.stderr")
    with open(err_path, "wb") as err_file:
        child = subprocess.Popen(
            [sys.executable, "-m", "app.simhost", json.dumps(params), tmp],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=err_file,
            text=True,
        )
    try:
        assert child.stdout is not None and child.stdin is not None
        first = child.stdout.readline()
        if not first:
            child.wait(10)
            with open(err_path, encoding="utf-8", errors="replace") as f:
                tail = f.read()[-2000:]
            raise AppError(f"the simulated devices did not start (exit {child.returncode}): {tail.strip()}")
        addresses = json.loads(first)
        truth = TruthStream(child.stdout)
        scorer = SimScorer(truth)
        cfg = _sim_config(config, addresses, float(scenario.robot_speed_mps), getattr(args, "mission", "cruise"))
        log_path = args.log if args.log is not None else (cfg.log.path if args.config else SIM_LOG_PATTERN)
        _slow_start_for_tests()
        loop = build_loop(cfg, log_path=log_path, truth=scorer.truth_for_log)
        loop.on_estimate = scorer.on_estimate
        try:
            from .daemon import freeze_startup_objects

            freeze_startup_objects()  # the loop's own start-up pause, before the world's clock starts
            start_world(child, truth)  # the daemon is ready: kernels loaded, devices open
        except AppError:
            loop.shutdown()
            raise
        stop = threading.Event()
        from .runtime import install_signal_handlers

        install_signal_handlers(stop)
        progress = Progress(duration_s, enabled=not args.no_progress)
        cpu0, wall0 = process_usage()["cpu_s"], time.monotonic()
        rss_samples: list[float] = []

        def show(lp: Any, elapsed: float) -> None:
            if lp.cycle % 50 == 0:
                rss_samples.append(process_usage()["rss_mb"])
            progress(f"sim: {elapsed:6.1f}/{duration_s:.0f} s, cycle {lp.cycle}, {lp.mission_state}", elapsed)

        try:
            loop.run(stop, duration_s=duration_s, progress=show)
        finally:
            loop.shutdown()
            progress.finish()
        usage = process_usage()
        wall = time.monotonic() - wall0
        summary = loop_summary(loop)
        summary.update(scorer.metrics())
        summary["scenario"] = {"name": scenario.name, "params": dict(scenario.params)}
        summary["daemon_cpu_percent"] = round(100.0 * (usage["cpu_s"] - cpu0) / wall, 2) if wall > 0 else None
        summary["rss_mb"] = round(usage["rss_mb"], 1)
        summary["rss_growth_mb"] = (
            round(rss_samples[-1] - rss_samples[len(rss_samples) // 4], 2) if len(rss_samples) >= 4 else None
        )
        child.stdin.close()
        child.wait(15)
        truth.join(5)
        summary["fakes"] = truth.final
        return {"headline": headline(summary, targets_for(params)), **summary}
    finally:
        if child.poll() is None:
            child.kill()
            child.wait(5)
        shutil.rmtree(tmp, ignore_errors=True)
