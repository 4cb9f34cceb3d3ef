"""Train the leg detector (:mod:`vipsm.legs`) on the recorded leg_tracker scans and store it as arrays.

    PYTHONPATH=. python tools/train_legs.py [--data-dir DIR] [--out vipsm/data/legs_model.npz] [--json]

(needs scikit-learn, which neither the estimator nor the app imports: the model is stored as arrays)

Samples: every segment of a scan (pre-filtered and segmented as the estimator does) that
:func:`vipsm.legs.segment_features` keeps. Positives: in the labelled scans of ``positive_N_extracted``,
segments whose centroid lies within ``app.legmodel.LABEL_M`` of a labelled leg cluster (a segment holding two
labelled legs, the legs touching, is a positive too). Negatives: every segment of the drive through
empty rooms (``negative_2``, three lasers, nobody present). Other segments of a labelled scan are not
used (a second person passes in some recordings, unlabelled).

Split (honest validation): ``HELD_OUT`` is never trained on, and of the drive only the first half (by
time) is; the held-out recording's positives with the drive's second half are the validation set. The
classifier is a random forest (scikit-learn, balanced class weights); the operating point is the
probability at which out-of-fold estimates (one trained recording, with a third of the drive's first
half, left out per fold) pass ``TARGET_FPR`` of the non-legs. The
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

from app.cmd_eval import default_real_data_dir
from app.evaluation.real_data import DRIVE_BAG, drive_leg_rows, labelled_leg_rows
from app.legmodel import default_model_path, load_leg_model
from vipsm.legs import FEATURE_NAMES, LegModel

LABELLED = ("positive_1", "positive_2", "positive_3", "positive_6")
HELD_OUT = "positive_6"
#: the operating point: the share of non-leg segments (out of fold) taken for legs. The tracker's
#: existence probability absorbs single false legs; a lower rate loses legs (recall 0.7 -> 0.5 at 0.05)
TARGET_FPR = 0.10
TREES = 60
DEPTH = 14
SEED = 29


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


def operating_point(x: np.ndarray, y: np.ndarray, groups: np.ndarray) -> tuple[float, np.ndarray]:
    """The leg probability at which forests trained on the other groups pass ``TARGET_FPR`` of the
    negatives of the group left out (out-of-fold, over all folds), and those out-of-fold probabilities."""
    p = np.zeros(y.size)
    for g in np.unique(groups):
        held = groups == g
        p[held] = _forest().fit(x[~held], y[~held]).predict_proba(x[held])[:, 1]
    return float(np.quantile(p[y == 0], 1.0 - TARGET_FPR)), p


def train(data: Path, out: Path) -> dict[str, Any]:
    pos = {name: labelled_leg_rows(data, name) for name in LABELLED}
    neg_train, neg_val = drive_leg_rows(data)
    trained = [n for n in LABELLED if n != HELD_OUT]
    x = np.concatenate([pos[n] for n in trained] + [neg_train])
    y = np.concatenate([np.ones(sum(len(pos[n]) for n in trained)), np.zeros(len(neg_train))])
    # folds: each trained recording's positives with a third of the drive's first half (in time order
    # per laser, so about one laser each)
    groups = np.concatenate([np.full(len(pos[n]), i) for i, n in enumerate(trained)]
                            + [np.arange(len(neg_train)) * len(trained) // len(neg_train)])
    thr, oof = operating_point(x, y, groups)
    forest = _forest().fit(x, y)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out, **export_forest(forest, thr))
    model: LegModel = load_leg_model(out)
    if not np.allclose(model.predict(x), forest.predict_proba(x)[:, 1], atol=1e-9):
        raise RuntimeError("the exported forest does not reproduce scikit-learn's probabilities")
    p_held, p_val = model.predict(pos[HELD_OUT]), model.predict(neg_val)
    return {
        "model": str(out), "trees": len(forest.estimators_), "depth": model.depth, "nodes": int(model.feature.size),
        "threshold_p": round(thr, 4), "held_out": HELD_OUT, "drive_split": "first half trained, second half held out",
        "training_out_of_fold": figures(oof[y == 1], oof[y == 0], thr),
        "validation": {"held_out_recording_positives": figures(p_held, np.zeros(0), thr),
                       "drive_second_half_negatives": figures(np.zeros(0), p_val, thr),
                       "recall_at_drive_fpr": {f"{f:g}": round(float(np.mean(p_held > np.quantile(p_val, 1 - f))), 3)
                                               for f in (0.02, 0.05, 0.1, 0.2)}},
        "positives_per_recording": {n: int(len(pos[n])) for n in LABELLED},
        "feature_importance": {n: round(float(v), 4) for n, v in zip(FEATURE_NAMES, forest.feature_importances_,
                                                                       strict=True)},
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="tools/train_legs.py", description=__doc__.split("\n")[0])
    ap.add_argument("--data-dir", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=default_model_path())
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    data = args.data_dir or default_real_data_dir()
    if not (data / DRIVE_BAG).exists():
        print(f"train_legs: error: no recordings in {data}", file=sys.stderr)
        return 2
    report = train(data, args.out)
    print(json.dumps(report, indent=None if args.json else 2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
