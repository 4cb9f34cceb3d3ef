"""The laser's geometry and timing as a scan states them (never assumed from one scanner model).

Every Hokuyo (and any ROS ``LaserScan``) gives its beams' bearings and each beam's time offset: the
bearing step, field of view and beam count follow from the bearings, the scan period from the time
between neighbouring beams (``beam_dt_s``) times the beams one full turn holds (``2 pi / step``). On the
UTM-30LX that is 0.25 deg, 1081 beams, 270 deg and 25 ms (40 Hz); on a URG-04LX 0.35 deg, 682 beams,
240 deg and 100 ms. Thresholds that depend on the sensor are derived from these (see
``docs/real_data.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .types import Scan


@dataclass(frozen=True)
class ScanGeometry:
    n_beams: int
    step_rad: float
    fov_rad: float
    #: one full turn of the mirror (the scan period); 0 when the scan carries no beam timing
    period_s: float

    @property
    def rate_hz(self) -> float:
        return 1.0 / self.period_s if self.period_s > 0.0 else 0.0


def scan_geometry(scan: Scan) -> ScanGeometry:
    b = scan.bearings_rad
    n = int(b.size)
    step = float(abs(b[-1] - b[0]) / (n - 1)) if n > 1 else 0.0
    return ScanGeometry(n, step, step * max(n - 1, 0), scan_period_s(scan.beam_dt_s, step))


def scan_period_s(beam_dt_s: float, step_rad: float) -> float:
    """The time of one turn from one beam's time and bearing step (0 if either is unknown)."""
    dt, step = abs(float(beam_dt_s)), abs(float(step_rad))
    if not (math.isfinite(dt) and math.isfinite(step)) or dt <= 0.0 or step <= 0.0:
        return 0.0
    return dt * 2.0 * math.pi / step


def scan_period_from_stamps(stamps_s: np.ndarray) -> float:
    """The scan period from consecutive scans' stamps (median spacing; 0 with fewer than two)."""
    d = np.diff(np.asarray(stamps_s, dtype=float))
    d = d[np.isfinite(d) & (d > 0.0)]
    return float(np.median(d)) if d.size else 0.0
