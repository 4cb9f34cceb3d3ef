"""Depth edges in recorded laser scans and in the simulated world's sweeps, measured the same way.

    PYTHONPATH=. python tools/laser_edges.py [--data-dir DIR] [--only SOURCE,...] [--fine] [--step S] [--json]

At every depth edge (two surfaces side by side, ranges at least 5 cm and 6 noise sigmas apart) the beams
between them are classified (:mod:`hil_fakes.world.edges`): a *mixed* pixel strictly between the surfaces,
a return *pulled* a few cm off one surface towards the other, *no echo*, a *clean* edge, or *other*. The
shares are reported per depth gap (``--fine``: finer bins) and per range of the nearer surface, for:

* ``utm30lx_frame``: the one recorded UTM-30LX ME frame (``hokuyo_utm30lx_session``, 1081 beams);
* ``utm30lx_diosi``: 25 recorded UTM-30LX scans (``psm_diosi_examples``, Mohsen Akbaritabar's set);
* ``leg_tracker_drive``: the 768-beam Hokuyo of the people recordings driving through empty rooms
  (``real_people_laser/negative_2.bag``, three lasers, about 1300 scans);
* ``leg_tracker_still``: the same sensor held still with people walking (``positive_1,2,3,6.bag``; the
  same static edges repeat scan after scan);
* ``world_utm30lx``, ``world_leg_tracker``: the realistic world's sweeps (``WORLD_SCENES``, every
  ``--step`` s, the robot driven as ``eval`` drives it), on the UTM-30LX's beams and on the recordings'
  beam pattern with their noise (``app.evaluation.leg_realism``).

The noise sigma per sensor: the UTM-30LX's measured model (``hil_fakes.world.LaserModel``), the
recordings' 5 mm (``LEG_TRACKER_SIGMA_M``). Shared data are read in place; a missing source is reported
as absent.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from hil_fakes.world import LaserModel  # noqa: E402
from hil_fakes.world.edges import FINE_GAP_BINS_M, GAP_BINS_M, KINDS, RANGE_BINS_M, rates, scan_edges  # noqa: E402

SOURCES = ("utm30lx_frame", "utm30lx_diosi", "leg_tracker_drive", "leg_tracker_still", "world_utm30lx",
           "world_leg_tracker")
#: the realistic suite's scenes the world's edges are taken from: furniture, people, a cylinder
WORLD_SCENES = ("static_clutter", "cylinder_clutter", "crowd", "cross_90", "cross_30", "two_people_opposite")
STILL_BAGS = ("positive_1", "positive_2", "positive_3", "positive_6")


def _utm_sigma(r: np.ndarray) -> np.ndarray:
    return LaserModel().sigma_m(r)


def _leg_tracker_sigma(r: np.ndarray) -> np.ndarray:
    from app.evaluation.leg_realism import LEG_TRACKER_SIGMA_M

    return np.full(r.shape, LEG_TRACKER_SIGMA_M)


def utm30lx_frame(shared: Path) -> list[np.ndarray]:
    """The recorded ME frame's ranges (m; below DMIN = no return)."""
    from drivers.hokuyo_scip.codec import ScanFrame, ScipDecoder

    path = shared / "hokuyo_utm30lx_session" / "example_utm_30lx.jsonl"
    if not path.exists():
        return []
    dec, frames = ScipDecoder(), []
    for line in path.read_text().splitlines():
        rec = json.loads(line)
        if rec["dir"] == "sensor_to_host":
            frames += [e for e in dec.feed(bytes.fromhex(rec["hex"])) if isinstance(e, ScanFrame)]
    out = []
    for f in frames:
        r = f.distances.astype(float) / 1000.0
        out.append(np.where(r >= LaserModel().dmin_m, r, np.nan))
    return out


def utm30lx_diosi(shared: Path) -> list[np.ndarray]:
    from app.evaluation.psm_real import DIOSI_FILE, read_diosi_scans

    path = shared / DIOSI_FILE
    return [s.ranges_m for s in read_diosi_scans(path)] if path.exists() else []


def bag_scans(shared: Path, names: tuple[str, ...]) -> list[np.ndarray]:
    """Every scan of every laser topic of the named recordings."""
    from app.bagread import BagTopics, read_bag
    from app.evaluation.real_data import scan_topics

    out = []
    for name in names:
        bag = shared / "real_people_laser" / f"{name}.bag"
        if not bag.exists():
            continue
        for topic in scan_topics(bag):
            out += [bc.scan.ranges_m for bc in read_bag(bag, BagTopics(topic))]
    return out


def world_sweeps(geometry: str, step_s: float) -> Iterator[np.ndarray]:
    from app.evaluation.leg_realism import sweeps
    from hil_fakes.world.scenarios import suite_scenario

    for name in WORLD_SCENES:
        for _, _, sw, _ in sweeps(suite_scenario(name), geometry, step_s):
            yield sw.ranges_m


def measure(shared: Path, only: tuple[str, ...], step_s: float, fine: bool) -> dict[str, Any]:
    gaps = FINE_GAP_BINS_M if fine else GAP_BINS_M
    loaders = {
        "utm30lx_frame": (lambda: utm30lx_frame(shared), _utm_sigma),
        "utm30lx_diosi": (lambda: utm30lx_diosi(shared), _utm_sigma),
        "leg_tracker_drive": (lambda: bag_scans(shared, ("negative_2",)), _leg_tracker_sigma),
        "leg_tracker_still": (lambda: bag_scans(shared, STILL_BAGS), _leg_tracker_sigma),
        "world_utm30lx": (lambda: list(world_sweeps("utm30lx", step_s)), _utm_sigma),
        "world_leg_tracker": (lambda: list(world_sweeps("leg_tracker", step_s)), _leg_tracker_sigma),
    }
    report: dict[str, Any] = {"kinds": list(KINDS)}
    for name in only:
        load, sigma = loaders[name]
        scans = load()
        if not scans:
            report[name] = {"absent": True}
            continue
        report[name] = {"scans": len(scans), **rates(scan_edges(scans, sigma), gaps, RANGE_BINS_M)}
    return report


def table(report: dict[str, Any]) -> str:
    lines = ["| source | bin | edges | " + " | ".join(KINDS) + " |", "|---|---|---|" + "---|" * len(KINDS)]
    for name, fig in report.items():
        if not isinstance(fig, dict):
            continue
        if fig.get("absent"):
            lines.append(f"| {name} | absent | | " + " | " * len(KINDS))
            continue
        for group, label in (("by_gap", "gap"), ("by_range", "range")):
            for b, v in fig[group].items():
                lines.append(f"| {name} ({fig['scans']} scans) | {label} {b} | {v['edges']} | "
                             + " | ".join(f"{v[k]:.2f}" for k in KINDS) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="tools/laser_edges.py", description=__doc__.split("\n")[0])
    ap.add_argument("--data-dir", type=Path, default=None,
                    help="the shared data folder (default: $VIPSM_SHARED_DATA, else ../shared/data)")
    ap.add_argument("--only", default=",".join(SOURCES), help=f"comma-separated sources ({', '.join(SOURCES)})")
    ap.add_argument("--step", type=float, default=0.5, help="seconds between the world's sweeps (default 0.5)")
    ap.add_argument("--fine", action="store_true", help="finer depth gap bins")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    only = tuple(s.strip() for s in args.only.split(",") if s.strip())
    bad = [s for s in only if s not in SOURCES]
    if bad or not only:
        print(f"laser_edges: error: unknown source(s) {bad} (choose from {', '.join(SOURCES)})", file=sys.stderr)
        return 2
    if not 0.01 <= args.step <= 5.0:
        print(f"laser_edges: error: --step must be in [0.01, 5] s, got {args.step}", file=sys.stderr)
        return 2
    if args.data_dir is None:
        from app.cmd_eval import default_real_data_dir

        shared = default_real_data_dir().parent
    else:
        shared = args.data_dir
    if not shared.is_dir():
        print(f"laser_edges: error: no shared data folder at {shared} (--data-dir)", file=sys.stderr)
        return 2
    report = measure(shared, only, args.step, args.fine)
    print(json.dumps(report) if args.json else table(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
