"""Static evidence: what the laser has recently seen free and seen occupied, in the estimator's frame.

A bounded, short-lived grid (``size_m`` square around the robot, re-centred as it drives; cells of
``cell_m``) holds two decaying counts per cell: how often a beam passed through it (free) and how
often a beam ended in it (occupied). Both decay with time constant ``memory_s``, so the map forgets a
person's trail and a moved chair within seconds.

The question it answers (:meth:`FreeSpaceGrid.violates`): does a point lie where the laser recently
saw free floor, in its cell and all 8 neighbours, with no occupied evidence there? A static object never
does (a face first seen at grazing incidence has free-marked cells in front of it, but the cells behind
it were never crossed):
its cells are occupied and the cells in front of it are only marked free up to ``free_margin_m``
short of each return (the matched pose is good to centimetres, the cells are 10 cm). Something that
moved into seen-free space does: that is the free-space violation that makes a segment a moving-body
candidate. Unknown space (never seen, or occluded) is never a violation: a body that appears from
behind furniture becomes a candidate only once it moves into space the laser has seen free.

Cost: per scan one free-space ray march of the valid beams up to ``max_free_range_m`` at half-cell
steps (~100 k points, compiled: well under a millisecond) and one decay of the grid; memory is fixed
by ``size_m``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit


@dataclass(frozen=True)
class StaticMapConfig:
    cell_m: float = 0.10
    size_m: float = 24.0
    max_free_range_m: float = 8.0
    #: free marking stops this short of every return (pose error + range noise + the cell size)
    free_margin_m: float = 0.25
    #: no free marking closer than this to the laser (the robot's own body, the laser's dead zone)
    min_free_range_m: float = 0.15
    memory_s: float = 6.0
    #: a cell is "seen free" with at least this much (decayed) free evidence ...
    min_free: float = 1.5
    #: ... and "clear" with at most this much occupied evidence in its 3x3 neighbourhood
    max_occupied: float = 0.5


class FreeSpaceGrid:
    def __init__(self, config: StaticMapConfig | None = None) -> None:
        self.config = config or StaticMapConfig()
        c = self.config
        self.n = int(math.ceil(c.size_m / c.cell_m))
        self.free = np.zeros((self.n, self.n), np.float32)
        self.occ = np.zeros((self.n, self.n), np.float32)
        self.last_free = np.zeros((self.n, self.n), bool)  # cells a beam crossed in the last scan
        # when a scan last ended a beam in each cell / last crossed it without ending one there (-inf: never)
        self.occ_s = np.full((self.n, self.n), -np.inf)
        self.free_s = np.full((self.n, self.n), -np.inf)
        self.origin = np.zeros(2)  # world position of cell (0, 0)'s corner
        self.stamp_s: float | None = None

    # ---------------------------------------------------------------- cells
    def _cells(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ij = np.floor((xy - self.origin) / self.config.cell_m).astype(np.int64)
        inside = (ij[:, 0] >= 0) & (ij[:, 0] < self.n) & (ij[:, 1] >= 0) & (ij[:, 1] < self.n)
        return ij[:, 0], ij[:, 1], inside

    def _recentre(self, x_m: float, y_m: float) -> None:
        """Keep the robot near the middle: shift the grid by whole cells when it has moved a quarter away."""
        half = self.n * self.config.cell_m / 2
        centre = self.origin + half
        if self.stamp_s is not None and max(abs(x_m - centre[0]), abs(y_m - centre[1])) < half / 2:
            return
        new_origin = np.floor((np.array([x_m, y_m]) - half) / self.config.cell_m) * self.config.cell_m
        shift = np.round((new_origin - self.origin) / self.config.cell_m).astype(int)
        self.origin = new_origin
        for name in ("free", "occ", "last_free"):
            self.__dict__[name] = _shifted(self.__dict__[name], int(shift[0]), int(shift[1]))
        for name in ("occ_s", "free_s"):
            self.__dict__[name] = _shifted(self.__dict__[name], int(shift[0]), int(shift[1]), -np.inf)

    # ---------------------------------------------------------------- queries
    def violates(self, points_xy: np.ndarray) -> np.ndarray:
        """Per point: inside cells recently seen free with no occupied evidence around (before the
        current scan is integrated)."""
        c = self.config
        if points_xy.size == 0:
            return np.zeros(0, bool)
        pts = np.require(np.asarray(points_xy, np.float64).reshape(-1, 2), np.float64, ("C", "W"))  # one signature
        return _violates(pts, self.origin[0], self.origin[1], c.cell_m, self.occ, self.free, np.float32(c.min_free),
                         np.float32(c.max_occupied))

    def occupied(self, points_xy: np.ndarray) -> np.ndarray:
        """Per point: the (decayed) count of scans that ended a beam in its cell (before the current
        scan is integrated); 0 outside the grid."""
        i, j, inside = self._cells(np.asarray(points_xy, float).reshape(-1, 2))
        out = np.zeros(inside.size, np.float32)
        out[inside] = self.occ[i[inside], j[inside]]
        return out

    def held(self, points_xy: np.ndarray) -> np.ndarray:
        """Per point: something stood in its cell when the laser last saw the cell (before the current scan
        is integrated): the last scan that saw it ended a beam there rather than passing through, and the
        (decayed) occupied count is above what the grid calls clear (``max_occupied``: seen more than once
        or lately). A body that has moved away since leaves its cell seen free; outside the grid: False."""
        i, j, inside = self._cells(np.asarray(points_xy, float).reshape(-1, 2))
        out = np.zeros(inside.size, bool)
        ii, jj = i[inside], j[inside]
        out[inside] = (self.occ_s[ii, jj] > self.free_s[ii, jj]) & (self.occ[ii, jj] > self.config.max_occupied)
        return out

    def occupied_cells_around(self, x_m: float, y_m: float, inner_m: float, outer_m: float,
                              min_occupied: float) -> np.ndarray:
        """(k, 2) centres of the cells with at least ``min_occupied`` (decayed) occupancy whose centre
        lies between ``inner_m`` and ``outer_m`` from (x, y)."""
        c = self.config
        k = int(math.ceil(outer_m / c.cell_m)) + 1
        i0 = int(math.floor((x_m - self.origin[0]) / c.cell_m))
        j0 = int(math.floor((y_m - self.origin[1]) / c.cell_m))
        return _ring_cells(self.occ, float(self.origin[0]), float(self.origin[1]), c.cell_m, i0, j0, k, float(x_m),
                           float(y_m), float(inner_m), float(outer_m), np.float32(min_occupied))

    def seen_free_now(self, x_m: float, y_m: float) -> bool:
        """Whether a beam of the last integrated scan crossed the cell of (x, y)."""
        i, j, inside = self._cells(np.array([[x_m, y_m]]))
        return bool(inside[0] and self.last_free[i[0], j[0]])

    # ---------------------------------------------------------------- update
    def integrate(self, stamp_s: float, laser_xy: tuple[float, float], laser_theta_rad: float,
                  ranges_m: np.ndarray, bearings_rad: np.ndarray, skip: np.ndarray | None = None) -> None:
        """Decay, then add one scan taken from the laser pose (world frame). Beams flagged in ``skip``
        (the tracked moving bodies) mark free space up to them but no occupancy."""
        c = self.config
        self._recentre(*laser_xy)
        k = 1.0 if self.stamp_s is None else math.exp(-max(stamp_s - self.stamp_s, 0.0) / c.memory_s)
        self.stamp_s = stamp_s
        r = np.require(ranges_m, np.float64, ("C", "W"))  # one compiled signature for every caller
        ang = laser_theta_rad + np.asarray(bearings_rad, float)
        hit = np.isfinite(r) if skip is None else np.isfinite(r) & ~np.asarray(skip, bool)
        steps = np.arange(c.min_free_range_m, c.max_free_range_m, c.cell_m / 2)
        occ_now = np.zeros((self.n, self.n), bool)
        crossed = np.zeros((self.n, self.n), bool)
        _mark(laser_xy[0], laser_xy[1], r, ang, hit, steps, c.free_margin_m, c.max_free_range_m, self.origin[0],
              self.origin[1], c.cell_m, occ_now, crossed)
        _add_scan(self.free, self.occ, self.occ_s, self.free_s, occ_now, crossed, np.float32(k), stamp_s)
        self.last_free = crossed


@njit(cache=True, nogil=True)
def _add_scan(free, occ, occ_s, free_s, occ_now, crossed, decay, stamp_s):  # pragma: no cover - compiled
    """Decays the counts by ``decay`` (float32) and adds this scan's ends (``occ_now``) and crossings; a
    return in a cell outweighs the beams that passed beside it in the stamps of when each was seen."""
    one = np.float32(1.0)
    for i in range(occ.shape[0]):
        for j in range(occ.shape[1]):
            free[i, j] *= decay
            occ[i, j] *= decay
            if crossed[i, j]:
                free[i, j] += one
            if occ_now[i, j]:
                occ[i, j] += one
                occ_s[i, j] = stamp_s
            elif crossed[i, j]:
                free_s[i, j] = stamp_s


@njit(cache=True, nogil=True)
def _ring_cells(occ, x0, y0, cell_m, i0, j0, k, x, y, inner_m, outer_m, min_occupied):  # pragma: no cover
    """Centres (m, 2) of the grid cells within ``k`` cells of (i0, j0), in row order, whose centre lies in
    (``inner_m``, ``outer_m``] from (x, y) and whose occupancy reaches ``min_occupied`` (float32, as the grid
    holds it)."""
    n0, n1 = occ.shape
    out = np.empty(((2 * k + 1) ** 2, 2))
    m = 0
    for i in range(i0 - k, i0 + k + 1):
        for j in range(j0 - k, j0 + k + 1):
            cx, cy = x0 + (i + 0.5) * cell_m, y0 + (j + 0.5) * cell_m
            d = math.hypot(cx - x, cy - y)
            if inner_m < d <= outer_m and 0 <= i < n0 and 0 <= j < n1 and occ[i, j] >= min_occupied:
                out[m, 0], out[m, 1] = cx, cy
                m += 1
    return out[:m].copy()


@njit(cache=True, nogil=True)
def _violates(pts, x0, y0, cell_m, occ, free, min_free, max_occupied):  # pragma: no cover - compiled
    """Per point: its cell (clamped 3x3 neighbourhood) has at least ``min_free`` free and at most
    ``max_occupied`` occupied evidence; False outside the grid."""
    n0, n1 = occ.shape
    out = np.zeros(pts.shape[0], np.bool_)
    for p in range(pts.shape[0]):
        fi, fj = (pts[p, 0] - x0) / cell_m, (pts[p, 1] - y0) / cell_m
        if not (0.0 <= fi < n0 and 0.0 <= fj < n1):  # outside the grid, or no point (NaN)
            continue
        i, j = int(fi), int(fj)  # the floor, as both are >= 0
        lo_free, hi_occ = np.float32(np.inf), np.float32(0.0)
        for a in range(max(i - 1, 0), min(i + 1, n0 - 1) + 1):
            for b in range(max(j - 1, 0), min(j + 1, n1 - 1) + 1):
                lo_free = min(lo_free, free[a, b])
                hi_occ = max(hi_occ, occ[a, b])
        out[p] = lo_free >= min_free and hi_occ <= max_occupied
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _mark(ox, oy, r, ang, hit, steps, margin_m, max_free_m, x0, y0, cell_m, occ, crossed):  # pragma: no cover
    """Per beam with a return: its end cell in ``occ`` (unless not ``hit``: a tracked moving body) and
    the cells of the points at ``steps`` along it short of ``margin_m`` before the return (and of
    ``max_free_m``) in ``crossed``. Points outside the grid are left out."""
    n0, n1 = occ.shape
    for b in range(r.size):
        if not math.isfinite(r[b]):
            continue
        ca, sa = math.cos(ang[b]), math.sin(ang[b])
        if hit[b]:
            _set_cell(ox + r[b] * ca, oy + r[b] * sa, x0, y0, cell_m, n0, n1, occ)
        reach = min(r[b] - margin_m, max_free_m)
        for k in range(steps.size):
            d = steps[k]
            if not d < reach:
                break
            _set_cell(ox + d * ca, oy + d * sa, x0, y0, cell_m, n0, n1, crossed)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _set_cell(x, y, x0, y0, cell_m, n0, n1, grid):  # pragma: no cover - compiled
    i = math.floor((x - x0) / cell_m)
    j = math.floor((y - y0) / cell_m)
    if 0 <= i < n0 and 0 <= j < n1:
        grid[i, j] = True


def _shifted(a: np.ndarray, di: int, dj: int, fill: float = 0.0) -> np.ndarray:
    """``a`` re-indexed so that new[i, j] = old[i + di, j + dj]; cells from outside hold ``fill``."""
    out = np.full_like(a, fill)
    n0, n1 = a.shape
    src_i = slice(max(di, 0), min(n0, n0 + di))
    dst_i = slice(max(-di, 0), min(n0, n0 - di))
    src_j = slice(max(dj, 0), min(n1, n1 + dj))
    dst_j = slice(max(-dj, 0), min(n1, n1 - dj))
    if src_i.start < src_i.stop and src_j.start < src_j.stop:
        out[dst_i, dst_j] = a[src_i, src_j]
    return out
