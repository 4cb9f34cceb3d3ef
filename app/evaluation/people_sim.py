"""``Estimate.people`` in the realistic simulated world: is every true body the laser sees a person entry,
and is its ``moving`` flag right?

    python -m app.evaluation.people_sim [--seed N] [--duration S] [--json] SCENARIO [SCENARIO ...]

Laser and odometry only (the people stage does not use the camera). Per scenario: over the cycles in
which a true body is hit by at least ``MIN_BEAMS`` beams, the share with a person within ``LOCATED_M``
(``located``), the median distance of those (``error_median_m``), the share flagged ``moving`` while the
body walks (``moving_while_walking``) and while it stands (``moving_while_standing``), and moving people
further than ``FALSE_M`` from every true body per minute (``false_moving_per_min``: furniture or
phantoms taken for walkers).
"""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

import numpy as np

from hil_fakes.world import RobotMount, World
from vipsm.types import Odometry, Scan

from .runner import CYCLE_S, make_estimators
from .scenarios import build_scenarios

MIN_BEAMS = 3
LOCATED_M = 0.5
FALSE_M = 1.0


def _share(num: int, den: int) -> float | None:
    return round(num / den, 3) if den else None


def run(name: str, seed: int | None = None, duration_s: float | None = None) -> dict[str, Any]:
    args = argparse.Namespace(scenario=name, world="realistic", scenario_file=None, seed=seed, duration=duration_s)
    sc = build_scenarios(args, name)[0]
    mount = RobotMount()
    world = World(sc, mount=mount)
    est, _ = make_estimators(mount)
    bearings = world.laser.angles_rad()
    cmd = sc.command_at(0.0)
    world.command(*cmd, 0.0)
    n = int(math.floor(sc.duration_s / CYCLE_S + 1e-9)) + 1
    count = {"seen": 0, "located": 0, "walking": 0, "moving_walking": 0, "standing": 0, "moving_standing": 0,
             "false": 0}
    errors: list[float] = []
    for k in range(n):
        t = k * CYCLE_S
        if sc.command_at(t) != cmd:
            cmd = sc.command_at(t)
            world.command(*cmd, t)
        sweep = world.sweep(t)
        e = est.step(Scan(sweep.ranges_m, bearings, t, seq=k, beam_dt_s=sweep.beam_dt_s),
                     Odometry(*world.odometry(t), t), None)
        _score(e.people, world.truth(t), sweep.hit_obstacle, count, errors)
    minutes = n * CYCLE_S / 60.0
    return {"scenario": name, "seed": sc.seed, "cycles_in_view": count["seen"],
            "located": _share(count["located"], count["seen"]),
            "error_median_m": round(float(np.median(errors)), 3) if errors else None,
            "moving_while_walking": _share(count["moving_walking"], count["walking"]),
            "moving_while_standing": _share(count["moving_standing"], count["standing"]),
            "false_moving_per_min": round(count["false"] / minutes, 1)}


def _score(people: tuple[Any, ...], truth: Any, hit_obstacle: np.ndarray, count: dict[str, int],
           errors: list[float]) -> None:
    hits = np.bincount(hit_obstacle[hit_obstacle >= 0], minlength=len(truth.obstacles))
    xy = np.array([[p.x_m, p.y_m] for p in people]).reshape(-1, 2)
    for i, ob in enumerate(truth.obstacles):
        if hits[i] < MIN_BEAMS:
            continue
        count["seen"] += 1
        if not xy.size:
            continue
        d = np.hypot(xy[:, 0] - ob.x_m, xy[:, 1] - ob.y_m)
        j = int(np.argmin(d))
        if d[j] > LOCATED_M:
            continue
        count["located"] += 1
        errors.append(float(d[j]))
        kind = "walking" if ob.moving else "standing"
        count[kind] += 1
        count[f"moving_{kind}"] += int(people[j].moving)
    count["false"] += sum(1 for p in people if p.moving and all(
        math.hypot(p.x_m - ob.x_m, p.y_m - ob.y_m) > FALSE_M for ob in truth.obstacles))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m app.evaluation.people_sim", description=__doc__.split("\n")[0])
    ap.add_argument("scenarios", nargs="+", help="realistic-suite scenario names")
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--duration", type=float, default=None, help="seconds (default: the scenario's)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    for name in args.scenarios:
        print(json.dumps(run(name, args.seed, args.duration), indent=None if args.json else 2), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
