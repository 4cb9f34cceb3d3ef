"""What velocity error a causal filter can reach on a scene's walkers: the bound behind issue 29's 0.15 m/s.

    PYTHONPATH=. python tools/velocity_bound.py --scenario stop_and_go [--seed N] [--noise-m 0.02,0.03]
                                                [--repeats 10] [--json]

The estimator's velocity error (``eval``'s ``person_velocity_err_max_mps``) is the mean over the cycles a
walker is in view and walking, once its track is a second old. Through a start or a stop a filter lags: how
much is set by the measurements' noise and the filter's motion model, not by the tracker's association. This
tool measures that part alone. It runs the realistic world of the scenario (the robot driven as ``eval``
drives it), takes each person's true pelvis path every 0.1 s, adds white position noise of each
``--noise-m`` (the leg-pair midpoint's jitter about the pelvis: 0.016-0.027 m per axis on the real
recordings, 0.028 m in the world while walking), and filters it with

* the people stage's own IMM (:class:`vipsm.imm.Imm`, default models; the velocity given that it walks
  while P(walking) >= 0.5, the combination otherwise, as :meth:`vipsm.people.PeopleTracker.people` reports);
* a constant-velocity Kalman filter at each white-acceleration sigma of ``CV_ACCEL_MPS2``, the best of
  them kept (chosen per scene, on the truth: an optimistic bound).

Both see every cycle from the run's start (perfect association, no gap, no occlusion). The error is scored
on the cycles ``eval`` could score: the person walking (true speed above zero) and in view (enough beams on
its legs and not inside a wall: ``person_metrics.person_in_view``), from 1 s after it first came into view (a
track's ``MIN_TRACK_AGE``). The figure is the mean over ``--repeats`` noise draws (seeded, reproducible).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from app.errors import AppError  # noqa: E402
from app.evaluation.person_metrics import CYCLE_S, MIN_TRACK_AGE, person_in_view, wall_segments  # noqa: E402
from app.evaluation.scenarios import REALISTIC_SUITE, build_scenarios  # noqa: E402
from hil_fakes.world import RobotMount, Scenario, World  # noqa: E402
from vipsm.imm import Imm, ImmConfig  # noqa: E402

#: the constant-velocity filter's white-acceleration sigmas tried (m/s^2); the best is reported
CV_ACCEL_MPS2 = (0.5, 1.0, 2.0, 3.0, 5.0)


def person_paths(scenario: Scenario) -> dict[int, dict[str, np.ndarray]]:
    """Per person of ``scenario``: its true position (n, 2), velocity (n, 2) and whether ``eval`` scores its
    velocity (n,) at each cycle of the run."""
    world = World(scenario, mount=RobotMount())
    persons = [i for i, o in enumerate(scenario.obstacles) if getattr(o, "kind", "") == "person"]
    walls = wall_segments(scenario)
    n = int(math.floor(scenario.duration_s / CYCLE_S + 1e-9)) + 1
    pos = {i: np.zeros((n, 2)) for i in persons}
    vel = {i: np.zeros((n, 2)) for i in persons}
    view = {i: np.zeros(n, bool) for i in persons}
    command = scenario.command_at(0.0)
    world.command(*command, 0.0)
    for k in range(n):
        t = k * CYCLE_S
        if scenario.command_at(t) != command:
            command = scenario.command_at(t)
            world.command(*command, t)
        hits = world.sweep(t).hit_obstacle
        beams = np.bincount(hits[hits >= 0], minlength=len(scenario.obstacles))
        truth = world.truth(t)
        for i in persons:
            o = truth.obstacles[i]
            pos[i][k], vel[i][k] = (o.x_m, o.y_m), (o.vx_mps, o.vy_mps)
            view[i][k] = person_in_view(o, int(beams[i]), walls)
    out = {}
    for i in persons:
        first = int(np.argmax(view[i])) if view[i].any() else n
        scored = view[i] & (np.hypot(*vel[i].T) > 0.0) & (np.arange(n) >= first + MIN_TRACK_AGE)
        out[i] = {"pos": pos[i], "vel": vel[i], "scored": scored}
    return out


def cv_velocities(z: np.ndarray, accel_mps2: float, noise_m: float) -> np.ndarray:
    """A constant-velocity Kalman filter's velocity after each of the positions ``z`` (n, 2), 0.1 s apart."""
    dt = CYCLE_S
    f = np.eye(4)
    f[0, 2] = f[1, 3] = dt
    g = np.array([[dt**4 / 4, 0, dt**3 / 2, 0], [0, dt**4 / 4, 0, dt**3 / 2],
                  [dt**3 / 2, 0, dt**2, 0], [0, dt**3 / 2, 0, dt**2]]) * accel_mps2**2
    h = np.eye(2, 4)
    x = np.array([z[0, 0], z[0, 1], 0.0, 0.0])
    p = np.diag([noise_m**2, noise_m**2, 1.0, 1.0])
    out = np.zeros_like(z)
    for k in range(1, len(z)):
        x, p = f @ x, f @ p @ f.T + g
        gain = p @ h.T @ np.linalg.inv(h @ p @ h.T + np.eye(2) * noise_m**2)
        x, p = x + gain @ (z[k] - h @ x), (np.eye(4) - gain @ h) @ p
        out[k] = x[2:]
    return out


def imm_velocities(z: np.ndarray, noise_m: float) -> np.ndarray:
    """The people stage's IMM's reported velocity after each of the positions ``z`` (n, 2), 0.1 s apart."""
    filt = Imm(float(z[0, 0]), float(z[0, 1]), noise_m, ImmConfig())
    out = np.zeros_like(z)
    for k in range(1, len(z)):
        filt.predict(CYCLE_S)
        filt.update(z[k], np.eye(2) * noise_m**2)
        out[k] = filt.walking()[0][2:4] if filt.p_moving >= 0.5 else filt.mean[2:4]
    return out


def bound(path: dict[str, np.ndarray], noise_m: float, repeats: int, seed: int) -> dict[str, Any]:
    """Mean velocity error over the scored cycles of one person's path at white noise ``noise_m``."""
    rng = np.random.default_rng(seed)
    scored = path["scored"]
    imm, cv = [], {a: [] for a in CV_ACCEL_MPS2}
    for _ in range(repeats):
        z = path["pos"] + rng.normal(0.0, noise_m, path["pos"].shape)
        imm.append(float(np.hypot(*(imm_velocities(z, noise_m) - path["vel"]).T)[scored].mean()))
        for a in CV_ACCEL_MPS2:
            cv[a].append(float(np.hypot(*(cv_velocities(z, a, noise_m) - path["vel"]).T)[scored].mean()))
    best = min(CV_ACCEL_MPS2, key=lambda a: float(np.mean(cv[a])))
    return {"noise_m": noise_m, "imm_mps": round(float(np.mean(imm)), 3),
            "cv_best_mps": round(float(np.mean(cv[best])), 3), "cv_best_accel_mps2": best}


def _noises(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        raise AppError(f"--noise-m must be comma-separated metres, got {text!r}") from exc
    if not values or not all(math.isfinite(v) and v > 0.0 for v in values):
        raise AppError(f"--noise-m needs positive finite values, got {text!r}")
    return values


def run(scenario_name: str, seed: int | None, noises: list[float], repeats: int) -> dict[str, Any]:
    if scenario_name not in REALISTIC_SUITE:
        raise AppError(f"--scenario must be one of the realistic suite's scenes: {', '.join(REALISTIC_SUITE)}")
    if repeats < 1:
        raise AppError(f"--repeats must be >= 1, got {repeats}")
    args = argparse.Namespace(scenario=scenario_name, world="realistic", scenario_file=None, seed=seed, duration=None)
    scenario = build_scenarios(args, scenario_name)[0]
    paths = person_paths(scenario)
    if not paths:
        raise AppError(f"--scenario {scenario_name} has no person")
    persons = []
    for i, path in paths.items():
        scored = int(path["scored"].sum())
        rows = [bound(path, s, repeats, 0) for s in noises] if scored else []
        persons.append({"index": i, "scored_cycles": scored, "bounds": rows})
    return {"scenario": scenario_name, "seed": seed, "repeats": repeats, "persons": persons}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", required=True, help="a scene of the realistic suite")
    ap.add_argument("--seed", type=int, default=None, help="the scene's seed (default: the suite's)")
    ap.add_argument("--noise-m", default="0.01,0.02,0.03", help="white position noise per axis, comma-separated (m)")
    ap.add_argument("--repeats", type=int, default=10, help="noise draws averaged")
    ap.add_argument("--json", action="store_true", help="print JSON")
    a = ap.parse_args(argv)
    try:
        res = run(a.scenario, a.seed, _noises(a.noise_m), a.repeats)
    except AppError as exc:
        print(f"velocity_bound: {exc}", file=sys.stderr)
        return 2
    if a.json:
        print(json.dumps(res, indent=1))
        return 0
    for p in res["persons"]:
        print(f"{res['scenario']} person {p['index']}: {p['scored_cycles']} scored cycles")
        for b in p["bounds"]:
            print(f"  noise {b['noise_m']:.3f} m: IMM {b['imm_mps']:.3f} m/s, best constant velocity "
                  f"{b['cv_best_mps']:.3f} m/s (accel sigma {b['cv_best_accel_mps2']} m/s^2)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
