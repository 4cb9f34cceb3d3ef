"""Real recorded pedestrian paths (ETH/UCY, ``../shared/data/pedestrian_trajectories/``), read in place.

File format (PROVENANCE.md there): comma-separated, 4 rows, one column per sample: frame number,
pedestrian id, x (m), y (m) in the scene's ground plane. ``frame_rate_hz`` converts frames to seconds
(eth_hotel: 15 frames/s; ucy_zara01: 2.5 frames/s, not stated upstream). Not yet wired into the
scenarios: people there still walk scripted polylines.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: where the shared data set lives (read in place, never copied into the repository)
PEDESTRIAN_DATA_DIR = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "pedestrian_trajectories"
#: frames per second of the files shipped in ``../shared/data/pedestrian_trajectories/`` (PROVENANCE.md)
FRAME_RATE_HZ: dict[str, float] = {"eth_hotel.csv": 15.0, "ucy_zara01.csv": 2.5}


class TrajectoryFileError(ValueError):
    """A trajectory file that is missing, malformed or holds no usable pedestrian."""


@dataclass(frozen=True)
class RecordedPath:
    """One pedestrian's samples: times from their first sample (s) and ground-plane positions (m)."""

    ped_id: int
    t_s: np.ndarray
    xy_m: np.ndarray

    def length_m(self) -> float:
        return float(np.sum(np.hypot(*np.diff(self.xy_m, axis=0).T)))

    def mean_speed_mps(self) -> float:
        dur_s = float(self.t_s[-1] - self.t_s[0])
        return self.length_m() / dur_s if dur_s > 0 else 0.0


def _read_rows(path: Path) -> np.ndarray:
    try:
        rows = np.loadtxt(path, delimiter=",", dtype=float, ndmin=2)
    except (OSError, ValueError) as exc:
        raise TrajectoryFileError(f"{path}: cannot read trajectory file: {exc}") from exc
    if rows.shape[0] != 4 or not np.all(np.isfinite(rows)):
        raise TrajectoryFileError(f"{path}: expected 4 finite rows (frame, id, x, y), got shape {rows.shape}")
    return rows


def load_paths(path: str | Path, frame_rate_hz: float | None = None, min_samples: int = 2) -> dict[int, RecordedPath]:
    """Every pedestrian of ``path`` with at least ``min_samples`` samples, keyed by id, time-ordered."""
    p = Path(path)
    rate = FRAME_RATE_HZ.get(p.name) if frame_rate_hz is None else frame_rate_hz
    if rate is None or not rate > 0:
        raise TrajectoryFileError(f"{p}: frame rate unknown or not positive ({rate!r}); pass frame_rate_hz")
    frame, ids, x, y = _read_rows(p)
    out: dict[int, RecordedPath] = {}
    for pid in np.unique(ids):
        sel = np.flatnonzero(ids == pid)
        order = sel[np.argsort(frame[sel], kind="stable")]
        if order.size < min_samples:
            continue
        t_s = (frame[order] - frame[order[0]]) / rate
        out[int(pid)] = RecordedPath(int(pid), t_s, np.column_stack([x[order], y[order]]))
    if not out:
        raise TrajectoryFileError(f"{p}: no pedestrian with at least {min_samples} samples")
    return out


def fitted_waypoints(
    rec: RecordedPath, start_xy: tuple[float, float], end_xy: tuple[float, float], max_points: int = 200
) -> tuple[tuple[float, float], ...]:
    """``rec``'s shape (:func:`smoothed`) rotated and uniformly scaled so it runs from ``start_xy`` to
    ``end_xy`` (its curves and detours keep their proportions), thinned to at most ``max_points`` waypoints."""
    pts = smoothed(rec.xy_m, annotation_stride(rec.xy_m))
    pts = pts - pts[0]
    chord = pts[-1]
    chord_m = float(np.hypot(*chord))
    if chord_m < 0.5:
        raise TrajectoryFileError(f"pedestrian {rec.ped_id} ends {chord_m:.2f} m from where it starts (< 0.5 m)")
    target = np.asarray(end_xy, float) - np.asarray(start_xy, float)
    k = float(np.hypot(*target)) / chord_m
    rot = np.arctan2(target[1], target[0]) - np.arctan2(chord[1], chord[0])
    c, s = np.cos(rot), np.sin(rot)
    out = k * (pts @ np.array([[c, s], [-s, c]])) + np.asarray(start_xy, float)
    idx = np.unique(np.linspace(0, len(out) - 1, min(len(out), max(2, max_points))).round().astype(int))
    return tuple((float(x), float(y)) for x, y in out[idx])


def annotation_stride(xy_m: np.ndarray) -> int:
    """Samples per annotation: a file whose annotations were linearly interpolated to its frame rate
    (eth_hotel: one every 10 frames) repeats the same step between frames for a stride; the median length
    of the runs of equal steps (1: every sample is an annotation)."""
    steps = np.diff(np.asarray(xy_m, float), axis=0)
    if len(steps) < 2:
        return 1
    same = np.hypot(*np.diff(steps, axis=0).T) < 5e-4  # interpolation: rounding only (0.1 mm)
    runs, n = [], 1
    for eq in same:
        if eq:
            n += 1
        else:
            runs.append(n)
            n = 1
    runs.append(n)
    return max(1, int(np.median(runs)))


def smoothed(xy_m: np.ndarray, stride: int, spacing_m: float = 0.05) -> np.ndarray:
    """The path through every ``stride``-th sample (the annotations, and the last sample) as a natural cubic
    spline of the distance along them, sampled every ``spacing_m`` and at each annotation. Linear
    interpolation between annotations turns the walker's heading by 10-15 deg at every annotation, a
    velocity no walking body has (a pelvis turns smoothly); the spline keeps the annotated positions."""
    xy = np.asarray(xy_m, float)
    knots = xy[::max(stride, 1)]
    if not np.allclose(knots[-1], xy[-1]):
        knots = np.vstack([knots, xy[-1]])
    seg = np.hypot(*np.diff(knots, axis=0).T)
    knots = np.vstack([knots[:1], knots[1:][seg > 1e-9]])
    if len(knots) < 3:
        return knots
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(knots, axis=0).T))])
    at = np.union1d(s, np.arange(0.0, s[-1], spacing_m))
    return _natural_spline(s, knots, at)


def _natural_spline(s: np.ndarray, y: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The natural cubic spline through (``s``, ``y``) (``y``: (n, d), ``s`` increasing) at ``at``: the
    second derivatives M from the tridiagonal system h[i-1] M[i-1] + 2 (h[i-1] + h[i]) M[i] + h[i] M[i+1] =
    6 (slope[i] - slope[i-1]), M zero at both ends."""
    h = np.diff(s)
    slope = np.diff(y, axis=0) / h[:, None]
    n = len(s)
    a = np.zeros((n - 2, n - 2))
    i = np.arange(n - 2)
    a[i, i] = 2.0 * (h[:-1] + h[1:])
    a[i[1:], i[1:] - 1] = h[1:-1]
    a[i[:-1], i[:-1] + 1] = h[1:-1]
    m = np.zeros_like(y)
    m[1:-1] = np.linalg.solve(a, 6.0 * np.diff(slope, axis=0))
    k = np.clip(np.searchsorted(s, at, side="right") - 1, 0, n - 2)
    hk, left, right = h[k][:, None], (at - s[k])[:, None], (s[k + 1] - at)[:, None]
    return (m[k] * right**3 + m[k + 1] * left**3) / (6.0 * hk) + (y[k] / hk - m[k] * hk / 6.0) * right \
        + (y[k + 1] / hk - m[k + 1] * hk / 6.0) * left
