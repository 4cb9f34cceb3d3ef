"""The leg detector on the URG-04LX-class demo recording (no labels: a check, never trained on).

    PYTHONPATH=$PWD python -m app.legmodel_urg [--data-dir DIR] [--model FILE] [--every N] [--json]

The demo recording (``demo_stationary_simple_environment.bag``: the laser stands still, people walk past)
has no labels, so its walkers' legs are taken as the leg-candidate segments whose every return lies at
least ``IN_FRONT_M`` in front of that beam's ``BACKGROUND_QUANTILE`` range over the whole recording (what
stands there only at times). Per range band: the segments' count, the share the detector takes, and the
quartiles of the shape features that tell a flat, held segment from a curved one (docs/estimator.md
stage 1, "Legs with few returns").
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from app.bagread import BagTopics, read_bag
from app.legmodel import leg_candidates, load_leg_model
from vipsm.legs import FEATURE_NAMES, LegModel, ModelError

DEMO_BAG = "demo_stationary_simple_environment.bag"
#: a segment this far in front of the background on every return is something that moved there
IN_FRONT_M = 0.3
#: the background: this quantile of each beam's ranges over the recording (people pass, walls stay)
BACKGROUND_QUANTILE = 90.0
BANDS_M = ((0.0, 1.5), (1.5, 2.5), (2.5, 3.6), (3.6, 6.0))
SHAPE = ("n_points", "width_m", "linearity_m", "radius_m", "mean_curvature", "std_angle_rad")


def transient_segments(bag: Path, every: int = 2) -> np.ndarray:
    """Features (n x ``FEATURE_NAMES``) of the leg candidates of every ``every``-th scan that stand in
    front of the recording's background."""
    from app.evaluation.real_data import scan_topics

    scans = [bc.scan for bc in read_bag(bag, BagTopics(scan_topics(bag)[0]))]
    ranges = np.array([s.ranges_m for s in scans], dtype=np.float64)
    with warnings.catch_warnings():  # a beam that never returned has no background: NaN, nothing in front
        warnings.simplefilter("ignore", RuntimeWarning)
        background = np.nanpercentile(ranges, BACKGROUND_QUANTILE, axis=0)
    rows = []
    for scan, r in zip(scans[::every], ranges[::every], strict=True):
        kept, x = leg_candidates(r, scan.bearings_rad)
        for (a, z, _), row in zip(kept, x, strict=True):
            k = a + np.flatnonzero(np.isfinite(r[a:z]))
            if np.all(r[k] < background[k] - IN_FRONT_M):
                rows.append(row)
    return np.array(rows).reshape(-1, len(FEATURE_NAMES))


def report(x: np.ndarray, model: LegModel) -> dict[str, Any]:
    p = model.predict(x) if len(x) else np.zeros(0)
    out: dict[str, Any] = {"threshold_p": round(model.threshold_p, 4), "segments": int(len(x)), "bands": {}}
    rng_m = x[:, FEATURE_NAMES.index("range_m")]
    for lo, hi in BANDS_M:
        sel = (rng_m >= lo) & (rng_m < hi)
        band: dict[str, Any] = {"segments": int(sel.sum())}
        if sel.any():
            band["taken"] = round(float(np.mean(p[sel] >= model.threshold_p)), 3)
            for name in SHAPE:
                q = np.quantile(x[sel, FEATURE_NAMES.index(name)], [0.25, 0.5, 0.75])
                band[name] = [round(float(v), 4) for v in q]
        out["bands"][f"{lo:g}-{hi:g}m"] = band
    return out


def main(argv: list[str] | None = None) -> int:
    from app.cmd_eval import default_real_data_dir

    ap = argparse.ArgumentParser(prog="python -m app.legmodel_urg", description=__doc__.split("\n")[0])
    ap.add_argument("--data-dir", type=Path, default=None)
    ap.add_argument("--model", type=Path, default=None, help="a leg model file (default: the packaged one)")
    ap.add_argument("--every", type=int, default=2, help="every N-th scan (default %(default)s)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if args.every < 1:
        print(f"legmodel_urg: error: --every must be >= 1, got {args.every}", file=sys.stderr)
        return 2
    bag = (args.data_dir or default_real_data_dir()) / DEMO_BAG
    if not bag.exists():
        print(f"legmodel_urg: error: no {DEMO_BAG} in {bag.parent}", file=sys.stderr)
        return 2
    try:
        model = load_leg_model(args.model)
    except ModelError as exc:
        print(f"legmodel_urg: error: {exc}", file=sys.stderr)
        return 2
    out = report(transient_segments(bag, args.every), model)
    print(json.dumps(out, indent=None if args.json else 2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
