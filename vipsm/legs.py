"""A leg detector learned from real scans: segment shape features and a tree ensemble stored as arrays.

Each segment of a scan (:func:`vipsm.bodies.segments`: returns on one surface) that is no wider than
``LegConfig.max_width_m`` gets a feature vector (:func:`features`: the shape features of leg_tracker,
Leigh et al., ICRA 2015 — point count, spread, width, line and circle fit residuals, fitted radius,
boundary length and regularity, curvature, inscribed-angle statistics — and how far it stands in front
of the returns beside it) and a leg probability from a random forest trained on the recorded leg_tracker
scans (``tools/train_legs.py``: labelled leg clusters as positives, the drive through empty rooms as
negatives, and every one of them also as seen from farther, up to 10 m: the labelled legs all lie within
5 m of the laser, ``app.legmodel.reseen_farther``). The forest is shipped as plain arrays in
``vipsm/data/legs_model.npz`` (no pickle, no scikit-learn at run time): every tree's nodes as ``feature``,
``threshold``, ``left``, ``right`` and the leaf's share of legs in ``value``, all trees in one array with
``roots`` giving each tree's first node.
The estimator does no I/O: ``app.legmodel`` reads the file and :func:`model_from_arrays` checks it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

#: the features, in the model's order (the training script writes the same names into the model file)
FEATURE_NAMES = (
    "n_points", "std_m", "mad_median_m", "width_m", "linearity_m", "circularity_m", "radius_m",
    "boundary_length_m", "boundary_regularity_m", "mean_curvature", "mean_angle_rad", "std_angle_rad",
    "front_left_m", "front_right_m", "range_m",
)
#: a neighbour further than this behind the segment (or none) counts as this much: open space
FRONT_CLIP_M = 1.0
#: beams looked at on each side of a segment for the nearest return beside it (``front_*_m``)
FRONT_BEAMS = 4


@dataclass(frozen=True)
class LegConfig:
    #: a segment wider than this (first to last return) is no leg: a trousered shin with a foot at the
    #: laser's height, or two legs touching, is at most ~0.4 m across
    max_width_m: float = 0.4
    #: a segment with fewer returns has no shape (a leg 0.1 m across is 3 beams at 7.6 m on a 0.25 deg scanner)
    min_points: int = 3
    #: leg probability from which a segment is a leg; 0: the operating point the training script chose
    #: out of fold and stored in the model file
    threshold: float = 0.0

    def __post_init__(self) -> None:
        if self.max_width_m <= 0.0 or self.min_points < 3:
            raise ValueError(f"need max_width_m > 0 and min_points >= 3, got {self.max_width_m}, {self.min_points}")
        if not 0.0 <= self.threshold < 1.0:
            raise ValueError(f"threshold must be in [0, 1), got {self.threshold}")


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
        x = np.require(x, np.float64, ("C", "W"))  # one compiled signature for every caller
        leaves = _leaves(x, self.feature, self.threshold, self.left, self.right, self.roots, self.depth)
        return self.value[leaves].mean(axis=1)


def warm_up() -> None:
    """Load the compiled forest walk (see :func:`vipsm.estimator.warm_up`) on a one-leaf forest of the
    types :func:`model_from_arrays` gives."""
    leaf = LegModel(np.array([-1], np.intp), np.zeros(1), np.array([-1], np.intp), np.array([-1], np.intp),
                    np.array([0.5]), np.array([0], np.intp), 1, 0.5)
    leaf.predict(np.zeros((1, len(FEATURE_NAMES))))


@njit(cache=True, nogil=True)
def _leaves(x, feature, threshold, left, right, roots, depth):  # pragma: no cover - compiled
    """The leaf each row of ``x`` reaches in each tree (n, trees), at most ``depth`` steps down (a NaN
    feature goes right: ``x <= threshold`` is false)."""
    out = np.empty((x.shape[0], roots.size), dtype=np.intp)
    for i in range(x.shape[0]):
        for t in range(roots.size):
            node = roots[t]
            for _ in range(depth):
                f = feature[node]
                if f < 0:
                    break
                node = left[node] if x[i, f] <= threshold[node] else right[node]
            out[i, t] = node
    return out


def model_from_arrays(arrays: dict[str, np.ndarray], source: str = "the leg model") -> LegModel:
    """The forest from its arrays (as stored by the training script); :class:`ModelError` when they are
    missing, malformed, or for other features."""
    try:
        names = tuple(str(n) for n in arrays["feature_names"])
        parts = {k: np.asarray(arrays[k]) for k in ("feature", "threshold", "left", "right", "value", "roots")}
        depth, thr = int(arrays["depth"]), float(arrays["threshold_p"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelError(f"{source} is malformed: {exc!r}") from exc
    if names != FEATURE_NAMES:
        raise ModelError(f"{source} was trained on features {names}, not {FEATURE_NAMES}")
    n = parts["feature"].size
    if any(parts[k].size != n for k in ("threshold", "left", "right", "value")) or not 0.0 < thr < 1.0:
        raise ModelError(f"{source} is malformed")
    inner = parts["feature"] >= 0
    kids = np.concatenate([parts["left"][inner], parts["right"][inner], parts["roots"]])
    if kids.size and (kids.min() < 0 or kids.max() >= n):
        raise ModelError(f"{source} has node indices out of range")
    return LegModel(parts["feature"].astype(np.intp), parts["threshold"].astype(np.float64),
                    parts["left"].astype(np.intp), parts["right"].astype(np.intp),
                    parts["value"].astype(np.float64), parts["roots"].astype(np.intp), depth, thr)


def features(points: np.ndarray, front_left_m: float, front_right_m: float) -> np.ndarray:
    """The feature vector (``FEATURE_NAMES``) of a segment's returns ``points`` (k x 2, k >= 3, in scan
    order, in the laser frame: the range is the centroid's distance from the origin) and how far the
    nearest return beside it on each side lies behind its nearest point (``front_*_m``: negative when
    in front, clipped to ``FRONT_CLIP_M``): one segment's row of :func:`segment_features`, which runs the same
    compiled code over a whole scan's segments at once."""
    pts = np.ascontiguousarray(points, dtype=np.float64)
    return _features(pts[:, 0].copy(), pts[:, 1].copy(), float(front_left_m), float(front_right_m))


@njit(cache=True, nogil=True, error_model="numpy")
def _features(px, py, front_l, front_r):  # pragma: no cover - compiled
    k = px.size
    mx, my = px.mean(), py.mean()
    dx, dy = px - mx, py - my
    std = math.sqrt(np.mean(dx * dx + dy * dy))
    medx, medy = np.median(px), np.median(py)
    mad = np.mean(np.sqrt((px - medx) ** 2 + (py - medy) ** 2))
    width = math.hypot(px[-1] - px[0], py[-1] - py[0])
    # rms distance from the best line: the smaller eigenvalue of the scatter matrix
    a, b, c = np.sum(dx * dx), np.sum(dx * dy), np.sum(dy * dy)
    lam = max(0.5 * (a + c) - math.sqrt(0.25 * (a - c) ** 2 + b * b), 0.0)
    linearity = math.sqrt(lam / k)
    radius, circularity = _circle(dx, dy)
    steps = np.sqrt(np.diff(px) ** 2 + np.diff(py) ** 2)
    curv = 0.0
    angles = np.empty(k - 2)
    for i in range(1, k - 1):
        ux, uy = px[i] - px[i - 1], py[i] - py[i - 1]
        vx, vy = px[i + 1] - px[i - 1], py[i + 1] - py[i - 1]
        sides = math.hypot(ux, uy) * math.hypot(px[i + 1] - px[i], py[i + 1] - py[i]) * math.hypot(vx, vy)
        curv += 2.0 * abs(ux * vy - uy * vx) / max(sides, 1e-12)
        # the angle this point makes with the segment's two ends (inscribed: constant on an arc, pi on a line)
        ax, ay = px[0] - px[i], py[0] - py[i]
        bx, by = px[-1] - px[i], py[-1] - py[i]
        angles[i - 1] = abs(math.atan2(ax * by - ay * bx, ax * bx + ay * by))
    out = np.empty(15)
    out[0], out[1], out[2], out[3], out[4] = k, std, mad, width, linearity
    out[5], out[6], out[7], out[8] = circularity, radius, steps.sum(), steps.std()
    out[9], out[10], out[11] = min(curv / (k - 2), 100.0), angles.mean(), angles.std()
    out[12], out[13], out[14] = front_l, front_r, math.hypot(mx, my)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _circle(x, y):  # pragma: no cover - compiled
    """Radius (clipped to 1 m) and rms residual of the algebraic circle fit to centred points (normal
    equations; a line or a degenerate fit: radius 1 m)."""
    m = np.empty((3, 3))
    rhs = np.empty(3)
    cols = (x, y, np.ones(x.size))
    z = -(x * x + y * y)
    for i in range(3):
        rhs[i] = np.sum(cols[i] * z)
        for j in range(3):
            m[i, j] = np.sum(cols[i] * cols[j])
    if abs(np.linalg.det(m)) < 1e-18:
        return 1.0, np.std(np.sqrt(x * x + y * y))
    sol = np.linalg.solve(m, rhs)
    cx, cy = -sol[0] / 2.0, -sol[1] / 2.0
    r2 = cx * cx + cy * cy - sol[2]
    if not r2 > 0.0:
        return 1.0, np.std(np.sqrt(x * x + y * y))
    r = math.sqrt(r2)
    res = math.sqrt(np.mean((np.sqrt((x - cx) ** 2 + (y - cy) ** 2) - r) ** 2))
    return min(r, 1.0), res


def segment_features(r: np.ndarray, b: np.ndarray, spans: list[tuple[int, int]], cfg: LegConfig
                     ) -> tuple[list[tuple[int, int, np.ndarray]], np.ndarray]:
    """The segments ``spans`` that may be legs (enough returns, not too wide) with their returns in the
    laser frame, and their features (n x features). Compiled over all spans at once (a cluttered room
    holds dozens of leg-sized segments): :func:`features` of each, with ``front_*_m`` how far the nearest return
    within ``FRONT_BEAMS`` beams on each side lies behind the segment's nearest return (``FRONT_CLIP_M`` when
    there is none: open space or the scan's edge)."""
    r = np.require(r, np.float64, ("C", "W"))
    finite = np.isfinite(r)
    x, y = r * np.cos(b), r * np.sin(b)
    bounds = np.array(spans, dtype=np.int64).reshape(-1, 2)
    rows, kept_mask = _span_features(x, y, r, finite, bounds, cfg.min_points, cfg.max_width_m)
    kept = []
    for a, z in bounds[kept_mask]:
        beams = a + np.flatnonzero(finite[a:z])
        kept.append((int(a), int(z), np.stack([x[beams], y[beams]], axis=1)))
    return kept, rows[kept_mask]


@njit(cache=True, nogil=True, error_model="numpy")
def _span_features(x, y, r, finite, bounds, min_points, max_width_m):  # pragma: no cover - compiled
    """Per span [a, z) of ``bounds``: its features (:func:`_features` and the two sides) and whether
    it may be a leg (at least ``min_points`` returns, first to last at most ``max_width_m`` apart)."""
    rows = np.zeros((bounds.shape[0], len(FEATURE_NAMES)))
    kept = np.zeros(bounds.shape[0], np.bool_)
    for s in range(bounds.shape[0]):
        a, z = bounds[s, 0], bounds[s, 1]
        idx = np.flatnonzero(finite[a:z]) + a
        if idx.size < min_points:
            continue
        px, py = x[idx], y[idx]
        if math.hypot(px[-1] - px[0], py[-1] - py[0]) > max_width_m:
            continue
        near = np.inf
        for k in range(a, z):
            if r[k] < near:  # NaN compares false
                near = r[k]
        fronts = np.empty(2)
        for side in range(2):
            fronts[side] = FRONT_CLIP_M
            if side == 0:
                lo, hi, step = a - 1, max(a - FRONT_BEAMS, 0) - 1, -1
            else:
                lo, hi, step = z, min(z + FRONT_BEAMS, r.size), 1
            for k in range(lo, hi, step):
                if finite[k]:
                    fronts[side] = min(max(r[k] - near, -FRONT_CLIP_M), FRONT_CLIP_M)
                    break
        rows[s] = _features(px, py, fronts[0], fronts[1])
        kept[s] = True
    return rows, kept
