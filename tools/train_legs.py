"""Train the leg detector (:mod:`vipsm.legs`) on the recorded leg_tracker scans and store it as arrays.

    PYTHONPATH=. python tools/train_legs.py [--data-dir DIR] [--out vipsm/data/legs_model.npz] [--json]
                                            [--baseline OTHER.npz] [--held-out positive_N --out FILE]

(needs scikit-learn, which neither the estimator nor the app imports: the model is stored as arrays)

Samples: every segment of a scan (pre-filtered and segmented as the estimator does) that
:func:`vipsm.legs.segment_features` keeps. Positives: in the labelled scans of ``positive_N_extracted``,
segments whose centroid lies within ``app.legmodel.LABEL_M`` of a labelled leg cluster (a segment holding two
labelled legs, the legs touching, is a positive too). Negatives: every segment of the drive through
empty rooms (``negative_2``, three lasers, nobody present). Other segments of a labelled scan are not
used (a second person passes in some recordings, unlabelled).

Farther than labelled: every labelled leg lies within 5 m of the laser (the labelling stopped there), so
each sample, leg or not alike, is also trained on as seen from ``COPIES`` longer ranges up to
``FAR_RANGE_M`` (:func:`app.legmodel.reseen_farther`: the segment and the scene beside it moved away along
its bearing, cast again with beams at the recording's or the UTM-30LX's step, with the range noise of the
new range); a copy stays in its original's fold and set.

Before a wall: the recordings' laser saw most legs before open space, the robot's UTM-30LX in a room sees
them before a wall, with a mixed pixel or a pulled return at most such depth edges. So each sample, leg or
not alike, is also trained on as standing ``WALL_DEPTH_M`` before a wall (uniform depth, turned up to
``WALL_SLANT_RAD``) with the UTM-30LX's depth edges at their recorded rates (:func:`app.legmodel.before_wall`:
this project's own model of those edges, measured on the recorded UTM-30LX, not the simulated world's):
``WALL_COPIES`` copies, at its recorded range and step, and re-seen farther at the UTM-30LX's step. A copy
that is no leg candidate there (merged with the wall, too few returns left) is dropped.

As a URG-04LX-class scanner reports it: the demo recording's scanner (and the class of cheap phase-shift
scanners it stands for) reports one range over neighbouring steps on one surface and no echo on the beams
whose footprint straddles a depth edge, so its legs at 3-5 m are 3-5 returns of one range, flat, not the
curved 4-6 returns the recordings' laser gives there. With ``--urg-copies N`` (default ``URG_COPIES``, 0:
measured, not kept) each sample, leg or not alike, is also trained on N times as such a scanner reports it
(:class:`app.legmodel.Reporting`, drawn per copy over the class: its holds and edge losses from none to all,
its range error up to its data sheet's), re-seen at its step from a range between the segment's own and its
longest (``URG04LX_MAX_RANGE_M``). The demo recording is never trained on (it has no labels). The held-out
sets are always validated as that class reports them (``validation.by_range.urg04lx_class``).

Split (honest validation): ``HELD_OUT`` is never trained on, and of the drive only the first half (by
time) is; the held-out recording's positives with the drive's second half are the validation set.
``--held-out`` holds another labelled recording out instead (written to ``--out``, never the packaged file):
the leave-one-recording-out models that ``eval --data real --leg-model`` scores each recording with, so that
every recording has a figure from a detector that never saw it. The
classifier is a random forest (scikit-learn, balanced class weights); the operating point is the
probability at which out-of-fold estimates (one trained recording, with a third of the drive's first
half, left out per fold) pass ``TARGET_FPR`` of the recorded non-legs. The validation is reported per
range band, for the held-out sets as recorded, re-seen farther and before a wall (``--baseline``: another model file's
figures beside them). The
forest is written as plain arrays (no pickle), so the run time needs neither scikit-learn nor a version
of it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from app.bagread import BagTopics, read_bag
from app.cmd_eval import default_real_data_dir
from app.evaluation.real_data import DRIVE_BAG, DRIVE_TOPICS, LABEL_M, read_labels, scan_topics
from app.legmodel import (
    URG04LX_MAX_RANGE_M,
    URG04LX_STEP_RAD,
    Reporting,
    Wall,
    default_model_path,
    leg_candidates,
    load_leg_model,
    prefiltered,
    reseen_farther,
    walled_features,
)
from vipsm.legs import FEATURE_NAMES, LegModel, ModelError

LABELLED = ("positive_1", "positive_2", "positive_3", "positive_6")
HELD_OUT = "positive_6"
#: the operating point: the share of non-leg segments (out of fold) taken for legs. The tracker's
#: existence probability absorbs single false legs; a lower rate loses legs (recall 0.7 -> 0.5 at 0.05)
TARGET_FPR = 0.10
TREES = 60
DEPTH = 14
SEED = 29
#: every real segment, leg or not, is also trained on as seen from this many longer ranges (the labelled
#: legs all lie within 5 m of the laser: the labelling stopped there, not the laser)
COPIES = 4
#: the re-seen ranges are drawn uniformly from the segment's own range to this: the range noise is
#: measured to 10 m (docs/simulation.md), and a 0.15 m leg gives the UTM-30LX 3 beams out to 11 m
FAR_RANGE_M = 10.0
#: the re-seen beams' spacing alternates between the recording's own and the robot's UTM-30LX's
UTM30LX_STEP_RAD = float(np.radians(0.25))
#: every real segment, leg or not, is also trained on before a wall this many times (the first at its recorded
#: range and step, the others re-seen farther at the UTM-30LX's step)
WALL_COPIES = 2
#: the wall's depth behind the segment's nearest return, uniform (m): from a leg at a wall to twice the
#: UTM-30LX's echo separation (its mixed pixels stop beyond about 1.1 m, its pulled returns do not)
WALL_DEPTH_M = (0.05, 2.0)
#: the wall turned from square to the beam by up to this, uniform (rad)
WALL_SLANT_RAD = float(np.radians(60.0))
#: with ``--urg-copies N``, every real segment, leg or not, is also trained on as a URG-04LX-class scanner
#: reports it N times (:class:`app.legmodel.Reporting`: at its step, from the segment's range to its longest,
#: with its range error, held ranges and lost edge beams drawn over the class). Measured and not kept (0, the
#: default; docs/estimator.md stage 1): with 1 or 2 the held-out recording's recall at the drive's 10 %
#: fell 0.63 -> 0.61 and the realistic people figures on the 768-beam recordings fell, for +0.1 on the class
URG_COPIES = 0
#: the held-out sets are always validated as the URG-04LX class reports them, this many copies each
URG_VALIDATION_COPIES = 2
#: the range bands of the validation tables (m)
BANDS_M = (0.0, 2.0, 3.5, 5.0, 6.5, 8.0, 10.0, np.inf)


def export_forest(forest: Any, threshold_p: float) -> dict[str, np.ndarray]:
    """A fitted ``RandomForestClassifier`` as the arrays :func:`vipsm.legs.model_from_arrays` takes."""
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("feature", "threshold", "left", "right", "value")}
    roots, offset, depth = [], 0, 0
    for est in forest.estimators_:
        t = est.tree_
        leaf = t.children_left < 0
        parts["feature"].append(np.where(leaf, -1, t.feature).astype(np.int16))
        parts["threshold"].append(t.threshold.astype(np.float64))
        parts["left"].append(np.where(leaf, -1, t.children_left + offset).astype(np.int32))
        parts["right"].append(np.where(leaf, -1, t.children_right + offset).astype(np.int32))
        counts = t.value[:, 0, :]
        parts["value"].append((counts[:, 1] / np.maximum(counts.sum(axis=1), 1e-12)).astype(np.float64))
        roots.append(offset)
        offset += t.node_count
        depth = max(depth, int(t.max_depth))
    out = {k: np.concatenate(v) for k, v in parts.items()}
    out.update(roots=np.array(roots, np.int32), depth=np.array(depth), threshold_p=np.array(threshold_p),
               feature_names=np.array(FEATURE_NAMES))
    return out


def figures(p_pos: np.ndarray, p_neg: np.ndarray, thr: float) -> dict[str, Any]:
    return {"positives": int(p_pos.size), "negatives": int(p_neg.size),
            "recall": round(float(np.mean(p_pos >= thr)), 4) if p_pos.size else None,
            "false_positive_rate": round(float(np.mean(p_neg >= thr)), 5) if p_neg.size else None}


def _forest() -> Any:
    from sklearn.ensemble import RandomForestClassifier

    return RandomForestClassifier(n_estimators=TREES, max_depth=DEPTH, min_samples_leaf=3,
                                  class_weight="balanced_subsample", random_state=SEED, n_jobs=1)


def _sklearn_version() -> str:
    import sklearn

    return str(sklearn.__version__)


def operating_point(x: np.ndarray, y: np.ndarray, groups: np.ndarray, recorded: np.ndarray
                    ) -> tuple[float, np.ndarray]:
    """The leg probability at which forests trained on the other groups pass ``TARGET_FPR`` of the
    recorded negatives (not the re-seen copies) of the group left out (out-of-fold, over all folds), and
    those out-of-fold probabilities."""
    p = np.zeros(y.size)
    for g in np.unique(groups):
        held = groups == g
        p[held] = _forest().fit(x[~held], y[~held]).predict_proba(x[held])[:, 1]
    return float(np.quantile(p[(y == 0) & recorded], 1.0 - TARGET_FPR)), p


class Samples:
    """Leg-candidate segments of pre-filtered scans: each sample is (scan index, (start, stop)), with its
    features; ``scans`` holds (ranges, bearings) once per scan. (A plain class: the tests load this
    script from its path, where a dataclass cannot find its module.)"""

    def __init__(self) -> None:
        self.scans: list[tuple[np.ndarray, np.ndarray]] = []
        self.spans: list[tuple[int, tuple[int, int]]] = []
        self.rows: list[np.ndarray] = []

    def add_scan(self, r: np.ndarray, b: np.ndarray, keep: Any = None) -> None:
        """The scan's candidate segments (those ``keep(points)`` accepts, default all)."""
        kept, x = leg_candidates(r, b)
        chosen = [(a, z, row) for (a, z, pts), row in zip(kept, x, strict=True) if keep is None or keep(pts)]
        if chosen:
            self.scans.append((prefiltered(r, b)[0], b))
            for a, z, row in chosen:
                self.spans.append((len(self.scans) - 1, (a, z)))
                self.rows.append(row)

    def matrix(self) -> np.ndarray:
        return np.array(self.rows).reshape(-1, len(FEATURE_NAMES))


def labelled_samples(data: Path, name: str) -> Samples:
    """The labelled leg segments of ``name`` (as ``app.evaluation.real_data.labelled_leg_rows``: centroid
    within ``LABEL_M`` of a labelled leg), with their scans."""
    bag = data / f"{name}.bag"
    labels = {round(t, 6): legs for t, legs in read_labels(bag, data / f"{name}_extracted.bag")}
    out = Samples()
    for bc in read_bag(bag, BagTopics(scan_topics(bag)[0])):
        legs = labels.get(round(bc.scan.stamp_s, 6))
        if legs is not None:
            out.add_scan(bc.scan.ranges_m, bc.scan.bearings_rad,
                         lambda pts, legs=legs: bool(np.min(np.hypot(*(legs - pts.mean(axis=0)).T)) <= LABEL_M))
    return out


def drive_samples(data: Path) -> tuple[Samples, Samples]:
    """Every candidate segment of the drive (nobody present), (first half, second half) by time on each
    laser (as ``app.evaluation.real_data.drive_leg_rows``)."""
    first, second = Samples(), Samples()
    for topic in DRIVE_TOPICS:
        scans = [(bc.scan.stamp_s, bc.scan.ranges_m, bc.scan.bearings_rad)
                 for bc in read_bag(data / DRIVE_BAG, BagTopics(topic))]
        mid = 0.5 * (scans[0][0] + scans[-1][0])
        for t, r, b in scans:
            (first if t < mid else second).add_scan(r, b)
    return first, second


def farther(samples: Samples, copies: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Each sample re-seen from ``copies`` longer ranges (:func:`app.legmodel.reseen_farther`), the beam
    spacing alternating between the recording's and the UTM-30LX's; the features and, per row, the index
    of the sample it came from. A copy that is no leg candidate any more (too few returns) is dropped."""
    rows, src = [], []
    for i, (scan, span) in enumerate(samples.spans):
        r, b = samples.scans[scan]
        own = float(abs(b[-1] - b[0]) / max(b.size - 1, 1))
        r0 = float(samples.rows[i][FEATURE_NAMES.index("range_m")])
        for c in range(copies):
            step = own if c % 2 == 0 else UTM30LX_STEP_RAD
            # never sampled finer across the surface than the recording sampled it
            lo = max(r0, r0 * own / step)
            if lo >= FAR_RANGE_M:
                continue
            row = reseen_farther(r, b, span, float(rng.uniform(lo, FAR_RANGE_M)), step, rng)
            if row is not None:
                rows.append(row)
                src.append(i)
    return np.array(rows).reshape(-1, len(FEATURE_NAMES)), np.array(src, dtype=np.intp)


def urg_class(samples: Samples, copies: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Each sample re-seen ``copies`` times as a URG-04LX-class scanner (drawn per copy,
    :meth:`app.legmodel.Reporting.drawn`) reports it, from a range drawn between the segment's own and the
    scanner's longest, at its step (never finer across the surface than recorded); the features and, per
    row, the index of the sample it came from (a copy that is no leg candidate there is dropped)."""
    rows, src = [], []
    for i, (scan, span) in enumerate(samples.spans):
        r, b = samples.scans[scan]
        own = float(abs(b[-1] - b[0]) / max(b.size - 1, 1))
        r0 = float(samples.rows[i][FEATURE_NAMES.index("range_m")])
        lo = max(r0, r0 * own / URG04LX_STEP_RAD)
        if lo >= URG04LX_MAX_RANGE_M:
            continue
        for _ in range(copies):
            row = reseen_farther(r, b, span, float(rng.uniform(lo, URG04LX_MAX_RANGE_M)), URG04LX_STEP_RAD, rng,
                                 reporting=Reporting.drawn(rng))
            if row is not None:
                rows.append(row)
                src.append(i)
    return np.array(rows).reshape(-1, len(FEATURE_NAMES)), np.array(src, dtype=np.intp)


def random_wall(rng: np.random.Generator) -> Wall:
    return Wall(float(rng.uniform(*WALL_DEPTH_M)), float(rng.uniform(-WALL_SLANT_RAD, WALL_SLANT_RAD)))


def walled(samples: Samples, copies: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Each sample before ``copies`` random walls (:func:`app.legmodel.before_wall`): the first at its
    recorded range and step, the others re-seen farther (up to ``FAR_RANGE_M``) at the UTM-30LX's step;
    the features and, per row, the index of the sample it came from (a copy that is no leg candidate
    there is dropped)."""
    rows, src = [], []
    for i, (scan, span) in enumerate(samples.spans):
        r, b = samples.scans[scan]
        a, z = span
        k = a + np.flatnonzero(np.isfinite(r[a:z]))
        target = np.array([np.mean(r[k] * np.cos(b[k])), np.mean(r[k] * np.sin(b[k]))])
        own = float(abs(b[-1] - b[0]) / max(b.size - 1, 1))
        r0 = float(np.hypot(*target))
        for c in range(copies):
            lo = max(r0, r0 * own / UTM30LX_STEP_RAD)
            if c == 0:
                row = walled_features(r, b, target, random_wall(rng), rng)
            elif lo < FAR_RANGE_M:
                row = reseen_farther(r, b, span, float(rng.uniform(lo, FAR_RANGE_M)), UTM30LX_STEP_RAD, rng,
                                     random_wall(rng))
            else:
                continue
            if row is not None:
                rows.append(row)
                src.append(i)
    return np.array(rows).reshape(-1, len(FEATURE_NAMES)), np.array(src, dtype=np.intp)


def banded(p: np.ndarray, x: np.ndarray, thr: float) -> dict[str, Any]:
    """The share of rows at or above ``thr`` per range band (``BANDS_M``), with the rows' count."""
    rng_m = x[:, FEATURE_NAMES.index("range_m")]
    out = {}
    for lo, hi in zip(BANDS_M[:-1], BANDS_M[1:], strict=True):
        sel = (rng_m >= lo) & (rng_m < hi)
        out[f"{lo:g}-{hi:g}"] = {"n": int(sel.sum()),
                                 "share": round(float(np.mean(p[sel] >= thr)), 4) if sel.any() else None}
    return out


def validation(model: LegModel, held_out: str, held: tuple[np.ndarray, np.ndarray],
               held_far: tuple[np.ndarray, np.ndarray],
               held_wall: tuple[np.ndarray, np.ndarray] | None = None,
               held_urg: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, Any]:
    """Per range band: recall on the held-out recording's legs, false-positive rate on the drive's
    second half; as recorded, each re-seen from farther (the only legs beyond 5 m there are), with
    ``held_wall`` each before a wall with the UTM-30LX's depth edges, and with ``held_urg`` each as a
    URG-04LX-class scanner reports it."""
    thr = model.threshold_p
    sets = {"recorded": held, "reseen_farther": held_far}
    if held_wall is not None:
        sets["before_wall"] = held_wall
    if held_urg is not None:
        sets["urg04lx_class"] = held_urg
    return {name: {"recall_" + held_out: banded(model.predict(pos), pos, thr),
                   "false_positive_rate_drive_second_half": banded(model.predict(neg), neg, thr)}
            for name, (pos, neg) in sets.items()}


def train(data: Path, out: Path, baseline: tuple[Path, LegModel] | None = None, urg_copies: int = URG_COPIES,
          held_out: str = HELD_OUT) -> dict[str, Any]:
    """Train, store the forest at ``out`` and report; ``baseline``: (path, model) validated beside it;
    ``urg_copies``: URG-04LX-class copies of each sample trained on (:func:`urg_class`); ``held_out``: the
    labelled recording never trained on (another than ``HELD_OUT`` for a leave-one-recording-out model)."""
    rng = np.random.default_rng(SEED)
    pos = {name: labelled_samples(data, name) for name in LABELLED}
    drive_train, drive_val = drive_samples(data)
    trained = [n for n in LABELLED if n != held_out]
    parts = [pos[n] for n in trained] + [drive_train]
    labels = [1.0] * len(trained) + [0.0]
    xs, ys, gs, real = [], [], [], []
    n_walled = n_urg = 0
    for k, (smp, lab) in enumerate(zip(parts, labels, strict=True)):
        x0 = smp.matrix()
        xf, src = farther(smp, COPIES, rng)
        xw, srcw = walled(smp, WALL_COPIES, rng)
        xu, srcu = urg_class(smp, urg_copies, rng)
        n_walled += len(xw)
        n_urg += len(xu)
        xf, src = np.concatenate([xf, xw, xu]), np.concatenate([src, srcw, srcu])
        # folds: each trained recording's positives with a third of the drive's first half (in time order
        # per laser, so about one laser each); a re-seen copy stays in its original's fold
        g0 = (np.full(len(x0), k) if lab else np.arange(len(x0)) * len(trained) // max(len(x0), 1))
        xs += [x0, xf]
        ys += [np.full(len(x0) + len(xf), lab)]
        gs += [g0, g0[src]]
        real += [np.ones(len(x0), bool), np.zeros(len(xf), bool)]
    x, y, groups, real_rows = np.concatenate(xs), np.concatenate(ys), np.concatenate(gs), np.concatenate(real)
    # scikit-learn's trees compare in float32: train on float32 values so that the exported arrays, which
    # compare in float64, split every training row as scikit-learn did
    x = x.astype(np.float32).astype(np.float64)
    thr, oof = operating_point(x, y, groups, real_rows)
    forest = _forest().fit(x, y)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out, **export_forest(forest, thr))
    model: LegModel = load_leg_model(out)
    if not np.allclose(model.predict(x), forest.predict_proba(x)[:, 1], atol=1e-9):
        raise RuntimeError("the exported forest does not reproduce scikit-learn's probabilities")
    vrng = np.random.default_rng(SEED + 1)
    held = (pos[held_out].matrix(), drive_val.matrix())
    held_far = (farther(pos[held_out], COPIES, vrng)[0], farther(drive_val, COPIES, vrng)[0])
    held_wall = (walled(pos[held_out], WALL_COPIES, vrng)[0], walled(drive_val, WALL_COPIES, vrng)[0])
    held_urg = (urg_class(pos[held_out], URG_VALIDATION_COPIES, vrng)[0],
                urg_class(drive_val, URG_VALIDATION_COPIES, vrng)[0])
    p_held, p_val = model.predict(held[0]), model.predict(held[1])
    report = {
        "model": str(out), "trees": len(forest.estimators_), "depth": model.depth, "nodes": int(model.feature.size),
        # the forest grown from the same samples differs between scikit-learn releases (docs/real_data.md)
        "scikit_learn": _sklearn_version(), "numpy": np.__version__,
        "threshold_p": round(thr, 4), "held_out": held_out, "drive_split": "first half trained, second half held out",
        "reseen_copies": COPIES, "reseen_up_to_m": FAR_RANGE_M, "wall_copies": WALL_COPIES,
        "wall_depth_m": list(WALL_DEPTH_M),
        "urg_copies": urg_copies,
        "training_rows": {"recorded": int(real_rows.sum()),
                          "reseen_farther": int((~real_rows).sum()) - n_walled - n_urg,
                          "before_wall": n_walled, "urg04lx_class": n_urg},
        "training_out_of_fold": figures(oof[(y == 1) & real_rows], oof[(y == 0) & real_rows], thr),
        "validation": {"held_out_recording_positives": figures(p_held, np.zeros(0), thr),
                       "drive_second_half_negatives": figures(np.zeros(0), p_val, thr),
                       "recall_at_drive_fpr": {f"{f:g}": round(float(np.mean(p_held > np.quantile(p_val, 1 - f))), 3)
                                               for f in (0.02, 0.05, 0.1, 0.2)},
                       "by_range": validation(model, held_out, held, held_far, held_wall, held_urg)},
        "positives_per_recording": {n: len(pos[n].rows) for n in LABELLED},
        "feature_importance": {n: round(float(v), 4) for n, v in zip(FEATURE_NAMES, forest.feature_importances_,
                                                                       strict=True)},
    }
    if baseline is not None:
        report["baseline"] = {"model": str(baseline[0]),
                              "by_range": validation(baseline[1], held_out, held, held_far, held_wall, held_urg)}
    return report


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="tools/train_legs.py", description=__doc__.split("\n")[0])
    ap.add_argument("--data-dir", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=None,
                    help="the model file to write (default: the packaged one, vipsm/data/legs_model.npz)")
    ap.add_argument("--held-out", choices=LABELLED, default=HELD_OUT,
                    help="the labelled recording never trained on (default %(default)s, the packaged model's); "
                    "another one needs --out (a leave-one-recording-out model, for eval --data real --leg-model)")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--urg-copies", type=int, default=URG_COPIES,
                    help="URG-04LX-class copies of each sample to train on (default %(default)s: measured, not kept)")
    ap.add_argument("--baseline", type=Path, default=None,
                    help="another model file, validated beside the new one (the before/after table)")
    args = ap.parse_args(argv)
    if args.urg_copies < 0:
        print(f"train_legs: error: --urg-copies must be >= 0, got {args.urg_copies}", file=sys.stderr)
        return 2
    if args.held_out != HELD_OUT and args.out is None:
        print(f"train_legs: error: --held-out {args.held_out} needs --out (the packaged model holds {HELD_OUT} out)",
              file=sys.stderr)
        return 2
    try:  # before the training: a bad file fails at once, not after it
        baseline = (args.baseline, load_leg_model(args.baseline)) if args.baseline is not None else None
    except ModelError as exc:
        print(f"train_legs: error: --baseline: {exc}", file=sys.stderr)
        return 2
    data = args.data_dir or default_real_data_dir()
    if not (data / DRIVE_BAG).exists():
        print(f"train_legs: error: no recordings in {data}", file=sys.stderr)
        return 2
    report = train(data, args.out or default_model_path(), baseline, args.urg_copies, args.held_out)
    print(json.dumps(report, indent=None if args.json else 2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
