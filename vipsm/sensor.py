"""The laser's geometry and timing as a scan states them (never assumed from one scanner model).

Every Hokuyo (and any ROS ``LaserScan``) gives its beams' bearings and each beam's time offset: the
bearing step, field of view and beam count follow from the bearings. The scan period is the spacing of
consecutive scans' stamps where the caller has seen two (``stamp_period_s``); from one scan alone it is the
time between neighbouring beams (``beam_dt_s``) times the beams one full turn holds (``2 pi / step``).
That is the mirror's turn, and it is the scan period only when every turn is delivered at the stated step:
the leg_tracker recordings' scanners state 65.1 us per 0.3516 deg beam (a 15 Hz mirror, 66.7 ms) but
deliver a scan every 133 ms (every other turn; their ``scan_time`` and stamps say so), and a recording
whose beams are every k-th mirror step with one step's ``time_increment`` gives k times too short a
period the same way. The stamps always come one delivered period apart. On the
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


def scan_geometry(scan: Scan, stamp_period_s: float | None = None) -> ScanGeometry:
    """The scan's geometry; its period from ``stamp_period_s`` (the measured spacing of consecutive scans'
    stamps, :func:`scan_period_from_stamps`) when that is known (> 0), else from the beam timing."""
    b = scan.bearings_rad
    n = int(b.size)
    step = float(abs(b[-1] - b[0]) / (n - 1)) if n > 1 else 0.0
    measured = float(stamp_period_s) if stamp_period_s is not None and math.isfinite(stamp_period_s) else 0.0
    period = measured if measured > 0.0 else scan_period_s(scan.beam_dt_s, step)
    return ScanGeometry(n, step, step * max(n - 1, 0), period)


def scan_period_s(beam_dt_s: float, step_rad: float) -> float:
    """The time of one turn from one beam's time and bearing step (0 if either is unknown). Right only when
    the step is the mirror's step (see the module's doc): prefer the stamps' spacing where it is known."""
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
    """A model of the robot's own body as its laser sees it: per beam, the range at which a part of the robot
    stands (its frame, a mast, another sensor at the edge of the field of view), learned online.

    A static surface seen by one beam changes range when the laser turns: the beam then points elsewhere. A
    part of the robot does not: it stays at one (beam, range) however the robot moves. The model keeps, per
    beam and per range bin of ``tol_m`` out to ``max_range_m`` (the robot's reach from its laser: the
    footprint is bounded, ``beams x max_range_m / tol_m`` counts), how often a return fell in that bin at the
    *checks*: the scans at which the laser has turned at least ``turn_rad`` since the last check (only turns:
    a still laser, or one driving straight past a parallel wall, sees the world at fixed ranges too). A bin
    counts as looked at when the beam's return lies in it or beyond it (a return in front hides it; no
    return is no evidence). Counts decay by ``1 - 1/memory_checks`` a check, so the model follows a robot
    that changes (a door of the robot opened, a load put on). A bin held in at least ``min_share`` of the
    checks that looked at it, by at least ``checks`` of them, is the robot's body; the nearest such bin is
    the beam's footprint. Parts seen only now and then (vibration, a dark surface, a thin rod that one beam
    hits every other scan) are found as long as they are seen in ``min_share`` of the looks, which an exact
    repeat test misses.

    Masked: every return at or in front of its beam's footprint (+ ``tol_m``: inside the robot's outline),
    and in the ``edge_beams`` either side of a footprint beam the returns at or in front of its range (the
    body's outline gives mixed returns that flicker between it and what lies behind). The laser's world
    heading is the estimated one: a match error of a few degrees changes nothing in a turn of ``turn_rad``.
    Not told apart: a person walking beside a turning robot at one bearing and one range (within ``tol_m``)
    over ``checks`` turns, within ``max_range_m``."""

    def __init__(self, turn_rad: float = math.radians(30.0), tol_m: float = 0.05, checks: int = 2,
                 edge_beams: int = 3, max_range_m: float = 1.0, min_share: float = 0.5,
                 memory_checks: int = 20) -> None:
        if not (turn_rad > 0.0 and tol_m > 0.0 and checks >= 1 and edge_beams >= 0 and max_range_m > tol_m
                and 0.0 < min_share <= 1.0 and memory_checks >= 1):
            raise ValueError("need turn_rad > 0, tol_m > 0, checks >= 1, edge_beams >= 0, max_range_m > tol_m, "
                             "0 < min_share <= 1 and memory_checks >= 1")
        self.turn_rad, self.tol_m, self.checks, self.edge_beams = turn_rad, tol_m, checks, edge_beams
        self.max_range_m, self.min_share, self.memory_checks = max_range_m, min_share, memory_checks
        self._bins = int(math.ceil(max_range_m / tol_m))
        self._anchor_heading_rad: float | None = None
        self._hits = np.zeros((0, self._bins))
        self._looks = np.zeros((0, self._bins))
        self._own_m = np.zeros(0)  # per beam: the footprint's range (NaN: no part of the robot found)

    def found(self) -> np.ndarray:
        """Per beam: a part of the robot found on it (empty before the first scan)."""
        return np.isfinite(self._own_m)

    def footprint_m(self) -> np.ndarray:
        """Per beam: the range of the robot's body along it (NaN where none was found)."""
        return self._own_m.copy()

    def update(self, ranges_m: np.ndarray, heading_rad: float) -> np.ndarray:
        """One scan's ranges (a fixed beam table) at the laser's world heading; returns the beams to mask."""
        r = np.asarray(ranges_m, dtype=np.float64)
        if self._anchor_heading_rad is None or self._own_m.size != r.size:
            self._anchor_heading_rad = heading_rad
            self._hits, self._looks = np.zeros((r.size, self._bins)), np.zeros((r.size, self._bins))
            self._own_m = np.full(r.size, np.nan)
            return np.zeros(r.size, dtype=bool)
        if abs(math.remainder(heading_rad - self._anchor_heading_rad, 2.0 * math.pi)) >= self.turn_rad:
            self._check(r)
            self._anchor_heading_rad = heading_rad
        return self._mask(r)

    def _check(self, r: np.ndarray) -> None:
        """Count one check's returns into the (beam, range bin) model and take the footprint again. A return
        hits the bins whose centre lies within ``tol_m`` of it (two bins: noise across a bin edge splits
        nothing) and is a look at every bin up to there."""
        keep = 1.0 - 1.0 / self.memory_checks
        self._hits *= keep
        self._looks *= keep
        seen = np.isfinite(r)
        rr = np.where(seen, r, -np.inf)[:, None]
        centre = (np.arange(self._bins) + 0.5) * self.tol_m
        self._looks += centre[None, :] <= rr + self.tol_m
        self._hits += np.abs(centre[None, :] - rr) <= self.tol_m
        body = (self._hits >= self.min_share * self._looks) & (self._hits >= self.checks - 0.5)
        # the footprint: the far end of the first run of body bins (one part spans two bins)
        first = np.argmax(body, axis=1)
        past = ~body & (np.arange(self._bins)[None, :] > first[:, None])
        last = np.where(past.any(axis=1), np.argmax(past, axis=1) - 1, self._bins - 1)
        self._own_m = np.where(body.any(axis=1), centre[last], np.nan)

    def _mask(self, r: np.ndarray) -> np.ndarray:
        own = self.found()
        if not own.any():
            return own
        with np.errstate(invalid="ignore"):
            mask = own & (r <= self._own_m + self.tol_m)
            k = self.edge_beams
            if k:
                body = np.where(own, self._own_m, -np.inf)
                padded = np.concatenate((np.full(k, -np.inf), body, np.full(k, -np.inf)))
                reach = np.max(np.stack([padded[k + s : k + s + r.size] for s in range(-k, k + 1)]), axis=0)
                mask |= ~own & (r <= reach + self.tol_m)
        return mask
