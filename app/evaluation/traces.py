"""Per-cycle data of an evaluation run in a neutral form, for figures drawn by any plotting module.

``RunLog.traces()`` (:mod:`app.evaluation.metrics`) builds one :class:`RunTrace` per method from what
the runner recorded; this module knows nothing of the runner and draws nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: laser ranges at or beyond this are no return (the UTM-30LX's maximum range)
MAX_RANGE_M = 30.0


@dataclass(frozen=True)
class TrackPoint:
    """An estimated obstacle in the world frame."""

    id: int
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    radius_m: float


@dataclass(frozen=True)
class CycleTrace:
    """One estimator cycle: estimated and true pose, the scan placed with the estimated pose, obstacles."""

    stamp_s: float
    pose_est: tuple[float, float, float]  # (x_m, y_m, theta_rad)
    pose_true: tuple[float, float, float] | None
    scan_xy_m: np.ndarray  # (N, 2) valid scan endpoints, world frame, placed with pose_est
    obstacles_est: tuple[TrackPoint, ...]
    obstacles_true: tuple[tuple[float, float, float], ...]  # (x_m, y_m, radius_m)
    #: (M, 2) endpoints of the beams the method cut out (restored), world frame
    cut_xy_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    #: per true obstacle: scored this cycle by the evaluation's table (moving, in the camera's view, hit
    #: by the laser); empty when unknown
    in_view: tuple[bool, ...] = ()


@dataclass(frozen=True)
class RunTrace:
    """A method's run over a scenario: its cycles and the room's walls ((x0, y0), (x1, y1))."""

    label: str
    cycles: tuple[CycleTrace, ...]
    walls_xy_m: tuple[tuple[tuple[float, float], tuple[float, float]], ...]


def scan_endpoints_xy(
    ranges_m: np.ndarray, bearings_rad: np.ndarray, pose: tuple[float, float, float], mount: Any
) -> np.ndarray:
    """(N, 2) world-frame endpoints of the valid beams (finite, positive, below ``MAX_RANGE_M``)."""
    x, y, th = pose
    lx = x + math.cos(th) * mount.laser_x_m - math.sin(th) * mount.laser_y_m
    ly = y + math.sin(th) * mount.laser_x_m + math.cos(th) * mount.laser_y_m
    r = np.asarray(ranges_m, dtype=float)
    ok = np.isfinite(r) & (r > 0.0) & (r < MAX_RANGE_M)
    a = th + mount.laser_theta_rad + np.asarray(bearings_rad, dtype=float)[ok]
    return np.column_stack((lx + r[ok] * np.cos(a), ly + r[ok] * np.sin(a)))


def split_cut(ranges_m: np.ndarray, restored: Any) -> tuple[np.ndarray, np.ndarray]:
    """(kept, cut) copies of a scan's ranges, NaN where the other one holds the beam; ``restored`` is the
    estimator's ``(start, stop)`` index pairs of the beams it cut out."""
    r = np.asarray(ranges_m, dtype=float)
    cut_mask = np.zeros(r.shape, bool)
    for i0, i1 in restored:
        cut_mask[i0:i1] = True
    return np.where(cut_mask, np.nan, r), np.where(cut_mask, r, np.nan)


def _walls(scenario: Any) -> tuple[tuple[tuple[float, float], tuple[float, float]], ...]:
    return tuple(((w.x0_m, w.y0_m), (w.x1_m, w.y1_m)) for w in scenario.walls)


def method_trace(log: Any, name: str) -> RunTrace:
    """The trace of method ``name`` of a run log; scans are empty arrays when the run kept no scans."""
    m = log.methods[name]
    radii = [o.radius_m for o in log.scenario.obstacles]
    empty = np.zeros((0, 2))
    cycles = []
    for k, stamp_s in enumerate(log.times_s):
        scan, cut = empty, empty
        if k < len(log.scans) and log.bearings_rad is not None:
            kept, removed = split_cut(log.scans[k], m.restored[k] if k < len(m.restored) else ())
            scan = scan_endpoints_xy(kept, log.bearings_rad, m.poses[k], log.mount)
            cut = scan_endpoints_xy(removed, log.bearings_rad, m.poses[k], log.mount)
        true_obs = tuple((float(x), float(y), float(radii[i])) for i, (x, y) in enumerate(log.true_obstacles[k]))
        views = tuple(bool(v) for v in log.in_view[k]) if k < len(log.in_view) else ()
        cycles.append(CycleTrace(float(stamp_s), m.poses[k], log.true_poses[k], scan, tuple(m.tracks[k]), true_obs,
                                 cut, views))
    return RunTrace(name, tuple(cycles), _walls(log.scenario))


def track_point(obstacle: Any) -> TrackPoint:
    """A :class:`TrackPoint` from an estimator's obstacle (``vipsm.types.Obstacle``)."""
    o = obstacle
    return TrackPoint(int(o.track_id), float(o.x_m), float(o.y_m), float(o.vx_mps), float(o.vy_mps), float(o.radius_m))
