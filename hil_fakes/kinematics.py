"""The robot's true motion: a unicycle that follows commanded velocities within acceleration limits.

One plant serves both the fake Pioneer (which integrates it between SIPs) and the simulated world
(which ray-casts and renders from its pose), so the robot has exactly one ground truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


def _approach(current: float, target: float, max_step: float) -> float:
    if target > current:
        return min(target, current + max_step)
    return max(target, current - max_step)


@dataclass
class Unicycle:
    """Differential-drive base in the world frame (x forward at theta = 0, y left, theta CCW).

    Defaults are the Pioneer 3-DX's firmware defaults (fact sheet: TRANSACCEL 300 mm/s^2,
    ROTACCEL 100 deg/s^2, TRANSVELMAX 1500 mm/s, ROTVELMAX 360 deg/s).
    """

    x_m: float = 0.0
    y_m: float = 0.0
    theta_rad: float = 0.0
    v_mps: float = 0.0
    w_radps: float = 0.0
    max_accel_mps2: float = 0.3
    max_rot_accel_radps2: float = math.radians(100.0)
    max_v_mps: float = 1.5
    max_w_radps: float = math.radians(360.0)
    v_cmd_mps: float = 0.0
    w_cmd_radps: float = 0.0
    #: total distance driven (m), e.g. for odometry-noise models
    distance_m: float = 0.0

    def command(self, v_mps: float, w_radps: float) -> None:
        self.v_cmd_mps = max(-self.max_v_mps, min(self.max_v_mps, v_mps))
        self.w_cmd_radps = max(-self.max_w_radps, min(self.max_w_radps, w_radps))

    def stop_now(self) -> None:
        """Emergency stop: velocities to zero at once (the firmware's E_STOP)."""
        self.v_cmd_mps = self.w_cmd_radps = 0.0
        self.v_mps = self.w_radps = 0.0

    def advance(self, dt_s: float) -> None:
        """Integrate over ``dt_s`` (exact arc integration for constant velocities within the step)."""
        if dt_s <= 0:
            return
        self.v_mps = _approach(self.v_mps, self.v_cmd_mps, self.max_accel_mps2 * dt_s)
        self.w_radps = _approach(self.w_radps, self.w_cmd_radps, self.max_rot_accel_radps2 * dt_s)
        v, w = self.v_mps, self.w_radps
        th = self.theta_rad
        if abs(w) < 1e-9:
            self.x_m += v * dt_s * math.cos(th)
            self.y_m += v * dt_s * math.sin(th)
        else:
            th2 = th + w * dt_s
            self.x_m += v / w * (math.sin(th2) - math.sin(th))
            self.y_m -= v / w * (math.cos(th2) - math.cos(th))
        self.theta_rad = math.atan2(math.sin(th + w * dt_s), math.cos(th + w * dt_s))
        self.distance_m += abs(v) * dt_s

    def pose(self) -> tuple[float, float, float]:
        return (self.x_m, self.y_m, self.theta_rad)
