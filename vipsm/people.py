"""People as people: every person-like body tracked from its first detection, walking or standing.

Each obstacle cycle:

1. **legs** (:mod:`vipsm.legs`): every leg-sized segment of the pre-filtered scan gets a leg probability
   from the learned detector; those at or above its operating point are legs, placed at their returns'
   centroid pushed back by a leg's radius along the viewing ray;
2. **people detections**: legs paired greedily, nearest first, within ``leg_pair_max_m`` (a stride at
   the laser's height); a pair is a person at the legs' midpoint, an unpaired leg a person seen by one
   leg (the other hidden or merged with it) at that leg, with the larger noise of a hip's half-width;
3. **association**: global nearest neighbour (:func:`vipsm.assignment.assign`) on the
   Mahalanobis distance of each detection to each track's predicted position, gated at the chi-square
   ``gate_p`` quantile of two degrees of freedom;
4. **motion state** (:mod:`vipsm.imm`): per track an IMM of a standing and a walking model gives the
   velocity and P(moving); a track is *moving* once P(moving) reaches ``moving_on`` and until it falls
   below ``moving_off`` (hysteresis);
5. **existence**: each track's existence probability follows Bayes' rule with the detection
   probability ``p_detect`` of a person in view and the chance ``p_clutter`` that a gate holds a
   non-person leg detection (weighted by the detection's leg probability); a track is confirmed (in
   ``Estimate.people``) from ``exist_confirm``, dropped below ``exist_drop``. A person seen nowhere in
   a cycle counts as missed only where the scan could have seen it (a return in that direction beyond it).

Positions in the world frame (the odometry frame, placed with the matched laser pose), SI units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .assignment import assign
from .bodies import BodiesConfig, segments
from .geometry import wrap_angle
from .imm import Imm, ImmConfig
from .legs import LegConfig, LegModel, segment_features
from .types import Obstacle, Person, Pose2D


@dataclass(frozen=True)
class PeopleConfig:
    legs: LegConfig = field(default_factory=LegConfig)
    imm: ImmConfig = field(default_factory=ImmConfig)
    #: a leg's radius at the laser's height (shin): the centre lies this far behind the returns
    leg_radius_m: float = 0.06
    #: two legs of one person: centres at most this far apart (stride at the laser's height)
    leg_pair_max_m: float = 0.65
    #: position noise of a leg-pair midpoint (gait jitter) and of a lone leg (a hip's half-width)
    pair_sigma_m: float = 0.06
    leg_sigma_m: float = 0.15
    #: association gate: this quantile of the chi-square distribution (2 degrees of freedom)
    gate_p: float = 0.99
    p_detect: float = 0.8
    p_clutter: float = 0.1
    #: existence of a new track, and from / below which it is confirmed / dropped
    exist_birth: float = 0.2
    exist_confirm: float = 0.7
    exist_drop: float = 0.05
    #: P(moving) from which a track is moving, and below which it is standing again
    moving_on: float = 0.8
    moving_off: float = 0.4
    #: a track nowhere the scan could see it loses existence with this time constant (a person hidden
    #: behind another is still there for a few seconds; a false track must not live on out of sight)
    unseen_memory_s: float = 3.0
    #: a track is in ``Estimate.people`` only while its position is known to within this (one standard
    #: deviation, along its least certain direction): about a person's half-width. A walker who vanished
    #: coasts out of it in about half a second; a standing one hidden behind another keeps it for seconds
    max_position_sigma_m: float = 0.3
    #: a moving person is a moving obstacle too (``Estimate.obstacles``, the safety stop's input) once one
    #: of its detections since it started moving had motion evidence (it stood where the laser had seen
    #: free space, or the camera saw it move: furniture legs whose centres drift as the robot drives by
    #: never do), unless the body tracker already reports one within a leg pair's reach of it. Off by
    #: default: on the real recordings it adds walkers the body tracker misses but also reports on the
    #: static background (docs/estimator.md, stage 6b)
    report_moving: bool = False
    #: a person's radius as an obstacle (shoulders seen from above)
    person_radius_m: float = 0.25
    #: bound on the number of tracks (the least likely to exist go first)
    max_tracks: int = 40

    def __post_init__(self) -> None:
        probs = (self.gate_p, self.p_detect, self.p_clutter, self.exist_birth, self.exist_confirm, self.exist_drop,
                 self.moving_on, self.moving_off)
        if not all(0.0 < p < 1.0 for p in probs):
            raise ValueError("the people tracker's probabilities must lie in (0, 1)")
        if not (self.exist_drop < self.exist_birth and self.moving_off < self.moving_on):
            raise ValueError("need exist_drop < exist_birth and moving_off < moving_on")
        if min(self.leg_pair_max_m, self.pair_sigma_m, self.leg_sigma_m) <= 0.0 or self.max_tracks < 1:
            raise ValueError("need positive leg_pair_max_m, pair_sigma_m, leg_sigma_m and max_tracks >= 1")


@dataclass(frozen=True)
class PersonDetection:
    x_m: float
    y_m: float
    sigma_m: float
    p_leg: float  # the legs' highest leg probability
    legs: tuple[tuple[float, float], ...]
    scan_index_start: int
    scan_index_stop: int
    #: motion evidence of the body stage (:mod:`vipsm.bodies`: its returns lie where the laser saw free
    #: space, or the camera saw it move) on these beams
    evidence: bool = False


@dataclass
class PersonTrack:
    track_id: int
    filt: Imm
    existence: float
    stamp_s: float
    legs: tuple[tuple[float, float], ...] = ()
    moving: bool = False
    confirmed: bool = False
    hits: int = 1
    missed: int = 0
    #: a detection with motion evidence since the track last became moving
    evidence: bool = False


def detect_people(ranges_m: np.ndarray, bearings_rad: np.ndarray, laser: Pose2D, model: LegModel,
                  cfg: PeopleConfig, bodies_cfg: BodiesConfig, dropped: np.ndarray | None = None
                  ) -> list[PersonDetection]:
    """People in one pre-filtered scan (world frame, laser at ``laser``)."""
    spans = segments(ranges_m, bearings_rad, bodies_cfg, dropped)
    kept, x = segment_features(ranges_m, bearings_rad, spans, cfg.legs)
    if not kept:
        return []
    p = model.predict(x)
    thr = cfg.legs.threshold or model.threshold_p
    c, s = math.cos(laser.theta_rad), math.sin(laser.theta_rad)
    legs = []
    for (a, z, pts), q in zip(kept, p, strict=True):
        if q < thr:
            continue
        cx, cy = (float(v) for v in pts.mean(axis=0))
        d = max(math.hypot(cx, cy), 1e-6)
        lx, ly = cx + cfg.leg_radius_m * cx / d, cy + cfg.leg_radius_m * cy / d
        legs.append((laser.x_m + c * lx - s * ly, laser.y_m + s * lx + c * ly, float(q), a, z))
    return _pair(legs, cfg)


def _pair(legs: list[tuple[float, float, float, int, int]], cfg: PeopleConfig) -> list[PersonDetection]:
    pairs = sorted((math.hypot(legs[i][0] - legs[j][0], legs[i][1] - legs[j][1]), i, j)
                   for i in range(len(legs)) for j in range(i + 1, len(legs)))
    used: set[int] = set()
    out = []
    for d, i, j in pairs:
        if d > cfg.leg_pair_max_m or i in used or j in used:
            continue
        used |= {i, j}
        a, b = legs[i], legs[j]
        out.append(PersonDetection(0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), cfg.pair_sigma_m, max(a[2], b[2]),
                                   ((a[0], a[1]), (b[0], b[1])), min(a[3], b[3]), max(a[4], b[4])))
    for i, a in enumerate(legs):
        if i not in used:
            out.append(PersonDetection(a[0], a[1], cfg.leg_sigma_m, a[2], ((a[0], a[1]),), a[3], a[4]))
    return out


#: people's track ids start here, apart from the body tracker's (both appear in ``Estimate.obstacles``)
FIRST_ID = 1 << 20


class PeopleTracker:
    def __init__(self, config: PeopleConfig, model: LegModel) -> None:
        self.config = config
        self.model = model
        self.tracks: list[PersonTrack] = []
        self._next_id = FIRST_ID
        self._gate = -2.0 * math.log(1.0 - self.config.gate_p)  # chi-square, 2 dof

    def step(self, stamp_s: float, detections: list[PersonDetection], visible=None) -> None:
        """Predict every track to ``stamp_s``, associate ``detections`` (GNN), update, start tracks from
        the unassociated, and update existence. ``visible(x, y) -> bool`` (optional): whether the scan
        could have seen a person there (a miss elsewhere, e.g. behind something nearer, is no evidence)."""
        c = self.config
        for t in self.tracks:
            dt = stamp_s - t.stamp_s
            t.filt.predict(dt)
            t.stamp_s = stamp_s
            t.existence *= math.exp(-max(dt, 0.0) / c.unseen_memory_s) if dt > 0 else 1.0
        got = self._associate(detections)
        for ti, t in enumerate(self.tracks):
            if ti in got:
                d = detections[got[ti]]
                t.filt.update(np.array([d.x_m, d.y_m]), np.eye(2) * d.sigma_m**2)
                t.legs, t.hits, t.missed = d.legs, t.hits + 1, 0
                t.evidence = t.evidence or d.evidence
                t.existence = _bayes(t.existence, c.p_detect * d.p_leg, c.p_clutter * (1.0 - d.p_leg))
            else:
                t.missed += 1
                t.legs = ()
                x, y = (float(v) for v in t.filt.mean[:2])
                if visible is None or visible(x, y):
                    t.existence = _bayes(t.existence, 1.0 - c.p_detect, 1.0 - c.p_clutter)
            t.confirmed = t.confirmed or t.existence >= c.exist_confirm
            p = t.filt.p_moving
            was = t.moving
            t.moving = p >= c.moving_on or (t.moving and p >= c.moving_off)
            if t.moving and not was:  # evidence counts from the start of this walk
                t.evidence = ti in got and detections[got[ti]].evidence
        taken = set(got.values())
        for di, d in enumerate(detections):
            if di not in taken:
                self.tracks.append(PersonTrack(self._next_id, Imm(d.x_m, d.y_m, d.sigma_m, c.imm),
                                               c.exist_birth * d.p_leg / max(d.p_leg, 0.5), stamp_s, d.legs))
                self._next_id += 1
        self._prune()

    def _associate(self, detections: list[PersonDetection]) -> dict[int, int]:
        if not self.tracks or not detections:
            return {}
        big = 1e6
        cost = np.full((len(self.tracks), len(detections)), big)
        for ti, t in enumerate(self.tracks):
            mean, cov = t.filt.mean[:2], t.filt.cov[:2, :2]
            for di, d in enumerate(detections):
                y = np.array([d.x_m, d.y_m]) - mean
                s = cov + np.eye(2) * d.sigma_m**2
                m2 = float(y @ np.linalg.solve(s, y))
                if m2 <= self._gate:
                    cost[ti, di] = m2 + math.log(np.linalg.det(s))  # the likelier of two equal distances
        rows, cols = assign(cost)
        return {int(r): int(k) for r, k in zip(rows, cols, strict=True) if cost[r, k] < big}

    def _prune(self) -> None:
        c = self.config
        # lost: existence gone, or the position unknown beyond twice the reporting bound (its gate would
        # then take a detection metres away as its own)
        lost2 = (2.0 * c.max_position_sigma_m) ** 2
        alive = [t for t in self.tracks if t.existence >= c.exist_drop and np.linalg.eigvalsh(t.filt.cov[:2, :2])[-1]
                 <= lost2]
        # a duplicate: a younger track within a leg pair's half-width of an older one
        keep: list[PersonTrack] = []
        kept_xy = np.zeros((0, 2))
        for t in sorted(alive, key=lambda t: t.track_id):
            xy = t.filt.mean[:2]
            if kept_xy.size and float(np.min(np.hypot(*(kept_xy - xy).T))) < 0.5 * c.leg_pair_max_m:
                continue
            keep.append(t)
            kept_xy = np.vstack([kept_xy, xy])
        if len(keep) > c.max_tracks:
            keep = sorted(keep, key=lambda t: -t.existence)[: c.max_tracks]
        self.tracks = sorted(keep, key=lambda t: t.track_id)

    def obstacles(self, people: tuple[Person, ...], others: tuple[Obstacle, ...], laser: Pose2D
                  ) -> tuple[Obstacle, ...]:
        """The moving ``people`` as moving obstacles, but those within a leg pair's reach (plus its radius)
        of one of ``others`` (the body tracker's): the same body, reported once. The bearing interval is
        the person's radius seen from ``laser``; scan indices -1 (a track, not one scan's segment)."""
        c = self.config
        if not c.report_moving:
            return ()
        out = []
        evidence = {t.track_id for t in self.tracks if t.evidence}
        for p in people:
            near = any(math.hypot(o.x_m - p.x_m, o.y_m - p.y_m) <= o.radius_m + c.leg_pair_max_m for o in others)
            if not p.moving or p.track_id not in evidence or near:
                continue
            dx, dy = p.x_m - laser.x_m, p.y_m - laser.y_m
            b = wrap_angle(math.atan2(dy, dx) - laser.theta_rad)
            half = math.asin(min(c.person_radius_m / max(math.hypot(dx, dy), 1e-6), 1.0))
            out.append(Obstacle(p.track_id, p.x_m, p.y_m, p.vx_mps, p.vy_mps, c.person_radius_m, b - half, b + half,
                                -1, -1))
        return tuple(out)

    def people(self, stamp_s: float) -> tuple[Person, ...]:
        """The confirmed tracks at ``stamp_s`` (positions predicted at constant velocity)."""
        out = []
        for t in self.tracks:
            m, p = t.filt.mean, t.filt.cov
            if not t.confirmed or np.linalg.eigvalsh(p[:2, :2])[-1] > self.config.max_position_sigma_m**2:
                continue
            dt = stamp_s - t.stamp_s
            vx, vy = (float(m[2]), float(m[3])) if t.moving else (0.0, 0.0)
            out.append(Person(t.track_id, float(m[0] + vx * dt), float(m[1] + vy * dt), float(m[2]), float(m[3]),
                              tuple(float(v) for v in p[:2, :2].ravel()), round(t.filt.p_moving, 4), t.moving,
                              round(t.existence, 4), t.legs))
        return tuple(out)


def _bayes(prior: float, like_true: float, like_false: float) -> float:
    num = prior * like_true
    den = num + (1.0 - prior) * like_false
    return float(np.clip(num / den, 1e-4, 1.0 - 1e-4)) if den > 0.0 else prior
