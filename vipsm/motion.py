"""Motion prediction without odometry: the robot keeps its last measured motion (constant velocity).

A robot driven without wheel odometry (a bag recorded without ``/odom``, a hand-carried scanner) still
moves between two scans; predicting each scan where the last one ended ("identity odometry") puts the
scan matcher's starting guess a whole scan's motion away (0.1 m and 5-9 deg at 7.5 Hz on a robot that
drives at 0.7 m/s and turns), outside its search. The constant-velocity model predicts the last
estimated motion again, scaled to the time since the last scan: the guess is then off by the change of
velocity over one period only. The velocity is the twist between the last two estimates in the body
frame, so a turn while driving forward is predicted as an arc's chord, not as a sideways slide.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .geometry import between, compose
from .types import Pose2D


@dataclass(frozen=True)
class Twist2D:
    """Body-frame velocity: forward, left (m/s) and turn rate (rad/s)."""

    vx_mps: float = 0.0
    vy_mps: float = 0.0
    w_radps: float = 0.0


class ConstantVelocity:
    """Predicts the next pose from the last two estimates. ``max_gap_s``: a longer gap between two
    scans (a stalled scanner, a cut in a recording) is not extrapolated across: the velocity is then
    unknown and the prediction is the last pose."""

    def __init__(self, max_gap_s: float = 1.0) -> None:
        if not max_gap_s > 0.0:
            raise ValueError(f"max_gap_s must be > 0, got {max_gap_s}")
        self.max_gap_s = max_gap_s
        self._pose: Pose2D | None = None
        self._stamp_s = 0.0
        self.twist = Twist2D()

    @property
    def stamp_s(self) -> float | None:
        """The stamp of the last estimate given (None before the first)."""
        return self._stamp_s if self._pose is not None else None

    def reset(self) -> None:
        self._pose = None
        self.twist = Twist2D()

    def predict(self, stamp_s: float) -> Pose2D | None:
        """The pose at ``stamp_s`` (None before the first update)."""
        if self._pose is None:
            return None
        dt = stamp_s - self._stamp_s
        if not 0.0 < dt <= self.max_gap_s:
            return self._pose
        t = self.twist
        return compose(self._pose, Pose2D(t.vx_mps * dt, t.vy_mps * dt, t.w_radps * dt))

    def update(self, pose: Pose2D, stamp_s: float) -> None:
        """The estimate at ``stamp_s``; the twist is the motion from the previous estimate per second."""
        if self._pose is not None:
            dt = stamp_s - self._stamp_s
            if 0.0 < dt <= self.max_gap_s:
                d = between(self._pose, pose)
                self.twist = Twist2D(d.x_m / dt, d.y_m / dt, d.theta_rad / dt)
            elif dt != 0.0:  # a gap (or time running backwards): the velocity is unknown
                self.twist = Twist2D()
        self._pose = pose
        self._stamp_s = stamp_s


def laser_twist(twist: Twist2D, mount: Pose2D) -> Twist2D:
    """The robot's body-frame twist as the laser (mounted at ``mount`` on the robot) moves: its own
    frame's forward / left velocity (the turn adds w x the mount's offset) and the same turn rate."""
    vx = twist.vx_mps - twist.w_radps * mount.y_m
    vy = twist.vy_mps + twist.w_radps * mount.x_m
    c, s = math.cos(mount.theta_rad), math.sin(mount.theta_rad)
    return Twist2D(c * vx + s * vy, -s * vx + c * vy, twist.w_radps)


def deskew(ranges_m: np.ndarray, bearings_rad: np.ndarray, beam_dt_s: float, twist: Twist2D,
           jump_m: float, jump_range_factor: float, weights: np.ndarray | None = None
           ) -> tuple[np.ndarray, np.ndarray | None]:
    """The scan as the laser would have measured it from where it was at the first beam (the scan's stamp),
    on the same bearings. A sweep takes time (beam ``i`` at ``i * beam_dt_s``: 100 ms for 270 deg of a
    7.5 Hz scanner); a laser that turns at ``w`` during it sees the scene stretched in bearing by
    ``w / mirror rate`` and, driving, displaced by up to the sweep's travel. Matching two such scans
    underestimates each turn by that stretch, a heading bias that grows with the turn rate squared
    whatever the direction of the turn. Each return is moved by the laser's motion since the first beam
    (``twist``, laser frame, constant over the sweep), then the ranges are taken again on the original
    bearings, interpolated between two consecutive returns that lie on one surface (a range jump below
    max(``jump_m``, ``jump_range_factor`` * r * step), the matcher's own segmentation test); a bearing
    between returns that do not takes the range of the nearer within half a step, else it is invalid (NaN).
    ``weights`` (per beam) follow: the smaller of the two.
    Returns (ranges, weights or None)."""
    r = np.asarray(ranges_m, dtype=np.float64)
    b = np.asarray(bearings_rad, dtype=np.float64)
    n = r.size
    if n < 2 or not math.isfinite(beam_dt_s) or beam_dt_s == 0.0 or (
            twist.vx_mps == 0.0 and twist.vy_mps == 0.0 and twist.w_radps == 0.0):
        return r.copy(), None if weights is None else np.asarray(weights, dtype=np.float64).copy()
    t = np.arange(n) * beam_dt_s
    th = twist.w_radps * t
    half = 0.5 * th  # the chord of the arc driven at constant twist points along half the turn
    tx = (np.cos(half) * twist.vx_mps - np.sin(half) * twist.vy_mps) * t
    ty = (np.sin(half) * twist.vx_mps + np.cos(half) * twist.vy_mps) * t
    ok = np.isfinite(r)
    px, py = r * np.cos(b + th) + tx, r * np.sin(b + th) + ty
    idx = np.flatnonzero(ok)
    out = np.full(n, np.nan)
    w_out = None if weights is None else np.zeros(n)
    if idx.size < 2:
        return out, w_out
    rb, bb = np.hypot(px[idx], py[idx]), np.arctan2(py[idx], px[idx])
    near_b = (b + th)[idx]  # the bearing turned by the sweep: bb lies near it (continuous over a wide scan)
    bb = near_b + np.mod(bb - near_b + math.pi, 2.0 * math.pi) - math.pi
    order = np.argsort(bb, kind="stable")
    rb, bb, src = rb[order], bb[order], idx[order]
    j = np.searchsorted(bb, b, side="right")  # bb[j-1] <= b < bb[j]
    inside = (j > 0) & (j < bb.size)
    lo, hi = np.clip(j - 1, 0, bb.size - 1), np.clip(j, 0, bb.size - 1)
    step = abs(float(b[-1] - b[0])) / (n - 1)
    gap = np.abs(rb[hi] - rb[lo])
    same = inside & (np.abs(src[hi] - src[lo]) == 1) & (
        gap <= np.maximum(jump_m, jump_range_factor * np.minimum(rb[lo], rb[hi]) * step))
    span = np.where(same, bb[hi] - bb[lo], 1.0)
    f = np.where(same & (span > 0.0), (b - bb[lo]) / np.where(span > 0.0, span, 1.0), 0.0)
    out[same] = (rb[lo] + f * (rb[hi] - rb[lo]))[same]
    # elsewhere (an edge, a lone return) the nearest return within half a step keeps its range: an edge
    # moves by at most half a beam and no return is lost
    near = np.where(np.abs(b - bb[lo]) <= np.abs(bb[hi] - b), lo, hi)
    edge = ~same & (np.abs(bb[near] - b) <= 0.5 * step)
    out[edge] = rb[near][edge]
    if weights is not None and w_out is not None:
        w = np.asarray(weights, dtype=np.float64)
        w_out[same] = np.minimum(w[src[lo]], w[src[hi]])[same]
        w_out[edge] = w[src[near]][edge]
    return out, w_out
