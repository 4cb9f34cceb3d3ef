"""A leg detector learned from real scans: segment shape features and a tree ensemble stored as arrays.

Each segment of a scan (:func:`vipsm.bodies.segments`: returns on one surface) that is no wider than
``LegConfig.max_width_m`` gets a feature vector (:func:`features`: the shape features of leg_tracker,
Leigh et al., ICRA 2015 — point count, spread, width, line and circle fit residuals, fitted radius,
boundary length and regularity, curvature, inscribed-angle statistics — and how far it stands in front
of the returns beside it) and a leg probability from a random forest trained on the recorded leg_tracker
scans (``app/evaluation/train_legs.py``: labelled leg clusters as positives, the drive through empty rooms
as negatives). The forest is shipped as plain arrays in ``vipsm/data/legs_model.npz`` (no pickle, no
scikit-learn at run time): every tree's nodes as ``feature``, ``threshold``, ``left``, ``right`` and the
leaf's share of legs in ``value``, all trees in one array with ``roots`` giving each tree's first node.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

#: the features, in the model's order (the training script writes the same names into the model file)
FEATURE_NAMES = (
    "n_points", "std_m", "mad_median_m", "width_m", "linearity_m", "circularity_m", "radius_m",
    "boundary_length_m", "boundary_regularity_m", "mean_curvature", "mean_angle_rad", "std_angle_rad",
    "front_left_m", "front_right_m", "range_m",
)
#: a neighbour further than this behind the segment (or none) counts as this much: open space
FRONT_CLIP_M = 1.0


@dataclass(frozen=True)
class LegConfig:
    #: a segment wider than this (first to last return) is no leg: a trousered shin with a foot at the
    #: laser's height, or two legs touching, is at most ~0.4 m across
    max_width_m: float = 0.4
    #: a segment with fewer returns has no shape (a leg 0.1 m across is 3 beams at 7.6 m on a 0.25 deg scanner)
    min_points: int = 3
    #: leg probability from which a segment is a leg (the operating point chosen on held-out data by the
    #: training script, stored in the model file; NaN: that stored value)
    threshold: float = math.nan

    def __post_init__(self) -> None:
        if self.max_width_m <= 0.0 or self.min_points < 3:
            raise ValueError(f"need max_width_m > 0 and min_points >= 3, got {self.max_width_m}, {self.min_points}")
        if not (math.isnan(self.threshold) or 0.0 < self.threshold < 1.0):
            raise ValueError(f"threshold must be in (0, 1) or NaN, got {self.threshold}")


class ModelError(ValueError):
    """The leg model file is missing, malformed or for other features."""


@dataclass(frozen=True)
class LegModel:
    feature: np.ndarray  # int (nodes,): feature tested at the node; -1 at a leaf
    threshold: np.ndarray  # float (nodes,): go left when feature <= threshold
    left: np.ndarray  # int (nodes,)
    right: np.ndarray  # int (nodes,)
    value: np.ndarray  # float (nodes,): share of legs among the training samples at the leaf
    roots: np.ndarray  # int (trees,)
    depth: int
    threshold_p: float  # the operating point stored with the model

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Leg probability (mean of the trees' leaf shares) of each row of ``x`` (n, features)."""
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != len(FEATURE_NAMES):
            raise ValueError(f"need (n, {len(FEATURE_NAMES)}) features, got {x.shape}")
        if x.shape[0] == 0:
            return np.zeros(0)
        node = np.broadcast_to(self.roots, (x.shape[0], self.roots.size)).copy()
        rows = np.arange(x.shape[0])[:, None]
        for _ in range(self.depth):
            f = self.feature[node]
            leaf = f < 0
            go_left = x[rows, np.where(leaf, 0, f)] <= self.threshold[node]
            node = np.where(leaf, node, np.where(go_left, self.left[node], self.right[node]))
        return self.value[node].mean(axis=1)


def default_model_path() -> Path:
    return Path(str(resources.files("vipsm") / "data" / "legs_model.npz"))


def load_model(path: Path | None = None) -> LegModel:
    """The forest from ``path`` (default: the packaged model); :class:`ModelError` when unusable."""
    path = path or default_model_path()
    try:
        with np.load(path, allow_pickle=False) as z:
            names = tuple(str(n) for n in z["feature_names"])
            arrays = {k: z[k] for k in ("feature", "threshold", "left", "right", "value", "roots")}
            depth, thr = int(z["depth"]), float(z["threshold_p"])
    except (OSError, KeyError, ValueError) as exc:
        raise ModelError(f"cannot read the leg model {path}: {exc}") from exc
    if names != FEATURE_NAMES:
        raise ModelError(f"the leg model {path} was trained on features {names}, not {FEATURE_NAMES}")
    n = arrays["feature"].size
    if any(arrays[k].size != n for k in ("threshold", "left", "right", "value")) or not 0.0 < thr < 1.0:
        raise ModelError(f"the leg model {path} is malformed")
    inner = arrays["feature"] >= 0
    kids = np.concatenate([arrays["left"][inner], arrays["right"][inner], arrays["roots"]])
    if kids.size and (kids.min() < 0 or kids.max() >= n):
        raise ModelError(f"the leg model {path} has node indices out of range")
    return LegModel(arrays["feature"].astype(np.intp), arrays["threshold"].astype(np.float64),
                    arrays["left"].astype(np.intp), arrays["right"].astype(np.intp),
                    arrays["value"].astype(np.float64), arrays["roots"].astype(np.intp), depth, thr)


def features(points: np.ndarray, front_left_m: float, front_right_m: float) -> np.ndarray:
    """The feature vector (``FEATURE_NAMES``) of a segment's returns ``points`` (k x 2, k >= 3, in scan
    order, in the laser frame: the range is the centroid's distance from the origin) and how far the
    nearest return beside it on each side lies behind its nearest point (``front_*_m``: negative when
    in front, clipped to ``FRONT_CLIP_M``)."""
    k = points.shape[0]
    c = points.mean(axis=0)
    d = points - c
    std = float(np.sqrt(np.mean(np.sum(d * d, axis=1))))
    med = np.median(points, axis=0)
    mad = float(np.mean(np.hypot(*(points - med).T)))
    width = float(np.hypot(*(points[-1] - points[0])))
    _, sv, _ = np.linalg.svd(d, full_matrices=False)
    linearity = float(sv[-1] / math.sqrt(k))  # rms distance from the best line
    radius, circularity = _circle(points)
    steps = np.hypot(*np.diff(points, axis=0).T)
    curvature, ang_mean, ang_std = _angles(points)
    return np.array([k, std, mad, width, linearity, circularity, radius, float(steps.sum()), float(steps.std()),
                     curvature, ang_mean, ang_std, front_left_m, front_right_m, float(np.hypot(*c))])


def _circle(points: np.ndarray) -> tuple[float, float]:
    """Radius (clipped to 1 m) and rms residual of the algebraic circle fit (a line: radius 1 m)."""
    x, y = points[:, 0] - points[:, 0].mean(), points[:, 1] - points[:, 1].mean()
    a = np.stack([x, y, np.ones_like(x)], axis=1)
    sol, _, rank, _ = np.linalg.lstsq(a, -(x * x + y * y), rcond=None)
    cx, cy = -sol[0] / 2.0, -sol[1] / 2.0
    r2 = cx * cx + cy * cy - sol[2]
    if rank < 3 or not r2 > 0.0:
        return 1.0, float(np.std(np.hypot(x, y)))
    r = math.sqrt(r2)
    res = float(np.sqrt(np.mean((np.hypot(x - cx, y - cy) - r) ** 2)))
    return min(r, 1.0), res


def _angles(points: np.ndarray) -> tuple[float, float, float]:
    """Mean curvature of consecutive triples (4 area / product of sides) and the mean and spread of
    the angles each interior point makes with the segment's two ends (inscribed angles: constant on an
    arc, pi on a line)."""
    p0, p1, p2 = points[:-2], points[1:-1], points[2:]
    a = np.hypot(*(p1 - p0).T)
    b = np.hypot(*(p2 - p1).T)
    cc = np.hypot(*(p2 - p0).T)
    cross = np.abs((p1 - p0)[:, 0] * (p2 - p0)[:, 1] - (p1 - p0)[:, 1] * (p2 - p0)[:, 0])
    curvature = float(np.mean(2.0 * cross / np.maximum(a * b * cc, 1e-12)))
    u = points[0] - p1
    v = points[-1] - p1
    ang = np.arctan2(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0], np.sum(u * v, axis=1))
    ang = np.abs(ang)
    return min(curvature, 100.0), float(ang.mean()), float(ang.std())


def front_of(r: np.ndarray, a: int, z: int, beams: int = 4) -> tuple[float, float]:
    """How far the nearest return within ``beams`` beams on each side of the segment [a, z) lies behind
    the segment's nearest return (``FRONT_CLIP_M`` when there is none: open space or the scan's edge)."""
    near = float(np.nanmin(r[a:z]))
    out = []
    for idx in (np.arange(a - 1, max(a - beams, 0) - 1, -1), np.arange(z, min(z + beams, r.size))):
        finite = idx[np.isfinite(r[idx])]
        out.append(FRONT_CLIP_M if not finite.size else float(np.clip(r[finite[0]] - near, -FRONT_CLIP_M,
                                                                      FRONT_CLIP_M)))
    return out[0], out[1]


@dataclass(frozen=True)
class LegCandidate:
    start: int
    stop: int  # exclusive
    points: np.ndarray  # world frame, the segment's returns
    x_m: float  # the leg's centre (world frame): the returns' centroid pushed back along the ray
    y_m: float
    p_leg: float


def segment_features(r: np.ndarray, b: np.ndarray, spans: list[tuple[int, int]], cfg: LegConfig
                     ) -> tuple[list[tuple[int, int, np.ndarray]], np.ndarray]:
    """The segments ``spans`` that may be legs (enough returns, not too wide) with their returns in the
    laser frame, and their features (n x features)."""
    kept, rows = [], []
    for a, z in spans:
        beams = a + np.flatnonzero(np.isfinite(r[a:z]))
        if beams.size < cfg.min_points:
            continue
        pts = np.stack([r[beams] * np.cos(b[beams]), r[beams] * np.sin(b[beams])], axis=1)
        if float(np.hypot(*(pts[-1] - pts[0]))) > cfg.max_width_m:
            continue
        kept.append((a, z, pts))
        rows.append(features(pts, *front_of(r, a, z)))
    return kept, np.array(rows).reshape(-1, len(FEATURE_NAMES))
