"""Sensor models of the simulated world: the UTM-30LX, the robot mount, the camera.

Unverified device facts are parameters here, with the best default and a note:

* UTM-30LX geometry and timing come from its PP reply (fact sheet §1.7, §3): 1081 steps AMIN 0 ..
  AMAX 1080, front step 540, 1440 steps per turn (0.25 deg), 2400 rpm (25 ms per turn, one step
  every 25 ms / 1440 = 17.4 us), DMIN 23 mm. Beam i is taken at t0 + i * 17.4 us.
* Range noise (random, per beam and scan; Gaussian): ``sigma_near_m + sigma_per_range * r`` up to
  ``near_limit_m``, ``sigma_far_m`` beyond. A time-of-flight timing jitter grows as the echo weakens
  with range, so sigma grows with range. Measured on the recorded UTM-30LX frame
  (``../shared/data/hokuyo_utm30lx_session``, ``python -m app.evaluation.leg_realism``): the second
  difference of neighbouring beams' ranges gives sigma 2.9 mm at a median range of 1.0 m and 4.5 mm at
  3.3 m (an upper bound: surface roughness and the 1 mm resolution count too), hence 2.2 mm + 0.7 mm
  per metre. At 10 m that is 9.2 mm, about a third of the datasheet's accuracy (+-30 mm over 0.1-10 m,
  a bound that includes the systematic error: the worst case, read as 3 sigma). Beyond 10 m no
  measurement: the datasheet's +-50 mm read as 3 sigma, 17 mm. (Before, +-30 mm was read as 3 sigma of
  the random noise at every range: 10 mm, 3x what the sensor shows at leg ranges.) The systematic part
  (a bias per unit, range and surface) is not modelled. No return beyond ``max_range_m`` (30 m, the
  guaranteed range) or where the beam meets nothing.
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
    #: range noise sigma at zero range, its growth per metre of range (up to ``near_limit_m``), beyond
    sigma_near_m: float = 0.0022
    sigma_per_range: float = 0.0007
    sigma_far_m: float = 0.017
    near_limit_m: float = 10.0
    intensity_scale: float = 8000.0

    def __post_init__(self) -> None:
        if min(self.sigma_near_m, self.sigma_per_range, self.sigma_far_m) < 0.0:
            raise ValueError(f"range noise must be >= 0: sigma_near_m {self.sigma_near_m}, sigma_per_range "
                             f"{self.sigma_per_range}, sigma_far_m {self.sigma_far_m}")

    def sigma_m(self, range_m: np.ndarray) -> np.ndarray:
        """The range noise's standard deviation (m) at ``range_m``."""
        r = np.asarray(range_m, float)
        return np.where(r <= self.near_limit_m, self.sigma_near_m + self.sigma_per_range * r, self.sigma_far_m)

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
