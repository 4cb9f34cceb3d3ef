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
    *checks*. Turn checks: the scans at which the laser has turned at least ``turn_rad`` since the last one
    (a still laser sees the world at fixed ranges too); there a bin counts as looked at when the beam's
    return lies in it or beyond it (a return in front hides it; no return is no evidence). Move checks (with
    the laser's world position and the beams' bearings given, ``move_m`` > 0): the scans at which the laser
    has travelled ``move_m`` since the last one. Driving straight, a wall parallel to the travel also stays at
    one (beam, range), so there a return counts only where the last check's scan saw through its world point
    (or this scan sees through the point that beam returned then): it moved with the laser, and only on a
    beam that held it in every scan since (see :meth:`_move_evidence`). A beam that returned nothing in
    some of those scans (a part it grazes, a dark part) held it too if it returned there in at least half
    of them; that weaker evidence counts only where the point was seen through to beyond ``max_range_m``
    (the world, not a second body within the robot's reach such as a follower's other leg). A robot that
    drives straight for its first seconds learns its parts within ``2-3 move_m``, before its first turn.

    Counts decay by ``1 - 1/memory_checks`` a check, so the model follows a robot
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
    over ``checks`` turns, within ``max_range_m``; or walking at the robot's pace with a leg held still
    relative to the laser (within ``2 tol_m``, every scan) over the ``move_m`` before two move checks."""

    def __init__(self, turn_rad: float = math.radians(30.0), tol_m: float = 0.05, checks: int = 2,
                 edge_beams: int = 3, max_range_m: float = 1.0, min_share: float = 0.5,
                 memory_checks: int = 20, move_m: float = 0.2) -> None:
        if not (turn_rad > 0.0 and tol_m > 0.0 and checks >= 1 and edge_beams >= 0 and max_range_m > tol_m
                and 0.0 < min_share <= 1.0 and memory_checks >= 1 and (move_m == 0.0 or move_m > 2.0 * tol_m)):
            raise ValueError("need turn_rad > 0, tol_m > 0, checks >= 1, edge_beams >= 0, max_range_m > tol_m, "
                             "0 < min_share <= 1, memory_checks >= 1 and move_m 0 (off) or > 2 tol_m")
        self.turn_rad, self.tol_m, self.checks, self.edge_beams = turn_rad, tol_m, checks, edge_beams
        self.max_range_m, self.min_share, self.memory_checks = max_range_m, min_share, memory_checks
        self.move_m = move_m
        self._bins = int(math.ceil(max_range_m / tol_m))
        self._anchor_heading_rad: float | None = None
        self._anchor: _Look | None = None  # the last check's scan and laser pose (for the move checks)
        self._since: list[np.ndarray] = []  # the scans since the last move check (at most ``_MAX_SINCE``)
        self._hits = np.zeros((0, self._bins))
        self._looks = np.zeros((0, self._bins))
        self._own_m = np.zeros(0)  # per beam: the footprint's range (NaN: no part of the robot found)

    def found(self) -> np.ndarray:
        """Per beam: a part of the robot found on it (empty before the first scan)."""
        return np.isfinite(self._own_m)

    def footprint_m(self) -> np.ndarray:
        """Per beam: the range of the robot's body along it (NaN where none was found)."""
        return self._own_m.copy()

    def update(self, ranges_m: np.ndarray, heading_rad: float, bearings_rad: np.ndarray | None = None,
               position_m: tuple[float, float] | None = None) -> np.ndarray:
        """One scan's ranges (a fixed beam table) at the laser's world heading; returns the beams to mask.
        With the beams' bearings and the laser's world position, the laser's travel is evidence too (the
        move checks, see the class doc)."""
        r = np.asarray(ranges_m, dtype=np.float64)
        look = (_Look(r, np.asarray(bearings_rad, dtype=np.float64), float(position_m[0]), float(position_m[1]),
                      heading_rad) if bearings_rad is not None and position_m is not None and self.move_m > 0.0
                else None)
        if self._anchor_heading_rad is None or self._own_m.size != r.size:
            self._hits, self._looks = np.zeros((r.size, self._bins)), np.zeros((r.size, self._bins))
            self._own_m = np.full(r.size, np.nan)
            self._anchor_heading_rad = heading_rad
            self._anchor_at(r, look)
            return np.zeros(r.size, dtype=bool)
        self._since = [*self._since[-(_MAX_SINCE - 1):], r]
        if abs(math.remainder(heading_rad - self._anchor_heading_rad, 2.0 * math.pi)) >= self.turn_rad:
            self._count(*self._turn_evidence(r))
            self._anchor_heading_rad = heading_rad
        if look is not None and (self._anchor is None or math.hypot(look.x_m - self._anchor.x_m,
                                                                     look.y_m - self._anchor.y_m) >= self.move_m):
            if self._anchor is not None:
                self._count(*self._move_evidence(look))
            self._anchor_at(r, look)
        return self._mask(r)

    def _anchor_at(self, r: np.ndarray, look: _Look | None) -> None:
        """The move checks' anchor (their own: a turn check does not move it) and the window of scans since."""
        self._anchor = look
        self._since = [r]

    def _turn_evidence(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A turn check: a return hits the bins whose centre lies within ``tol_m`` of it (two bins: noise
        across a bin edge splits nothing) and is a look at every bin up to there."""
        rr = np.where(np.isfinite(r), r, -np.inf)[:, None]
        centre = (np.arange(self._bins) + 0.5) * self.tol_m
        return centre[None, :] <= rr + self.tol_m, np.abs(centre[None, :] - rr) <= self.tol_m

    def _move_evidence(self, look: _Look) -> tuple[np.ndarray, np.ndarray]:
        """A move check. Bins in front of the return now and of the beam's return at the last check are
        looked at and empty (a part of the robot that the beam passes beside now and then is seldom missed at
        both ends; a person's leg that crossed the beam is). The bins at the return count only on a beam that
        held it since the last check (:meth:`_held`), and only if
        the last check's scan saw through its world point, or this scan sees through the world point of the
        return that beam had then (the point moved with the laser: a hit). A point that scan saw (a static
        surface, a wall parallel to the travel, but also a part of the robot that stretches along the travel),
        or could not see (out of its view, behind a nearer return, no return there), says nothing: no count.
        A return held with gaps (:meth:`_held`) counts only where the point was seen through to beyond the
        robot's reach ``max_range_m``: a follower's near leg is seen through by its other leg a few tenths
        of a metre further, a part of the robot by the room."""
        rr = np.where(np.isfinite(look.ranges_m), look.ranges_m, -np.inf)[:, None]
        centre = (np.arange(self._bins) + 0.5) * self.tol_m
        # both ways: a part ahead of the laser's travel moves to where the last check's scan could not look
        # (behind a laser that faces back), but where it stood then is in the view now
        m, reach = 2.0 * self.tol_m, self.max_range_m
        free_a, world_a = _seen_through(self._anchor, look, m, reach)
        free_b, world_b = _seen_through(look, self._anchor, m, reach)
        free, world = free_a | free_b, world_a | world_b
        held, gapped = self._held(look.ranges_m)
        steady = (held | gapped)[:, None]
        hits = ((held & free) | (gapped & world))[:, None] & (np.abs(centre[None, :] - rr) <= self.tol_m)
        return hits | (steady & (centre[None, :] < rr - self.tol_m)), hits

    def _held(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per beam: its return ``r`` held since the last move check, within ``2 tol_m`` in every scan since
        (that check's scan included) without a gap; and, where not, held with gaps: in the scans between, the
        beam returned there or nothing, and there in at least half of them. A part of the robot holds its
        return; a walking person's legs, which stand on the floor while the laser passes and then swing past
        it, seldom do over the ``move_m`` between two checks: the beam sees the world behind them (a return
        beyond). A part's return is always at one range when present, but a beam that grazes it or a dark part
        returns nothing now and then (in up to half of the scans), which is no evidence against it. A leg in
        open space, with nothing behind it to return, gives the same gaps; so a gapped return is the weaker
        evidence (see :meth:`_move_evidence`). A part that the beam passes beside now and then (its outline, a
        return beyond it) is left to the turn checks."""
        since = np.stack(self._since)
        with np.errstate(invalid="ignore"):
            at = np.abs(since - r[None, :]) <= 2.0 * self.tol_m
        ok = np.isfinite(r)
        held = ok & at.all(axis=0)
        gapped = ok & ~held & (at | ~np.isfinite(since)).all(axis=0) & (2 * at.sum(axis=0) >= len(self._since))
        return held, gapped

    def _count(self, looks: np.ndarray, hits: np.ndarray) -> None:
        """Count one check's evidence into the (beam, range bin) model and take the footprint again."""
        keep = 1.0 - 1.0 / self.memory_checks
        self._hits = self._hits * keep + hits
        self._looks = self._looks * keep + looks
        body = (self._hits >= self.min_share * self._looks) & (self._hits >= self.checks - 0.5)
        # the footprint: the far end of the first run of body bins (one part spans two bins)
        first = np.argmax(body, axis=1)
        past = ~body & (np.arange(self._bins)[None, :] > first[:, None])
        last = np.where(past.any(axis=1), np.argmax(past, axis=1) - 1, self._bins - 1)
        centre = (np.arange(self._bins) + 0.5) * self.tol_m
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


#: the move checks' window: the scans since the last one, at most this many (a robot that stands still)
_MAX_SINCE = 32


@dataclass(frozen=True)
class _Look:
    """One scan as :class:`SelfReturns` keeps it for a move check: its ranges and bearings, the laser's
    world pose."""

    ranges_m: np.ndarray
    bearings_rad: np.ndarray
    x_m: float
    y_m: float
    heading_rad: float


def _seen_through(then: _Look, now: _Look, margin_m: float, reach_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Per beam of ``now``: its return's world point was seen through by ``then`` (all three nearest beams
    returned beyond it by more than ``margin_m``; none returned within ``margin_m`` of it, which would be
    the point seen, static), and seen through to beyond ``reach_m`` from ``then``'s laser as well. Neither
    where the point is out of ``then``'s view, behind a nearer return or where a beam returned nothing (no
    evidence)."""
    a = now.heading_rad + now.bearings_rad
    wx, wy = now.x_m + now.ranges_m * np.cos(a), now.y_m + now.ranges_m * np.sin(a)
    dx, dy = wx - then.x_m, wy - then.y_m
    c, s = math.cos(then.heading_rad), math.sin(then.heading_rad)
    qx, qy = c * dx + s * dy, -s * dx + c * dy
    rng, brg = np.hypot(qx, qy), np.arctan2(qy, qx)
    b = then.bearings_rad
    n = b.size
    step = (b[-1] - b[0]) / (n - 1) if n > 1 else 1.0
    with np.errstate(invalid="ignore"):
        pos = np.remainder((brg - b[0]) * np.sign(step), 2.0 * math.pi) / abs(step)  # a view across +-pi too
        pos = np.where(pos > 2.0 * math.pi / abs(step) - 0.5, pos - 2.0 * math.pi / abs(step), pos)
        inside = np.isfinite(pos) & (pos > -0.5) & (pos < n - 0.5)
        idx = np.clip(np.rint(np.where(inside, pos, 0.0)).astype(int), 0, n - 1)
        near = then.ranges_m[np.clip(idx[:, None] + np.array([-1, 0, 1])[None, :], 0, n - 1)]
        static = inside & (np.abs(near - rng[:, None]) <= margin_m).any(axis=1)
        free = inside & ~static & (np.isfinite(near) & (near > rng[:, None] + margin_m)).all(axis=1)
        far = free & (near > reach_m).all(axis=1)
    ok = np.isfinite(now.ranges_m)
    return free & ok, far & ok
