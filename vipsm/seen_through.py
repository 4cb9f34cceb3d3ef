"""Seen through: did a recent scan's beams pass beyond a point? The free-space test at beam resolution.

The static map (:mod:`vipsm.static_map`) keeps free and occupied evidence in 10 cm cells, coarser
than a table leg (4-5 cm) or a chair leg (2.5 cm). A beam that passes 3 cm beside a thin leg crosses
the leg's cell, so a leg that was hidden behind another one (or never hit) sits in cells the grid
counts as seen free; when the robot's motion uncovers it, it "violates" that free space although it
never moved. At beam resolution the question has a sharp answer: a point was seen free by a past
scan when every beam of that scan passing within ``lateral_tol_m`` of it went at least
``range_margin_m`` beyond it. A leg that was hidden stops those beams at the occluder; a leg that
was seen stops one of them itself; either way it was not seen through. Something that moved into
the beams' path was.

:class:`ScanMemory` keeps the last ``scans`` scans given to it (one per obstacle cycle) with the laser
pose each was taken from, and answers per point: seen through by at least one of them. Bounded:
``scans`` x beams floats; one query costs points x scans x the beams in the lateral window (compiled).
A beam with no return is not evidence of free space (it may be a dropped mixed pixel or a dark
surface), so it makes the point unknown for that scan.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numba import njit

from .types import Pose2D


@dataclass(frozen=True)
class SeenThroughConfig:
    #: past scans kept, one per obstacle cycle (2 s at 0.1 s: a slow body has moved on by then)
    scans: int = 20
    #: a beam this close beside the point could have hit it (the matched pose's error, ~2 cm, plus a
    #: thin leg's half-width and the beam's own footprint)
    lateral_tol_m: float = 0.05
    #: the beam went at least this far beyond the point (UTM-30LX range noise +-3 cm x 3, pose error)
    range_margin_m: float = 0.15


class ScanMemory:
    """The last ``config.scans`` scans (world-frame laser pose, ranges, bearings), oldest first."""

    def __init__(self, config: SeenThroughConfig | None = None) -> None:
        self.config = config or SeenThroughConfig()
        if self.config.scans < 1:
            raise ValueError(f"SeenThroughConfig.scans must be >= 1, got {self.config.scans}")
        self._scans: deque[tuple[Pose2D, np.ndarray, np.ndarray]] = deque(maxlen=self.config.scans)

    def __len__(self) -> int:
        return len(self._scans)

    def push(self, laser: Pose2D, ranges_m: np.ndarray, bearings_rad: np.ndarray) -> None:
        """Keep a scan (copied, in bearing order) taken from ``laser`` (world frame); the oldest falls
        out. A scan without beams is kept too (it saw nothing through)."""
        r = np.array(ranges_m, dtype=np.float64)
        b = np.array(bearings_rad, dtype=np.float64)
        if r.shape != b.shape or r.ndim != 1:
            raise ValueError("ranges and bearings must be 1-D arrays of one length")
        order = np.argsort(b, kind="stable")
        self._scans.append((laser, r[order], b[order]))

    def seen_through(self, points_xy: np.ndarray) -> np.ndarray:
        """Per point (world frame, k x 2): some kept scan's beams all passed beyond it."""
        pts = np.ascontiguousarray(np.asarray(points_xy, dtype=np.float64).reshape(-1, 2))
        out = np.zeros(pts.shape[0], bool)
        c = self.config
        for laser, r, b in self._scans:
            todo = ~out
            if not todo.any():
                break
            out[todo] = _passed_beyond(pts[todo, 0], pts[todo, 1], laser.x_m, laser.y_m, laser.theta_rad, r, b,
                                       c.lateral_tol_m, c.range_margin_m)
        return out


@njit(cache=True, nogil=True, error_model="numpy")
def _passed_beyond(px, py, lx, ly, lth, r, b, lateral_m, margin_m):  # pragma: no cover - compiled
    """Per point: every beam of the scan (bearings ``b`` ascending) whose ray passes within
    ``lateral_m`` of the point returned at least ``margin_m`` beyond it (and there is such a beam)."""
    out = np.zeros(px.size, np.bool_)
    ct, st = math.cos(lth), math.sin(lth)
    for k in range(px.size):
        dx, dy = px[k] - lx, py[k] - ly
        xl, yl = ct * dx + st * dy, -st * dx + ct * dy
        dist = math.hypot(xl, yl)
        if dist <= lateral_m:
            continue  # the point is at the laser: nothing to say
        bearing = math.atan2(yl, xl)
        half = math.asin(lateral_m / dist)
        lo = np.searchsorted(b, bearing - half, side="left")
        hi = np.searchsorted(b, bearing + half, side="right")
        if lo >= hi:
            continue  # outside the scan's field of view, or between two beams: unknown
        ok = True
        for j in range(lo, hi):
            if not (math.isfinite(r[j]) and r[j] >= dist + margin_m):
                ok = False
                break
        out[k] = ok
    return out
