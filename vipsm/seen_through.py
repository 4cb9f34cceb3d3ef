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

**The pose's uncertainty.** The points asked about are placed with the current matched pose, the kept scans
with theirs. A heading error between the two moves a return at range r sideways by r times it: a beam that
passed that close beside the point is no evidence (the point may be the edge of the very surface that beam
passed); so does a position error. The lateral window is
``lateral_tol_m + max(sigma_gate * hypot(r * sigma_rel, sigma_pos) - pose_tol_m, 0)`` (``lateral_tol_m``
already holds ``pose_tol_m`` for the matched pose's error) with the two scans' relative heading uncertainty
``sigma_rel^2 = s_now^2 + s_kept^2 + heading_sigma_rad^2 * steps`` and position uncertainty
``sigma_pos = translation_sigma_m * sqrt(steps)``: each scan's own
heading error beyond a match's (given per scan, :meth:`ScanMemory.observe`, :meth:`ScanMemory.push`: what
the sweep's skew left; ``heading_sigma_rad`` for a pose no match measured) and a random walk of one match
error per keyframe step between them (``steps`` = turn / ``step_angle_rad`` + distance / ``step_dist_m``:
the estimator's keyframe spacing). A still laser keeps its window of ``lateral_tol_m`` (its scans'
heading noise, 0.01-0.06 deg on the shared still recordings, moves a return by less than ``pose_tol_m``);
driving and turning widen it for the older scans. The window is sharp: 1-2 cm more on a still laser cut
a real recording's walking recall from 0.75 to 0.60 (a walker's leg moves only centimetres a scan).
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
    #: the part of ``lateral_tol_m`` that allows for the matched pose's error: the heading uncertainty widens
    #: the window only where it moves a return further than this
    pose_tol_m: float = 0.02
    #: the beam went at least this far beyond the point (UTM-30LX range noise +-3 cm x 3, pose error)
    range_margin_m: float = 0.15
    #: one scan-to-keyframe match's heading error (1 sigma; the matcher's median rotation error on the real
    #: Intel and CSAIL pairs is 0.29-0.32 deg), also a pose's own where no match measured it
    heading_sigma_rad: float = math.radians(0.3)
    #: the keyframe spacing (the estimator's ``keyframe_angle_rad`` / ``keyframe_dist_m``): one match error
    #: is added per step between two scans
    step_angle_rad: float = math.radians(10.0)
    step_dist_m: float = 0.30
    #: one scan-to-keyframe match's position error (1 sigma; the matcher's median translation error on the
    #: real Intel and CSAIL pairs is 0.022-0.023 m), a random walk over the keyframe steps like the heading's
    translation_sigma_m: float = 0.02
    #: a sideways displacement within this many sigmas of the heading uncertainty is no evidence
    sigma_gate: float = 2.0


class ScanMemory:
    """The last ``config.scans`` scans (world-frame laser pose, ranges, bearings), oldest first."""

    def __init__(self, config: SeenThroughConfig | None = None) -> None:
        self.config = config or SeenThroughConfig()
        c = self.config
        if c.scans < 1:
            raise ValueError(f"SeenThroughConfig.scans must be >= 1, got {c.scans}")
        if (min(c.heading_sigma_rad, c.sigma_gate, c.translation_sigma_m) < 0.0
                or not (c.step_angle_rad > 0.0 and c.step_dist_m > 0.0) or not 0.0 <= c.pose_tol_m <= c.lateral_tol_m):
            raise ValueError("SeenThroughConfig: need heading_sigma_rad, translation_sigma_m and sigma_gate >= 0, "
                             "step_angle_rad > 0, step_dist_m > 0 and 0 <= pose_tol_m <= lateral_tol_m")
        self._scans: deque[tuple[Pose2D, np.ndarray, np.ndarray, float, float]] = deque(maxlen=c.scans)
        #: the pose the asked points are placed with and its own heading sigma (None: no pose uncertainty is
        #: accounted for, the plain lateral window)
        self._observer: tuple[Pose2D, float] | None = None

    def __len__(self) -> int:
        return len(self._scans)

    def observe(self, laser: Pose2D, sigma_rad: float | None = None) -> None:
        """The points asked about next are placed with the laser pose ``laser`` (world frame) whose own
        heading error is ``sigma_rad`` (1 sigma beyond ``lateral_tol_m``; None: ``heading_sigma_rad``)."""
        sigma = self.config.heading_sigma_rad if sigma_rad is None else sigma_rad
        if not (math.isfinite(laser.theta_rad) and math.isfinite(sigma) and sigma >= 0.0):
            raise ValueError("observe needs a finite heading and a finite heading sigma >= 0")
        self._observer = (laser, sigma)

    def relative_heading_sigma_rad(self, a: Pose2D, sigma_a_rad: float, b: Pose2D, sigma_b_rad: float) -> float:
        """The heading uncertainty between two scans taken from laser poses ``a`` and ``b`` (1 sigma): each
        one's own and one match error per keyframe step between them."""
        c = self.config
        turn = abs(math.remainder(a.theta_rad - b.theta_rad, 2.0 * math.pi))
        steps = turn / c.step_angle_rad + math.hypot(a.x_m - b.x_m, a.y_m - b.y_m) / c.step_dist_m
        return math.sqrt(sigma_a_rad**2 + sigma_b_rad**2 + c.heading_sigma_rad**2 * steps)

    def relative_position_sigma_m(self, a: Pose2D, b: Pose2D) -> float:
        """The position uncertainty between two scans taken from laser poses ``a`` and ``b`` (1 sigma): one
        match's translation error per keyframe step between them."""
        c = self.config
        turn = abs(math.remainder(a.theta_rad - b.theta_rad, 2.0 * math.pi))
        steps = turn / c.step_angle_rad + math.hypot(a.x_m - b.x_m, a.y_m - b.y_m) / c.step_dist_m
        return c.translation_sigma_m * math.sqrt(steps)

    def push(self, laser: Pose2D, ranges_m: np.ndarray, bearings_rad: np.ndarray, sigma_rad: float | None = None,
             stamp_s: float = -math.inf) -> None:
        """Keep a scan (copied, in bearing order) taken from ``laser`` (world frame) at ``stamp_s`` whose own
        heading error is ``sigma_rad`` (None: ``heading_sigma_rad``); the oldest falls out. A scan without
        beams is kept too (it saw nothing through)."""
        r = np.array(ranges_m, dtype=np.float64)
        b = np.array(bearings_rad, dtype=np.float64)
        if r.shape != b.shape or r.ndim != 1:
            raise ValueError("ranges and bearings must be 1-D arrays of one length")
        order = np.argsort(b, kind="stable")
        sigma = self.config.heading_sigma_rad if sigma_rad is None else float(sigma_rad)
        self._scans.append((laser, r[order], b[order], sigma, float(stamp_s)))

    def seen_through(self, points_xy: np.ndarray, since_s: float = -math.inf, same_view_echoless: bool = False
                     ) -> np.ndarray:
        """Per point (world frame, k x 2): some kept scan's beams all passed beyond it (within the lateral
        window the heading uncertainty between that scan and the observer's pose widens). Only the scans
        stamped at or after ``since_s`` are asked. ``same_view_echoless``: a beam without an echo counts as
        passing beyond the point where the kept scan saw it from the observer's viewpoint (the pose between
        them no more uncertain than the matched pose's own, ``pose_tol_m``: a still laser): whether a
        surface echoes depends on the angle it is seen at, so a thing that stood there then, seen from the
        same place, would have sent none now either."""
        pts = np.ascontiguousarray(np.asarray(points_xy, dtype=np.float64).reshape(-1, 2))
        out = np.zeros(pts.shape[0], bool)
        c = self.config
        for laser, r, b, sigma, stamp_s in self._scans:
            if stamp_s < since_s:
                continue
            todo = ~out
            if not todo.any():
                break
            per_m = shift_m = 0.0
            if self._observer is not None:
                pose, own = self._observer
                per_m = c.sigma_gate * self.relative_heading_sigma_rad(pose, own, laser, sigma)
                shift_m = c.sigma_gate * self.relative_position_sigma_m(pose, laser)
            out[todo] = _passed_beyond(pts[todo, 0], pts[todo, 1], laser.x_m, laser.y_m, laser.theta_rad, r, b,
                                       c.lateral_tol_m, c.range_margin_m, per_m, shift_m, c.pose_tol_m,
                                       same_view_echoless)
        return out


@njit(cache=True, nogil=True, error_model="numpy")
def _passed_beyond(px, py, lx, ly, lth, r, b, lateral_m, margin_m, lateral_per_m, shift_m, pose_tol_m,
                   same_view_echoless):  # pragma: no cover - compiled
    """Per point: every beam of the scan (bearings ``b`` ascending) whose ray passes within
    ``lateral_m + max(hypot(lateral_per_m * range, shift_m) - pose_tol_m, 0)`` of the point returned at
    least ``margin_m`` beyond it (and there is such a beam); with ``same_view_echoless`` a beam without a return
    counts as beyond where the window is not widened (the same viewpoint)."""
    out = np.zeros(px.size, np.bool_)
    ct, st = math.cos(lth), math.sin(lth)
    for k in range(px.size):
        dx, dy = px[k] - lx, py[k] - ly
        xl, yl = ct * dx + st * dy, -st * dx + ct * dy
        dist = math.hypot(xl, yl)
        widened = math.hypot(lateral_per_m * dist, shift_m) - pose_tol_m
        lateral = lateral_m + max(widened, 0.0)
        echoless_ok = same_view_echoless and widened <= 0.0
        if dist <= lateral:
            continue  # the point is at the laser (or the heading is unknown): nothing to say
        bearing = math.atan2(yl, xl)
        half = math.asin(lateral / dist)
        lo = np.searchsorted(b, bearing - half, side="left")
        hi = np.searchsorted(b, bearing + half, side="right")
        if lo >= hi:
            continue  # outside the scan's field of view, or between two beams: unknown
        ok = True
        for j in range(lo, hi):
            if not (r[j] >= dist + margin_m if math.isfinite(r[j]) else echoless_ok):
                ok = False
                break
        out[k] = ok
    return out
