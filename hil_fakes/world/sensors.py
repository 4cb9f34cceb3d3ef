"""Sensor models of the simulated world: the UTM-30LX, the robot mount, the camera.

Unverified device facts are parameters here, with the best default and a note:

* UTM-30LX geometry and timing come from its PP reply (fact sheet §1.7, §3): 1081 steps AMIN 0 ..
  AMAX 1080, front step 540, 1440 steps per turn (0.25 deg), 2400 rpm (25 ms per turn, one step
  every 25 ms / 1440 = 17.4 us), DMIN 23 mm. Beam i is taken at t0 + i * 17.4 us.
* Range noise [?]: the datasheet's accuracy is +-30 mm over 0.1-10 m and +-50 mm over 10-30 m; we read
  those bounds as 3 sigma: Gaussian sigma 10 mm up to 10 m and 17 mm beyond. No return beyond
  ``max_range_m`` (30 m, the guaranteed range) or where the beam meets nothing.
* Intensity: unitless, ~2300 on a matt wall at 3.3 m face-on (the real ME frame in the fact sheet),
  scaled by reflectivity and the cosine of the incidence; not calibrated.
* Camera: SNC-RZ50 wide end HFOV 54 deg [?], square pixels, principal point at the image centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LaserModel:
    n_beams: int = 1081
    first_step: int = 0  # AMIN
    front_step: int = 540  # AFRT
    steps_per_rev: int = 1440  # ARES
    scan_period_s: float = 0.025  # 60 / SCAN(2400 rpm)
    dmin_m: float = 0.023  # DMIN
    max_range_m: float = 30.0
    sigma_near_m: float = 0.010
    sigma_far_m: float = 0.017
    near_limit_m: float = 10.0
    intensity_scale: float = 8000.0

    @property
    def angle_increment_rad(self) -> float:
        return 2 * math.pi / self.steps_per_rev

    @property
    def beam_dt_s(self) -> float:
        return self.scan_period_s / self.steps_per_rev

    def angles_rad(self) -> np.ndarray:
        steps = np.arange(self.first_step, self.first_step + self.n_beams)
        return (steps - self.front_step) * self.angle_increment_rad


@dataclass(frozen=True)
class RobotMount:
    """Where the sensors sit on the robot (robot frame: x forward, y left, z up from the floor)."""

    laser_x_m: float = 0.16
    laser_y_m: float = 0.0
    laser_theta_rad: float = 0.0
    laser_z_m: float = 0.30
    camera_x_m: float = 0.10
    camera_y_m: float = 0.0
    camera_z_m: float = 0.55


@dataclass(frozen=True)
class CameraModel:
    width_px: int = 320
    height_px: int = 240
    hfov_wide_rad: float = math.radians(54.0)
    #: std of the additive Gaussian pixel noise, grey levels
    noise_sigma: float = 2.5
    #: texture resolution (m per texel at the finest level)
    texel_m: float = 0.01
    ceiling_height_m: float = 2.6
    texture_seed: int = 7


def intrinsics(width_px: int, height_px: int, hfov_rad: float) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) in pixels for the rendered images: square pixels, pixel centres at integer
    coordinates, principal point at the geometric centre ((W - 1) / 2, (H - 1) / 2)."""
    fx = (width_px / 2.0) / math.tan(hfov_rad / 2.0)
    return fx, fx, (width_px - 1) / 2.0, (height_px - 1) / 2.0
