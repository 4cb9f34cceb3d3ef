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

from dataclasses import dataclass

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
