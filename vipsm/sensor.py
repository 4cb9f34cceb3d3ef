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


class SelfReturns:
    """Beams that see the robot itself (its frame, a mast, another sensor at the edge of the field of view).

    A static surface seen by one beam changes range when the laser turns: the beam then points elsewhere.
    A return that keeps its range, within ``tol_m``, across ``checks`` successive turns of at least
    ``turn_rad`` each is fixed in the laser frame: it moves with the robot, and left in the scan it pulls
    every match towards no motion and looks like a body moving with the robot. Checks are made only on
    turns, so a still laser (or one that only drives straight, past a parallel wall) never finds any.
    A found beam is masked only while its return stays at that range (within ``tol_m``): whatever shows
    up beyond it is the world again. It stays found while later checks see it there or further (a part
    seen only now and then as the robot shakes) and is forgotten when a return shows in front of it.
    ``edge_beams`` either side of a found beam are masked at or in front of its range: the body's outline
    gives mixed returns that flicker between it and what lies behind, never holding still long enough to
    be found themselves. The laser's world heading is the estimated one: a match error of a few degrees
    changes nothing in a turn of ``turn_rad``."""

    def __init__(self, turn_rad: float = math.radians(30.0), tol_m: float = 0.05, checks: int = 2,
                 edge_beams: int = 3) -> None:
        if not (turn_rad > 0.0 and tol_m > 0.0 and checks >= 1 and edge_beams >= 0):
            raise ValueError("need turn_rad > 0, tol_m > 0, checks >= 1 and edge_beams >= 0")
        self.turn_rad, self.tol_m, self.checks, self.edge_beams = turn_rad, tol_m, checks, edge_beams
        self._anchor_m: np.ndarray | None = None
        self._anchor_heading_rad = 0.0
        self._count = np.zeros(0, dtype=np.int64)
        self._own_m = np.zeros(0)  # per beam: the range the robot is seen at (valid where found)

    def found(self) -> np.ndarray:
        """Per beam: found to see the robot (empty before the first scan)."""
        return self._count >= self.checks

    def update(self, ranges_m: np.ndarray, heading_rad: float) -> np.ndarray:
        """One scan's ranges (a fixed beam table) at the laser's world heading; returns the beams to mask."""
        r = np.asarray(ranges_m, dtype=np.float64)
        if self._anchor_m is None or self._anchor_m.size != r.size:
            self._anchor_m, self._anchor_heading_rad = r.copy(), heading_rad
            self._count, self._own_m = np.zeros(r.size, dtype=np.int64), np.full(r.size, np.nan)
            return np.zeros(r.size, dtype=bool)
        if abs(math.remainder(heading_rad - self._anchor_heading_rad, 2.0 * math.pi)) >= self.turn_rad:
            d = np.abs(r - self._anchor_m)
            seen = np.isfinite(d)  # no return on either side (a flickering edge, a dark part): no evidence
            same = seen & (d <= self.tol_m)
            with np.errstate(invalid="ignore"):
                # a found beam whose return is now further: the body hidden by vibration, or out of the way
                # for a moment; it is forgotten only when something shows in front of it (then it was no body)
                keep = self.found() & (r > self._own_m - self.tol_m)
            self._count = np.where(seen & ~keep, np.where(same, self._count + 1, 0), self._count + same)
            self._own_m = np.where(same, r, self._own_m)
            self._anchor_m, self._anchor_heading_rad = r.copy(), heading_rad
        return self._mask(r)

    def _mask(self, r: np.ndarray) -> np.ndarray:
        own = self.found()
        if not own.any():
            return own
        with np.errstate(invalid="ignore"):
            mask = own & (np.abs(r - self._own_m) <= self.tol_m)
            k = self.edge_beams
            if k:
                body = np.where(own, self._own_m, -np.inf)
                padded = np.concatenate((np.full(k, -np.inf), body, np.full(k, -np.inf)))
                reach = np.max(np.stack([padded[k + s : k + s + r.size] for s in range(-k, k + 1)]), axis=0)
                mask |= ~own & (r <= reach + self.tol_m)
        return mask
