"""Where the fake UTM-30LX's ranges come from: the range-source interface and a fixed room."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

_MASK24 = (1 << 24) - 1


# --------------------------------------------------------------------------------------------
# Range sources
# --------------------------------------------------------------------------------------------


class RangeSource(Protocol):
    def sweep(self, t0_s: float, angles_rad: np.ndarray, beam_dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        """ranges_m (float64, NaN = no return) and intensities (float64 >= 0, unitless) for the beams at
        angles_rad (sensor frame: 0 = front, counter-clockwise positive), beam i taken at t0_s + i*beam_dt_s."""
        ...


@dataclass(frozen=True)
class FixedRoom:
    """A rectangular room around a still sensor, with one round pillar; deterministic by default.

    The sensor sits at the origin facing +x; walls at ``x_min_m``/``x_max_m``/``y_min_m``/``y_max_m``.
    ``noise_sigma_m`` adds Gaussian range noise (seeded by the scan time, so reproducible).
    """

    x_min_m: float = -1.5
    x_max_m: float = 6.5
    y_min_m: float = -2.45
    y_max_m: float = 2.45
    pillar_x_m: float = 2.0
    pillar_y_m: float = 1.0
    pillar_radius_m: float = 0.2
    noise_sigma_m: float = 0.0

    def sweep(self, t0_s: float, angles_rad: np.ndarray, beam_dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        c = np.cos(angles_rad)
        s = np.sin(angles_rad)
        with np.errstate(divide="ignore", invalid="ignore"):
            tx = np.where(c > 0, self.x_max_m / c, np.where(c < 0, self.x_min_m / c, np.inf))
            ty = np.where(s > 0, self.y_max_m / s, np.where(s < 0, self.y_min_m / s, np.inf))
        r = np.minimum(tx, ty)
        # ray / circle: |t*d - p|^2 = R^2
        px, py, rad = self.pillar_x_m, self.pillar_y_m, self.pillar_radius_m
        b = c * px + s * py
        disc = b * b - (px * px + py * py - rad * rad)
        hit = disc >= 0
        t_hit = np.where(hit, b - np.sqrt(np.where(hit, disc, 0.0)), np.inf)
        t_hit = np.where(t_hit > 0, t_hit, np.inf)
        r = np.minimum(r, t_hit)
        if self.noise_sigma_m > 0:
            rng = np.random.default_rng(int(t0_s * 1000) & 0x7FFFFFFF)
            r = r + rng.normal(0.0, self.noise_sigma_m, r.shape)
        r = np.where(np.isfinite(r), r, np.nan)
        intensity = np.clip(9000.0 / np.maximum(r, 0.3) ** 1.2, 100.0, 16000.0)
        return r, np.where(np.isnan(r), 0.0, intensity)
