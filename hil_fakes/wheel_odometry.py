"""Wheel odometry with configurable systematic and random error, for the fake Pioneer and the world.

The robot's true motion (the plant) is cut into body-frame increments ``(ds_m, dtheta_rad)``;
:class:`WheelOdometry` integrates them after corrupting them with :class:`OdometryNoise`, the way
real wheel encoders misreport distance and heading. With all noise parameters at zero it integrates
the increments exactly (arc integration, the same motion model as
:class:`hil_fakes.kinematics.Unicycle`), so it reproduces the true pose to floating-point rounding.

Error model, per step with true increments ``ds`` (signed, m) and ``dth`` (signed, rad):

* systematic: ``ds' = ds * (1 + scale_error)``; ``dth' = dth * (1 + rot_scale_error) +
  heading_drift_rad_per_m * ds`` (drift follows the signed distance, as an unequal wheel diameter
  does: driving backwards turns the other way; a left/right radius mismatch ``d`` on a wheelbase ``b``
  gives ``d / b`` rad/m; ``rot_scale_error`` is an effective wheelbase that differs from the
  configured one);
* random (independent Gaussian per step, variance proportional to the distance or angle of the
  step, so the accumulated error does not depend on how finely the motion is cut):
  ``ds'  += N(0, sigma_trans_frac^2 * |ds| * 1 m)``, i.e. after driving ``D`` metres the distance
  error has std ``sigma_trans_frac * sqrt(D / 1 m)`` metres (``sigma_trans_frac`` is the std of the
  distance error accumulated over one metre, in metres per metre);
  ``dth' += N(0, sigma_rot_rad_per_rad^2 * |dth| * 1 rad + sigma_rot_rad_per_m^2 * |ds| * 1 m)``,
  so the heading error has std ``sigma_rot_rad_per_rad`` after turning one radian and
  ``sigma_rot_rad_per_m`` after driving one metre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class OdometryNoise:
    """Odometry error parameters (all zero: perfect odometry). See the module docstring for the model."""

    #: fraction; 0.01 reports 1 % more distance than driven
    scale_error: float = 0.0
    #: heading error added per metre driven (signed distance), rad/m
    heading_drift_rad_per_m: float = 0.0
    #: fraction; rotation reported too large by this (effective wheelbase shorter than the configured
    #: one: 0.02 = 2 %)
    rot_scale_error: float = 0.0
    #: std of the distance error accumulated over 1 m of travel, m/m
    sigma_trans_frac: float = 0.0
    #: std of the heading error accumulated over 1 rad of rotation, rad/rad
    sigma_rot_rad_per_rad: float = 0.0
    #: std of the heading error accumulated over 1 m of travel, rad/m
    sigma_rot_rad_per_m: float = 0.0
    #: seed of the random-noise generator (None: fresh entropy)
    seed: int | None = None

    def __post_init__(self) -> None:
        for name in ("sigma_trans_frac", "sigma_rot_rad_per_rad", "sigma_rot_rad_per_m"):
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0:
                raise ValueError(f"OdometryNoise.{name} must be finite and >= 0, got {value}")
        for name in ("scale_error", "heading_drift_rad_per_m", "rot_scale_error"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ValueError(f"OdometryNoise.{name} must be finite, got {value}")
        if self.scale_error <= -1.0:
            raise ValueError(f"OdometryNoise.scale_error must be > -1, got {self.scale_error}")

    @property
    def is_random(self) -> bool:
        return self.sigma_trans_frac > 0 or self.sigma_rot_rad_per_rad > 0 or self.sigma_rot_rad_per_m > 0


def _wrap_pi(angle_rad: float) -> float:
    return math.atan2(math.sin(angle_rad), math.cos(angle_rad))


class WheelOdometry:
    """Integrates (noisy) body-frame increments into an odometry pose.

    ``x_m, y_m, theta_rad`` is the pose the odometry starts from (e.g. the controller's raw
    start-up pose). ``pose()`` returns the odometry pose with theta wrapped to (-pi, pi];
    ``heading_unwrapped_rad`` keeps the accumulated, unwrapped heading.
    """

    def __init__(self, noise: OdometryNoise, x_m: float = 0.0, y_m: float = 0.0, theta_rad: float = 0.0) -> None:
        self.noise = noise
        self._rng = np.random.default_rng(noise.seed)
        self._x_m = float(x_m)
        self._y_m = float(y_m)
        self._theta_rad = float(theta_rad)
        #: total |distance| reported by the odometry (m)
        self.distance_m = 0.0

    def step(self, ds_m: float, dtheta_rad: float) -> None:
        """Add the true body-frame increments since the last step (distance along the arc, rotation)."""
        n = self.noise
        ds = ds_m * (1.0 + n.scale_error)
        dth = dtheta_rad * (1.0 + n.rot_scale_error) + n.heading_drift_rad_per_m * ds_m
        if n.is_random:
            if n.sigma_trans_frac > 0 and ds_m != 0.0:
                ds += float(self._rng.normal(0.0, n.sigma_trans_frac * math.sqrt(abs(ds_m))))
            var_rot = n.sigma_rot_rad_per_rad**2 * abs(dtheta_rad) + n.sigma_rot_rad_per_m**2 * abs(ds_m)
            if var_rot > 0:
                dth += float(self._rng.normal(0.0, math.sqrt(var_rot)))
        th = self._theta_rad
        if abs(dth) < 1e-9:
            self._x_m += ds * math.cos(th)
            self._y_m += ds * math.sin(th)
        else:
            # exact arc: same as Unicycle.advance with v = ds/dt, w = dth/dt
            radius = ds / dth
            self._x_m += radius * (math.sin(th + dth) - math.sin(th))
            self._y_m -= radius * (math.cos(th + dth) - math.cos(th))
        self._theta_rad = th + dth
        self.distance_m += abs(ds)

    def pose(self) -> tuple[float, float, float]:
        """The odometry pose (x_m, y_m, theta_rad in (-pi, pi])."""
        return (self._x_m, self._y_m, _wrap_pi(self._theta_rad))

    @property
    def heading_unwrapped_rad(self) -> float:
        return self._theta_rad

    def reset(self, x_m: float = 0.0, y_m: float = 0.0, theta_rad: float = 0.0) -> None:
        """Set the odometry pose (e.g. the controller's SETO); the noise generator keeps its state."""
        self._x_m, self._y_m, self._theta_rad = float(x_m), float(y_m), float(theta_rad)
