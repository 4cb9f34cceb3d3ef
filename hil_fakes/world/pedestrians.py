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
