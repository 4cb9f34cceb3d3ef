"""``vipsm-robot eval``: the paper's experiments and the realistic suite on the simulated world, and
(``--data real``) the real-data suite on recorded scans (:mod:`app.evaluation.real_data`).

The command line only: the scenarios come from :mod:`app.evaluation.scenarios`, the run from
:mod:`app.evaluation.runner`, the metric definitions from :mod:`app.evaluation.metrics`, the table from
:mod:`app.evaluation.report` and the figures from :mod:`app.plots`.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from .cli import print_json
from .evaluation.metrics import ROBUSTNESS_FACTOR
from .evaluation.report import print_people_table, print_table
from .evaluation.runner import run_scenario, scenario_result, tune_allocator
from .evaluation.scenarios import add_scenario_arguments, driven_scenarios

#: the paper's two scenarios: their Fig. 8 is drawn at the paper's instants (6, 8, 10, 12 s)
PAPER_NAMES = {"paper1", "paper2", "scenario1_45deg", "scenario2_90deg"}


def cmd_eval(args: argparse.Namespace) -> int:
    if args.data == "real":
        return cmd_eval_real(args)
    if args.leg_model is not None:
        from .errors import AppError

        raise AppError("--leg-model applies to --data real (the simulated runs use the packaged leg detector)")
    tune_allocator()
    scenarios = driven_scenarios(args, args.scenario)
    results = []
    t0 = time.perf_counter()
    for sc in scenarios:
        log = run_scenario(
            sc,
            frame_lag_s=args.frame_lag_s,
            jpeg_quality=args.jpeg_quality,
            camera_fps=args.camera_fps,
            keep_scans=args.plots is not None,
        )
        results.append(scenario_result(log))
        if args.plots is not None:
            from .plots import write_figures

            for p in write_figures(log.traces(), Path(args.plots), sc.name, paper=sc.name in PAPER_NAMES,
                                   svg=args.svg):
                if not args.json:
                    print(f"wrote {p}")
    elapsed = time.perf_counter() - t0
    if args.json:
        print_json({"scenarios": results})
    else:
        print_table(results, ROBUSTNESS_FACTOR if args.scenario == "robustness" else 1.0)
        print_people_table(results)
        print(f"total {elapsed:.2f} s for {len(results)} scenario(s), both methods, {args.world} world")
    return 0


def default_real_data_dir() -> Path:
    """``$VIPSM_SHARED_DATA/real_people_laser``, else ``../shared/data/real_people_laser`` beside the
    repository."""
    import os

    base = os.environ.get("VIPSM_SHARED_DATA")
    root = Path(base) if base else Path(__file__).resolve().parents[1].parent / "shared" / "data"
    return root / "real_people_laser"


def cmd_eval_real(args: argparse.Namespace) -> int:
    """``eval --data real``: the real-data suite (:mod:`app.evaluation.real_data`)."""
    from vipsm.legs import ModelError

    from .errors import AppError
    from .evaluation.real_data import RECORDINGS, print_real_table, run_suite

    data_dir = Path(args.data_dir) if args.data_dir else default_real_data_dir()
    if not data_dir.is_dir():
        raise AppError(f"--data-dir {data_dir}: not a directory (expected the real_people_laser folder)")
    only = args.only.split(",") if args.only else None
    known = {r.name for r in RECORDINGS}
    if only and not set(only) <= known:
        unknown = ", ".join(sorted(set(only) - known))
        raise AppError(f"unknown recording(s) {unknown}; known: {', '.join(sorted(known))}")
    if args.max_scans is not None and args.max_scans < 1:
        raise AppError("--max-scans must be >= 1")
    t0 = time.perf_counter()
    try:
        suite = run_suite(data_dir, only, args.max_scans, Path(args.leg_model) if args.leg_model else None)
    except ModelError as exc:
        raise AppError(f"--leg-model: {exc}") from exc
    if args.json:
        print_json(suite)
    else:
        print_real_table(suite)
        print(f"total {time.perf_counter() - t0:.1f} s for {len(suite['recordings'])} recording(s), laser only")
    return 0


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "eval",
        help="the paper's experiments and the realistic suite on the simulated world: VIPSM vs plain PSM",
        description="Run VIPSM and plain PSM on identical simulated inputs and print the obstacle position "
        "error (Table 1), the final pose error, the obstacle velocity error and, in the realistic world, the "
        "false moving obstacles and false safety stops, each against its target.",
    )
    add_scenario_arguments(p, allow_all=True)
    p.add_argument(
        "--frame-lag-s",
        type=float,
        default=0.04,
        help="ideal world only: camera frame captured this long before the scan's first beam (default "
        "0.04 s); the realistic world's camera runs on its own clock with its own latency",
    )
    p.add_argument(
        "--camera-fps",
        type=float,
        default=0.0,
        help="ideal world only: free-running camera at this rate; each cycle gets the newest frame "
        "captured at least --frame-lag-s before the scan (0, the default: one fresh frame per cycle)",
    )
    p.add_argument(
        "--jpeg-quality",
        type=int,
        default=80,
        help="ideal world only: JPEG round trip of every frame (0: off; default 80); the realistic "
        "world uses its camera_jpeg_quality",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object: {scenarios: [...]}")
    p.add_argument("--plots", metavar="DIR", default=None,
                   help="write the figures per scenario (Fig. 8 map, Fig. 9 paths, errors over time) as PNG into DIR")
    p.add_argument("--svg", action="store_true", help="with --plots: also write each figure as SVG")
    g = p.add_argument_group("real recorded data (--data real)")
    g.add_argument("--data", choices=("sim", "real"), default="sim",
                   help="sim: the simulated scenarios (the default); real: the estimator, laser only, on every "
                   "recording of the real-data folder, scored per recording (the scenario options do not apply)")
    g.add_argument("--data-dir", metavar="DIR", default=None,
                   help="the real_people_laser folder (default: $VIPSM_SHARED_DATA/real_people_laser, else "
                   "../shared/data/real_people_laser beside the repository)")
    g.add_argument("--only", metavar="NAMES", default=None, help="comma list of recordings (e.g. positive_2)")
    g.add_argument("--max-scans", type=int, metavar="N", default=None, help="only the first N scans of each")
    g.add_argument("--leg-model", metavar="FILE", default=None,
                   help="the leg detector's model file (default: the packaged one); e.g. one trained with "
                   "tools/train_legs.py --held-out positive_N, to score a recording its detector never saw")
    p.set_defaults(func=cmd_eval)


def bench(args: argparse.Namespace) -> dict[str, object]:
    from .evaluation.runner import bench as world_bench

    return world_bench(args)
