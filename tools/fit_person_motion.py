"""Fit the people filter's leg swing (:class:`vipsm.imm.ImmConfig.leg_swing_s`: how much more a leg's offset
from the body's centre spreads along the line of walking per unit of speed) by maximum likelihood on the
labelled walkers of the recordings; the hip's half-width (the spread across) is the body's, the offset's
correlation time and a detected leg's noise are those of the isotropic fit (docs/estimator.md 6b).

    PYTHONPATH=. python tools/fit_person_motion.py [--data-dir DIR] [--json]

Data: the recordings positive_1-3 (``positive_6`` is held out, as for the leg detector: it is only
scored). Per labelled scan, the labelled person's legs (the closest two labelled legs within
``real_data.PAIR_M``, else the one labelled leg) as the estimator's leg detector finds them: each labelled
leg's nearest detected leg within ``MATCH_M`` (the detector's centre lies a leg's radius behind the returns;
an undetected leg is unseen that scan). The legs keep their identity from scan to scan (the nearer of the
two last places), a person's track starts anew after ``GAP_S`` without a labelled scan, and it is filtered
by :class:`vipsm.imm.Imm` itself (:meth:`~vipsm.imm.Imm.update_legs`). The objective is the sum over the
scans of the predictive log density of the detected legs, each scan's floored at ``FLOOR_NATS`` (a leg
mislabelled or taken from a neighbouring thing counts as one outlier, not as the fit). Nelder-Mead on the
swing's scale, bounded to 0.01-0.4 s (a step of at most 1.2 s swinging the whole leg).

Printed: the fitted values, the log density per scan before and after, and (for information, not fitted
on) the share of each recording's labelled walking scans (> 0.3 m/s) at which the filter's P(walking) is at
least 0.8, with the shipped and with the fitted values.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

from app.evaluation import real_data as rd
from vipsm.imm import Imm, ImmConfig
from vipsm.people import PeopleTracker

FIT = ("positive_1", "positive_2", "positive_3")
HELD_OUT = ("positive_6",)
#: a detected leg this close to a labelled one is that leg (a leg's radius behind the labelled returns, and
#: the labels' own tolerance)
MATCH_M = 0.15
#: a person's track starts anew after this long without a labelled scan
GAP_S = 0.5
FLOOR_NATS = -10.0
KEY = "leg_swing_s"


def detected_people(data: Path, name: str) -> list[tuple[float, list[np.ndarray | None], float | None]]:
    """Per labelled scan of ``name``: (stamp, the person's legs as detected (None: undetected), the labelled
    speed). The estimator runs over the whole recording; its leg detections are read as it passes them to
    the people stage (the laser at rest at the origin: the recordings' frame is the laser's)."""
    rec = next(r for r in rd.RECORDINGS if r.name == name)
    bag = data / rec.bag
    labels = rd.read_labels(bag, data / rec.labels)
    speeds = rd.person_speeds(labels)
    seen: dict[float, list[tuple[float, float]]] = {}
    step = PeopleTracker.step

    def spy(self: PeopleTracker, stamp_s: float, detections: list, *args: object, **kw: object) -> None:
        seen[round(stamp_s, 6)] = [(d.x_m, d.y_m) for d in detections]
        step(self, stamp_s, detections, *args, **kw)

    PeopleTracker.step = spy  # type: ignore[method-assign]
    try:
        rd.run_estimator(bag, rd.scan_topics(bag)[0])
    finally:
        PeopleTracker.step = step  # type: ignore[method-assign]
    out = []
    for (t, legs), v in zip(labels, speeds, strict=True):
        dets = np.array(seen.get(round(t, 6), []), float).reshape(-1, 2)
        person = _person_legs(legs)
        found: list[np.ndarray | None] = []
        for leg in person:
            d = np.hypot(*(dets - leg).T) if dets.size else np.array([])
            found.append(dets[int(np.argmin(d))] if d.size and d.min() <= MATCH_M else None)
        out.append((t, found, v))
    return out


def _person_legs(legs: np.ndarray) -> list[np.ndarray]:
    if len(legs) >= 2:
        d = np.hypot(legs[:, None, 0] - legs[None, :, 0], legs[:, None, 1] - legs[None, :, 1])
        d[np.tril_indices(len(legs))] = np.inf
        i, j = np.unravel_index(int(np.argmin(d)), d.shape)
        if d[i, j] <= rd.PAIR_M:
            return [legs[i], legs[j]]
    return [legs[0]]


def replay(scans: list[tuple[float, list[np.ndarray | None], float | None]], cfg: ImmConfig
           ) -> tuple[float, int, int, int]:
    """(sum of the floored log densities, scans updated, walking scans, walking scans at P(walking) >= 0.8)."""
    filt: Imm | None = None
    prev = -math.inf
    last: list[np.ndarray | None] = [None, None]
    total, n, walking, sure = 0.0, 0, 0, 0
    for t, found, v in scans:
        legs = [leg for leg in found if leg is not None]
        if filt is not None and t - prev <= GAP_S:
            filt.predict(t - prev)
            if legs:
                first, second = _identify(legs, last)
                filt.update_legs(first, second, cfg.leg_noise_m, cfg.leg_noise_m, cfg.leg_noise_m)
                total += max(filt.log_density, FLOOR_NATS)
                n += 1
        elif legs:
            offset = (0.5 * (legs[0][0] - legs[1][0]), 0.5 * (legs[0][1] - legs[1][1])) if len(legs) == 2 else None
            centre = np.mean(legs, axis=0)
            filt = Imm(float(centre[0]), float(centre[1]), cfg.leg_noise_m, cfg, offset)
            last = [legs[0], legs[1] if len(legs) == 2 else None]
        else:
            continue
        prev = t
        if rd.speed_class(v) == "walking":
            walking += 1
            sure += filt.p_moving >= 0.8
    return total, n, walking, sure


def _identify(legs: list[np.ndarray], last: list[np.ndarray | None]) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The legs seen as (first, second), by the nearer of their last places; ``last`` is updated."""
    a, b = last
    if len(legs) == 2:
        swap = b is not None and a is not None and (
            np.hypot(*(legs[0] - b)) + np.hypot(*(legs[1] - a)) < np.hypot(*(legs[0] - a)) + np.hypot(*(legs[1] - b)))
        first, second = (legs[1], legs[0]) if swap else (legs[0], legs[1])
    elif a is None or (b is not None and np.hypot(*(legs[0] - b)) < np.hypot(*(legs[0] - a))):
        first, second = None, legs[0]
    else:
        first, second = legs[0], None
    last[0] = first if first is not None else last[0]
    last[1] = second if second is not None else last[1]
    return first, second


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data-dir", type=Path, default=Path("../shared/data/real_people_laser"))
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    data = {name: detected_people(args.data_dir, name) for name in FIT + HELD_OUT}
    base = ImmConfig()

    def cfg_of(x: float) -> ImmConfig:
        return replace(base, **{KEY: float(x)})

    def cost(x: float) -> float:
        cfg = cfg_of(x)
        runs = [replay(data[name], cfg) for name in FIT]
        return -sum(r[0] for r in runs) / sum(r[1] for r in runs)

    res = minimize_scalar(cost, bounds=(0.01, 0.4), method="bounded", options={"xatol": 0.005})
    fitted = cfg_of(res.x)

    def shares(cfg: ImmConfig) -> dict[str, float]:
        return {name: round(r[3] / max(r[2], 1), 3) for name in data for r in [replay(data[name], cfg)]}

    out = {"fitted": {KEY: round(getattr(fitted, KEY), 4)},
           "log_density_per_scan": {"shipped": round(-cost(getattr(base, KEY)), 4), "fitted": round(-float(res.fun), 4),
                                    "no_swing": round(-cost(0.01), 4)},
           "p_walking_0.8_share": {"shipped": shares(base), "fitted": shares(fitted)},
           "fit": list(FIT), "held_out": list(HELD_OUT)}
    print(json.dumps(out, indent=2) if args.json else out)


if __name__ == "__main__":
    main()
