"""The learned leg detector's model file (``vipsm/data/legs_model.npz``, written by ``tools/train_legs.py``)
read for the estimator, which does no I/O itself (:func:`vipsm.legs.model_from_arrays` checks it), and the
detector's samples outside the estimator: the leg-candidate segments of a scan and the labelled legs of a
recorded leg_tracker bag (for training, ``tools/train_legs.py``, and the world's check,
:mod:`app.evaluation.leg_realism`)."""

from __future__ import annotations

import functools
from importlib import resources
from pathlib import Path

import numpy as np

from vipsm.bodies import BodiesConfig, segments
from vipsm.legs import FEATURE_NAMES, LegConfig, LegModel, ModelError, model_from_arrays, segment_features
from vipsm.prefilter import PrefilterConfig, veiling_masks

#: a segment's centroid this close to a labelled leg cluster's position is that leg (the label is the
#: centroid of leg_tracker's own cluster of the same returns, so they agree to a few centimetres)
LABEL_M = 0.12
#: the drive through empty rooms (nobody present: every segment is a non-leg) and its three lasers
DRIVE_BAG = "negative_2.bag"
DRIVE_TOPICS = ("/left_scan", "/rear_scan", "/right_scan")


def default_model_path() -> Path:
    return Path(str(resources.files("vipsm") / "data" / "legs_model.npz"))


def load_leg_model(path: str | Path | None = None) -> LegModel:
    """The forest stored at ``path`` (default: the packaged model), read without pickle;
    :class:`vipsm.legs.ModelError` when the file is missing or unusable."""
    path = Path(path) if path is not None else default_model_path()
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise ModelError(f"cannot read the leg model {path}: {exc}") from exc
    return model_from_arrays(arrays, f"the leg model {path}")


@functools.lru_cache(maxsize=1)
def default_leg_model() -> LegModel:
    """The packaged model, read once per process (it is immutable)."""
    return load_leg_model()


def leg_candidates(r: np.ndarray, b: np.ndarray) -> tuple[list[tuple[int, int, np.ndarray]], np.ndarray]:
    """The leg-candidate segments of one scan (start, stop, points) and their features, pre-filtered and
    segmented as the estimator does."""
    mixed, lone = veiling_masks(r, b, PrefilterConfig())
    dropped = mixed | lone
    rr = np.where(dropped, np.nan, r)
    return segment_features(rr, b, segments(rr, b, BodiesConfig(), dropped), LegConfig())


def labelled_leg_rows(data: Path, name: str) -> np.ndarray:
    """Features of the labelled leg segments of the recording ``name`` (``name.bag`` with its labels in
    ``name_extracted.bag``): segments whose centroid lies within ``LABEL_M`` of a labelled leg (a segment
    holding two labelled legs, the legs touching, is one too)."""
    from app.bagread import BagTopics, read_bag
    from app.evaluation.real_data import read_labels, scan_topics

    bag = data / f"{name}.bag"
    labels = {round(t, 6): legs for t, legs in read_labels(bag, data / f"{name}_extracted.bag")}
    rows = []
    for bc in read_bag(bag, BagTopics(scan_topics(bag)[0])):
        legs = labels.get(round(bc.scan.stamp_s, 6))
        if legs is None:
            continue
        kept, x = leg_candidates(bc.scan.ranges_m, bc.scan.bearings_rad)
        for (_, _, pts), row in zip(kept, x, strict=True):
            c = pts.mean(axis=0)
            if np.min(np.hypot(legs[:, 0] - c[0], legs[:, 1] - c[1])) <= LABEL_M:
                rows.append(row)
    return np.array(rows).reshape(-1, len(FEATURE_NAMES))


def drive_leg_rows(data: Path) -> tuple[np.ndarray, np.ndarray]:
    """Features of every candidate segment of the drive (nobody present), (first half, second half) by
    time on each laser: training takes the first, validation the second."""
    from app.bagread import BagTopics, read_bag

    first, second = [], []
    for topic in DRIVE_TOPICS:
        scans = [(bc.scan.stamp_s, bc.scan.ranges_m, bc.scan.bearings_rad)
                 for bc in read_bag(data / DRIVE_BAG, BagTopics(topic))]
        mid = 0.5 * (scans[0][0] + scans[-1][0])
        for t, r, b in scans:
            (first if t < mid else second).append(leg_candidates(r, b)[1])
    width = len(FEATURE_NAMES)
    return (np.concatenate(first).reshape(-1, width) if first else np.zeros((0, width)),
            np.concatenate(second).reshape(-1, width) if second else np.zeros((0, width)))
