"""People as people: every person-like body tracked from its first detection, walking or standing.

Each obstacle cycle (after leg_tracker, Leigh et al. ICRA 2015: legs are tracked one by one, a person
is a pair of leg tracks):

1. **legs** (:mod:`vipsm.legs`): every leg-sized segment of the pre-filtered scan gets a leg probability
   from the learned detector; those at or above its operating point are legs, placed at their returns'
   centroid pushed back by a leg's radius along the viewing ray; those below it (down to
   :func:`weak_floor`) are *weak* candidates (``weak_legs``); of two closer than a leg's diameter only the
   likelier is kept (:func:`_apart`: two legs cannot overlap);
2. **leg tracks**: global nearest neighbour (:func:`vipsm.assignment.assign`) of the legs to the leg
   tracks' predicted positions within a leg's reach in the elapsed time (``leg_step_m`` plus
   ``leg_max_speed_mps`` per second; each pair's cost its distance squared over that reach), one person's
   two legs then given their two detections by a gait's model (:meth:`PeopleTracker._one_leg_at_a_time`),
   then of the weak candidates to the person's leg tracks no leg continued (a far leg of 3 returns often
   scores below the operating point); a weak candidate alone never starts a leg track and joins no leg to a
   person (two within a stride, in no person's gate, start a person: :meth:`PeopleTracker._from_weak_pairs`),
   is weighed by its leg probability in the person's existence, and is no evidence
   that a body moves (it may be another thing's segment); a leg track unseen for ``leg_memory_s`` ends. A
   static leg's detection barely moves, so a chair's four legs are four still leg tracks whatever the
   viewpoint. A track that took a detection where something else already stood (the laser returned there
   when it last saw the place) re-locked onto that thing: its "travel" there is no motion evidence;
3. **people from leg tracks**: a person keeps its leg tracks (at most two) for as long as they live.
   Its measurement is the midpoint of its two legs (one hidden: the midpoint with where that leg's track
   predicts it, at its own velocity for up to ``leg_memory_s``, with noise growing with how far it may have
   gone since, up to a lone leg's hip's half-width; a partly hidden leg, its centre up to a leg's radius
   off, adds half that). A person short of a leg adopts the nearest free leg
   within ``leg_pair_max_m`` of its own; a person with none takes a free pair or leg in its gate; the other
   free legs pair greedily into new people. A measurement outside the person's gate frees the legs instead
   of moving the person (two legs that drifted apart are not one body);
4. **motion state** (:mod:`vipsm.imm`): per person an IMM of a standing and a walking model gives the
   velocity and P(walking); P(moving) is that times P(a body that moves), the posterior of a person
   against a static thing taken for legs, from the motion evidence of its legs (a return where the
   laser had seen free space, :mod:`vipsm.bodies`, or a leg that left a place now seen empty), expected
   on ``evidence_moving`` of a walker's detections and ``evidence_standing`` of a still body's, person or
   furniture, from how well the IMM's walking models rather than its standing model predicted a detection
   without such evidence (the kinematics), and from time standing still (a person walks on after
   ``stand_dwell_s`` on average, furniture never). A person is *moving* once P(moving) reaches
   ``moving_on`` and until it falls below ``moving_off`` (hysteresis);
5. **existence**: Bayes' rule with the detection probability ``p_detect`` of a person in view and the
   chance ``p_clutter`` that a gate holds a non-person leg (weighted by the leg probability); confirmed
   (in ``Estimate.people``) from ``exist_confirm``, dropped below ``exist_drop``. A miss counts only
   where the scan could have seen the person (a return in that direction beyond it).

Positions in the world frame (the odometry frame, placed with the matched laser pose), SI units.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .assignment import assign_gated, greedy_pairs
from .bodies import BodiesConfig, KnownLeg, segments
from .geometry import wrap_angle
from .imm import Imm, ImmConfig
from .legs import FEATURE_NAMES, LegConfig, LegModel, segment_features
from .person import PersonSize, across_beyond_m, leg_reach_m
from .types import Obstacle, Person, Pose2D


@dataclass(frozen=True)
class PeopleConfig:
    legs: LegConfig = field(default_factory=LegConfig)
    imm: ImmConfig = field(default_factory=ImmConfig)
    #: a leg's radius at the laser's height (shin): the centre lies this far behind the returns
    leg_radius_m: float = PersonSize.leg_radius_m
    #: a leg moves at most this fast (a swing leg: about twice the walking speed) ...
    leg_max_speed_mps: float = PersonSize.leg_max_speed_mps
    #: ... plus this (its centre's noise) between two detections
    leg_step_m: float = PersonSize.leg_step_m
    #: a leg track unseen this long ends (a walker's leg hidden behind the other for a stride)
    leg_memory_s: float = 0.5
    #: a leg seen this far from where it was within ``leg_memory_s`` has left its own footprint (a leg's
    #: width and its centre's drift with the viewpoint; a walker's swing leg moves 0.3-0.6 m in a swing
    #: of about 0.4 s): motion evidence, like a return where the laser saw free space. Over a short time
    #: only: a static leg's position drifts with the robot's pose error
    leg_travel_m: float = 0.2
    #: two legs of one person: centres at most this far apart (stride at the laser's height)
    leg_pair_max_m: float = PersonSize.leg_pair_max_m
    #: ... and, while it walks, at most this far apart across its line of walking: the feet swing along
    #: it a hip's width apart (0.1-0.2 m at the laser's height) plus each centre's few cm of noise. Two
    #: people walking side by side, each seen by one leg, are two people, not one person's stride
    leg_across_max_m: float = PersonSize.leg_across_max_m
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
    #: share of a walker's / a still body's detections with motion evidence (the likelihood of it): a
    #: track that walks by its kinematics but shows none is a static thing whose detections drift
    evidence_moving: float = 0.2
    evidence_standing: float = 0.02
    #: a person standing still walks on after this long on average (seconds to a minute), furniture
    #: never: each second a body stands counts against "a body that moves" by exp(-1 / this)
    stand_dwell_s: float = 10.0
    #: a track nowhere the scan could see it loses existence with this time constant (a person hidden
    #: behind another is still there for a few seconds; a false track must not live on out of sight)
    unseen_memory_s: float = 3.0
    #: a track is in ``Estimate.people`` only while its position is known to within this (one standard
    #: deviation, along its least certain direction): about a person's half-width
    max_position_sigma_m: float = 0.3
    #: moving people are moving obstacles too (``Estimate.obstacles``, the safety stop's input)
    report_moving: bool = True
    #: a person's radius as an obstacle (shoulders seen from above); two people stand at least twice
    #: this apart, so a track takes no detection further than that from its prediction
    person_radius_m: float = PersonSize.person_radius_m
    #: bound on the number of person tracks (the least likely to exist go first); leg tracks: twice it
    max_tracks: int = 40
    #: leg candidates below the detector's operating point continue existing leg tracks (weighed by their
    #: leg probability); off: such segments are dropped before the leg tracker
    weak_legs: bool = True

    def __post_init__(self) -> None:
        probs = (self.gate_p, self.p_detect, self.p_clutter, self.exist_birth, self.exist_confirm, self.exist_drop,
                 self.moving_on, self.moving_off, self.evidence_moving, self.evidence_standing)
        if not all(0.0 < p < 1.0 for p in probs):
            raise ValueError("the people tracker's probabilities must lie in (0, 1)")
        if not (self.exist_drop < self.exist_birth and self.moving_off < self.moving_on):
            raise ValueError("need exist_drop < exist_birth and moving_off < moving_on")
        if min(self.leg_pair_max_m, self.pair_sigma_m, self.leg_sigma_m, self.leg_step_m,
               self.leg_memory_s, self.leg_max_speed_mps, self.leg_travel_m, self.leg_across_max_m) <= 0.0 \
                or self.max_tracks < 1:
            raise ValueError("need positive leg and pair sizes, noises, leg speed and memory, and max_tracks >= 1")
        if not self.stand_dwell_s > 0.0:
            raise ValueError(f"stand_dwell_s must be > 0 (a person's mean standing time), got {self.stand_dwell_s}")


@dataclass(frozen=True)
class LegDetection:
    x_m: float
    y_m: float
    p_leg: float
    scan_index_start: int
    scan_index_stop: int
    #: motion evidence of the body stage (:mod:`vipsm.bodies`: its returns lie where the laser saw free
    #: space, or the camera saw it move) on these beams
    evidence: bool = False
    #: a nearer return right beside it: only part of it is seen, and its centre moves with the edge of
    #: what hides it (a wall piece behind a table leg slides along the wall as the robot drives by)
    occluded: bool = False
    #: below the detector's operating point: a leg candidate only, weighed by ``p_leg`` (it may continue a
    #: leg track within its reach; alone it starts no leg track and no person)
    weak: bool = False


@dataclass
class LegTrack:
    leg_id: int
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    seen_s: float
    #: this cycle's detection (None: unseen)
    det: LegDetection | None = None
    #: (stamp_s, x_m, y_m) of its detections over the last ``PeopleConfig.leg_memory_s``
    path: list[tuple[float, float, float]] = field(default_factory=list)
    #: how far its newest detection lies from the furthest of ``path``, and that point
    travel_m: float = 0.0
    left_xy: tuple[float, float] = (0.0, 0.0)
    #: it arrived where it stands now at a place where something else already stood (the laser returned
    #: there when it last saw the place, before this track came): it re-locked onto that thing
    arrived_held: bool = False
    #: it has left its footprint (:meth:`PeopleTracker._travelled`) at its newest detection
    travelled: bool = False
    #: a step not yet weighed for a person: it left its footprint at a detection after one where it had not
    #: (counted once, however long the leg stays ``leg_travel_m`` from where it stood; a free leg's step is
    #: weighed for the person that takes it while it has not landed back)
    stepped: bool = False

    def seen(self, stamp_s: float, det: LegDetection, window_s: float) -> None:
        self.x_m, self.y_m, self.seen_s, self.det = det.x_m, det.y_m, stamp_s, det
        self.path = [p for p in self.path if stamp_s - p[0] <= window_s] + [(stamp_s, det.x_m, det.y_m)]
        self.travel_m, self.left_xy = max((math.hypot(det.x_m - x, det.y_m - y), (x, y)) for _, x, y in self.path)

    def predicted(self, stamp_s: float, cap_s: float) -> tuple[float, float]:
        dt = min(max(stamp_s - self.seen_s, 0.0), cap_s)
        return self.x_m + self.vx_mps * dt, self.y_m + self.vy_mps * dt


@dataclass
class PersonTrack:
    track_id: int
    filt: Imm
    existence: float
    stamp_s: float
    leg_ids: list[int] = field(default_factory=list)
    legs: tuple[tuple[float, float], ...] = ()
    moving: bool = False
    confirmed: bool = False
    #: probability that it is a body that moves at all (a person), not a static thing taken for legs; a new
    #: track's from the legs it is born of (:func:`_born_dynamic`)
    p_dynamic: float = 0.5
    #: obstacle cycles the track has lived (``Obstacle.age_cycles`` of a moving person)
    age_cycles: int = 1
    #: when a detection last updated it (None: never)
    updated_s: float | None = None
    #: seen this cycle by a leg the detector took, or by weak candidates while its existence stays at
    #: ``exist_confirm`` or above, or by no leg but the laser returned where it stands while it stays so sure
    #: (``PeopleTracker._missed``): only then is a moving person a moving obstacle (weak candidates alone may
    #: be other things' segments: they are believed only for a person they do not make doubtful)
    leg_seen: bool = False
    #: the share of its position estimate that lone-leg detections made since its last pair (their
    #: position gains compounded): how much of a lone leg's offset from the body the estimate carries
    lone_share: float = 0.0

    @property
    def p_moving(self) -> float:
        """P(moving): a body that moves (``p_dynamic``), walking now (the IMM's walking models)."""
        return self.p_dynamic * self.filt.p_moving


def detect_legs(ranges_m: np.ndarray, bearings_rad: np.ndarray, laser: Pose2D, model: LegModel,
                cfg: PeopleConfig, bodies_cfg: BodiesConfig, dropped: np.ndarray | None = None) -> list[LegDetection]:
    """Leg candidates in one pre-filtered scan (world frame, laser at ``laser``): the segments at or above
    the detector's operating point are legs, those below it ``weak`` candidates (a far leg of 3 returns
    often scores below it, and so does a near leg seen edge-on for a scan) unless ``p_leg`` says less for a
    leg than no detection at all would (:func:`weak_floor`)."""
    spans = segments(ranges_m, bearings_rad, bodies_cfg, dropped)
    kept, x = segment_features(ranges_m, bearings_rad, spans, cfg.legs)
    if not kept:
        return []
    p = model.predict(x)
    thr = cfg.legs.threshold or model.threshold_p
    floor = weak_floor(cfg) if cfg.weak_legs else thr
    c, s = math.cos(laser.theta_rad), math.sin(laser.theta_rad)
    # how far the returns beside each segment lie behind it (negative: in front): nearer on both sides
    # is background seen between two things, nearer on one side a partly hidden segment
    front = x[:, [FEATURE_NAMES.index("front_left_m"), FEATURE_NAMES.index("front_right_m")]]
    nearer = front < -bodies_cfg.foreground_m
    legs = []
    for (a, z, pts), q, near in zip(kept, p, nearer, strict=True):
        if q < floor or near.all():
            continue
        cx, cy = (float(v) for v in pts.mean(axis=0))
        d = max(math.hypot(cx, cy), 1e-6)
        lx, ly = cx + cfg.leg_radius_m * cx / d, cy + cfg.leg_radius_m * cy / d
        legs.append(LegDetection(laser.x_m + c * lx - s * ly, laser.y_m + s * lx + c * ly, float(q), a, z,
                                 occluded=bool(near.any()), weak=bool(q < thr)))
    return _apart(legs, 2.0 * cfg.leg_radius_m)


def _apart(legs: list[LegDetection], diameter_m: float) -> list[LegDetection]:
    """Two legs cannot stand closer than a leg's diameter (centre to centre): of two candidates closer than
    that, at most one is a leg, the other a piece of the same thing (a leg's segment split at one noisy
    return). The likelier leg stays; the piece would otherwise continue another leg track, a hidden leg's,
    that then stands beside its partner."""
    kept: list[LegDetection] = []
    for d in sorted(legs, key=lambda d: -d.p_leg):
        if all(math.hypot(d.x_m - k.x_m, d.y_m - k.y_m) >= diameter_m for k in kept):
            kept.append(d)
    return sorted(kept, key=lambda d: d.scan_index_start)


def weak_floor(cfg: PeopleConfig) -> float:
    """The least leg probability with which a candidate below the operating point still counts for a person
    rather than against it: where its likelihood ratio in the existence update (``p_detect`` p against
    ``p_clutter`` (1 - p); the detector's forest is trained with balanced classes, so p / (1 - p) is the
    ratio of the two classes' score densities) equals a miss's ((1 - ``p_detect``) against
    (1 - ``p_clutter``)). Below it the segment is no detection of a leg at all: a miss says more for the
    person than it does."""
    miss = (1.0 - cfg.p_detect) / (1.0 - cfg.p_clutter)
    odds = miss * cfg.p_clutter / cfg.p_detect
    return odds / (1.0 + odds)


#: a yes/no question about a world point (x_m, y_m) asked of this cycle's scan
PointTest = Callable[[float, float], bool]

#: from this speed on the velocity gives a walker's line of walking (a standing person's legs and centre
#: wander by a few cm/s; the slowest walk is about 0.3 m/s)
WALK_DIR_MPS = 0.3

#: people's track ids start here, apart from the body tracker's (both appear in ``Estimate.obstacles``)
FIRST_ID = 1 << 20


class PeopleTracker:
    def __init__(self, config: PeopleConfig, model: LegModel) -> None:
        self.config = config
        self.model = model
        self.tracks: list[PersonTrack] = []
        self.legs: dict[int, LegTrack] = {}
        self._next_id = FIRST_ID
        self._next_leg = 0
        self._gate = -2.0 * math.log(1.0 - self.config.gate_p)  # chi-square, 2 dof
        self._seen_free: PointTest | None = None
        self._seen_before: PointTest | None = None
        self._visible: PointTest | None = None
        self._stood_before: PointTest | None = None
        #: this cycle's weak candidates no leg track took (:meth:`_from_weak_pairs`)
        self._unclaimed_weak: list[LegDetection] = []

    # ------------------------------------------------------------------ one cycle
    def step(self, stamp_s: float, detections: list[LegDetection], visible: PointTest | None = None,
             seen_free: PointTest | None = None, stood_before: PointTest | None = None,
             occupied: PointTest | None = None, seen_before: PointTest | None = None) -> None:
        """Predict every person to ``stamp_s``, track the legs ``detections``, measure each person from
        its legs, start people from free legs, update existence and motion state. ``visible(x, y) ->
        bool`` (optional): whether the scan could have seen a person there (a miss elsewhere, e.g.
        behind something nearer, is no evidence). ``seen_free(x, y) -> bool`` (optional): the scan saw
        through that point: a leg that travelled counts as motion evidence only when the place it left
        is seen empty (a leg track that hopped to a neighbouring table leg left one standing there).
        ``stood_before(x, y) -> bool`` (optional): something stood at that leg position when the laser
        last saw it before this scan: a leg track that arrived where something else already stood
        re-locked onto it and did not travel (:meth:`_judge_arrival`). ``occupied(x, y) -> bool`` (optional): the
        scan returned from within a person's radius of that point (:meth:`_missed`). ``seen_before(x, y) ->
        bool`` (optional): a scan of the last ``leg_memory_s`` before this one saw through the front of a leg
        centred there: a leg that travelled counts as motion evidence also when it came to such a place
        (:meth:`_travelled`)."""
        c = self.config
        self._seen_free = seen_free
        self._seen_before = seen_before
        self._stood_before = stood_before
        for t in self.tracks:
            dt = stamp_s - t.stamp_s
            t.filt.predict(dt)
            t.stamp_s = stamp_s
            t.age_cycles += 1
            if dt > 0:
                t.existence *= math.exp(-dt / c.unseen_memory_s)
        self._track_legs(stamp_s, detections)
        self._split()
        self._beyond_stride()
        self._two_pairs()
        self._adopt(stamp_s)
        seen: set[int] = set()
        self._visible = visible
        for t in self.tracks:
            z = self._measurement(t)
            if z is not None and self._in_gate(t, z[0], z[1]):
                self._update(t, z)
                seen.add(t.track_id)
            elif z is not None and self._own_legs_seen(t):
                # its two legs, each followed as a leg, left the person's gate together: the motion models
                # lost a start or a stop faster than they allow, not the person (its legs are its identity).
                # Its motion state starts again there, known to the reporting bound until the measurement
                t.filt, t.lone_share = Imm(z[0], z[1], c.max_position_sigma_m, c.imm), 0.0
                self._update(t, z)
                seen.add(t.track_id)
            elif z is not None:  # legs that drifted apart from the body: free them
                self._release(t)
        for t in self._from_free_legs(stamp_s) + self._from_weak_pairs(stamp_s):
            seen.add(t.track_id)
        for t in self.tracks:
            if t.track_id not in seen:
                self._missed(t, visible, occupied)
            t.confirmed = t.confirmed or t.existence >= c.exist_confirm
            p = t.p_moving
            t.moving = p >= c.moving_on or (t.moving and p >= c.moving_off)
        self._prune()

    def _missed(self, t: PersonTrack, visible: PointTest | None, occupied: PointTest | None) -> None:
        """A person no leg of whom was detected this cycle. Where the scan could have seen it, that is a miss
        against its existence. It is still seen (``PersonTrack.leg_seen``: a moving person stays a moving
        obstacle) while it surely exists (``exist_confirm``) and the laser returned from where it stands
        (``occupied``): the detector missed the legs of a body that is there (a walker's legs merged into one
        segment, or scored under the operating point for a scan). A person whose place the laser saw through,
        or could not see, is no obstacle until a leg is seen again."""
        c = self.config
        x, y = (float(v) for v in t.filt.mean[:2])
        in_view = visible is None or visible(x, y)
        if in_view:
            t.existence = _bayes(t.existence, 1.0 - c.p_detect, 1.0 - c.p_clutter)
        t.legs = ()
        t.leg_seen = t.existence >= c.exist_confirm and in_view and occupied is not None and occupied(x, y)

    # ------------------------------------------------------------------ legs
    def _track_legs(self, stamp_s: float, detections: list[LegDetection]) -> None:
        c = self.config
        tracks = list(self.legs.values())
        for lt in tracks:
            lt.det = None
        # legs first; a weak candidate only continues a person's leg track that no leg continued (it never
        # displaces a leg, and a free leg track, no person's, is not kept alive by it)
        strong = [j for j, d in enumerate(detections) if not d.weak]
        got = self._associate(stamp_s, tracks, detections, strong)
        owned = {k for t in self.tracks for k in t.leg_ids}
        rest = [i for i, lt in enumerate(tracks) if i not in got and lt.leg_id in owned]
        weak = [j for j, d in enumerate(detections) if d.weak]
        got |= {rest[i]: j for i, j in self._associate(stamp_s, [tracks[i] for i in rest], detections, weak).items()}
        partner = {a: b for t in self.tracks if len(t.leg_ids) == 2 for a, b in (t.leg_ids, t.leg_ids[::-1])}
        for i, j in got.items():
            lt, d = tracks[i], detections[j]
            self._judge_arrival(stamp_s, lt, d, self.legs.get(partner.get(lt.leg_id, -1)))
            dt = stamp_s - lt.seen_s
            if dt > 0:  # velocity: half the last one, half this step's (a leg's speed changes every stride)
                vmax = c.leg_max_speed_mps
                lt.vx_mps = 0.5 * lt.vx_mps + 0.5 * float(np.clip((d.x_m - lt.x_m) / dt, -vmax, vmax))
                lt.vy_mps = 0.5 * lt.vy_mps + 0.5 * float(np.clip((d.y_m - lt.y_m) / dt, -vmax, vmax))
            lt.seen(stamp_s, d, c.leg_memory_s)
            before, lt.travelled = lt.travelled, self._travelled(lt)
            lt.stepped = lt.travelled and (lt.stepped or not before)
        taken = set(got.values())
        self._unclaimed_weak = [d for j, d in enumerate(detections) if j not in taken and d.weak]
        for j, d in enumerate(detections):
            if j not in taken and not d.weak:
                self._new_leg_track(stamp_s, d)
        gone = {k for k, lt in self.legs.items() if stamp_s - lt.seen_s > c.leg_memory_s}
        if len(self.legs) - len(gone) > 2 * c.max_tracks:  # the longest unseen go first
            alive = sorted((lt for k, lt in self.legs.items() if k not in gone), key=lambda lt: -lt.seen_s)
            gone |= {lt.leg_id for lt in alive[2 * c.max_tracks :]}
        for k in gone:
            del self.legs[k]
        for t in self.tracks:
            t.leg_ids = [k for k in t.leg_ids if k in self.legs]

    def _new_leg_track(self, stamp_s: float, d: LegDetection) -> LegTrack:
        lt = LegTrack(self._next_leg, d.x_m, d.y_m, 0.0, 0.0, stamp_s)
        lt.seen(stamp_s, d, self.config.leg_memory_s)
        self.legs[self._next_leg] = lt
        self._next_leg += 1
        return lt

    def _associate(self, stamp_s: float, tracks: list[LegTrack], detections: list[LegDetection], cols: list[int]
                   ) -> dict[int, int]:
        """Global nearest neighbour of the leg tracks to the detections ``cols`` within each track's reach
        (``leg_step_m`` plus ``leg_max_speed_mps`` over the time since it was seen): track index -> detection
        index. Each pair costs its distance squared over the track's reach (a Gaussian's negative
        log-likelihood, the reach its scale): summed distances let a track whose own leg went unseen jump
        past another body's leg onto a far detection while that body's track takes a worse one (side-by-side
        walkers' tracks swapping legs); one person's two legs are judged by a gait's model after
        (:meth:`_one_leg_at_a_time`)."""
        c = self.config
        if not tracks or not cols:
            return {}
        cost = np.full((len(tracks), len(cols)), np.inf)
        for i, lt in enumerate(tracks):
            px, py = lt.predicted(stamp_s, c.leg_memory_s)
            reach = self._reach_m(lt, stamp_s)
            for k, j in enumerate(cols):
                dist = math.hypot(detections[j].x_m - px, detections[j].y_m - py)
                if dist <= reach:
                    cost[i, k] = (dist / reach) ** 2
        got = {i: cols[k] for i, k in assign_gated(cost).items()}
        self._one_leg_at_a_time(stamp_s, tracks, detections, got)
        return got

    def _one_leg_at_a_time(self, stamp_s: float, tracks: list[LegTrack], detections: list[LegDetection],
                           got: dict[int, int]) -> None:
        """Which of one person's two leg tracks took which of two detections, by a gait's model (in place in
        ``got``): the association's cost, a leg's squared distance over its reach, keeps each track off
        another person's leg, but between one person's two legs it prefers both moving half as far to one
        standing and one swinging, and a gait moves one leg at a time. So of the two ways to give the two
        detections to the person's two legs, the likelier under :func:`_leg_cost` (each leg standing or
        swinging, even odds) is kept, where both lie within both legs' reach."""
        index = {lt.leg_id: i for i, lt in enumerate(tracks)}
        for t in self.tracks:
            if len(t.leg_ids) != 2 or not all(k in index and index[k] in got for k in t.leg_ids):
                continue
            a, b = (tracks[index[k]] for k in t.leg_ids)
            da, db = (detections[got[index[k]]] for k in t.leg_ids)
            if (self._gait_cost(stamp_s, a, db) + self._gait_cost(stamp_s, b, da)
                    < self._gait_cost(stamp_s, a, da) + self._gait_cost(stamp_s, b, db)):
                ia, ib = (index[k] for k in t.leg_ids)
                got[ia], got[ib] = got[ib], got[ia]

    def _gait_cost(self, stamp_s: float, lt: LegTrack, d: LegDetection) -> float:
        """:func:`_leg_cost` of leg track ``lt`` taking detection ``d`` (inf beyond its reach)."""
        c = self.config
        px, py = lt.predicted(stamp_s, c.leg_memory_s)
        dist, reach = math.hypot(d.x_m - px, d.y_m - py), self._reach_m(lt, stamp_s)
        return _leg_cost(dist, reach, 0.5 * c.leg_step_m) if dist <= reach else math.inf

    def _reach_m(self, lt: LegTrack, stamp_s: float) -> float:
        """How far leg track ``lt``'s leg may be from its prediction at ``stamp_s``: ``leg_step_m`` plus
        ``leg_max_speed_mps`` over the time since it was seen (the leg association's gate)."""
        return leg_reach_m(self.config, stamp_s - lt.seen_s)

    def _one_body(self, a: tuple[float, float], b: tuple[float, float], v: tuple[float, float]) -> bool:
        """Two leg centres ``a``, ``b`` can be one person's whose body moves at velocity ``v``: within a
        stride (``leg_pair_max_m``) and, once it walks (from ``WALK_DIR_MPS``), within
        ``leg_across_max_m`` across its line of walking (the feet swing along that line)."""
        c = self.config
        dx, dy = b[0] - a[0], b[1] - a[1]
        if math.hypot(dx, dy) > c.leg_pair_max_m:
            return False
        speed = math.hypot(*v)
        return speed < WALK_DIR_MPS or abs(dx * v[1] - dy * v[0]) / speed <= c.leg_across_max_m

    def _split(self) -> None:
        """A walking person whose two legs, both seen this cycle, lay side by side across its line of
        walking (further apart than ``leg_across_max_m``) in each of at least 3 of their common detections
        of the last ``leg_memory_s`` holds two people's legs (two walkers side by
        side, each seen by one leg, paired when neither had a velocity yet): it keeps the leg nearer its
        prediction and frees the other. A hidden leg's predicted place is no measurement: not judged."""
        for t in self.tracks:
            legs = [self.legs[k] for k in t.leg_ids]
            if len(legs) != 2 or any(lt.det is None for lt in legs):
                continue
            # over the legs' common detections of the last ``leg_memory_s`` (about a stride): a walker's
            # swing leg steps aside of its line only briefly, two walkers' legs stay side by side
            a_at = {round(st, 3): (x, y) for st, x, y in legs[0].path}
            common = [(a_at[round(st, 3)], (x, y)) for st, x, y in legs[1].path if round(st, 3) in a_at]
            if len(common) < 3 or any(self._across_ok(t, bx - ax, by - ay) for (ax, ay), (bx, by) in common):
                continue
            _keep_nearer(t, legs)

    def _beyond_stride(self) -> None:
        """A person whose two legs, both seen this cycle, lie further apart than a stride (``leg_pair_max_m``)
        holds a leg that is not its own: a leg track unseen for a while reaches far (``leg_max_speed_mps`` per
        second) and may take a neighbour's leg, and the person's gate, wide while its walking models are
        unsure of the velocity, may still hold the midpoint. It keeps the leg nearer its prediction and frees
        the other (which may start or join another person)."""
        for t in self.tracks:
            legs = [self.legs[k] for k in t.leg_ids]
            if len(legs) != 2 or any(lt.det is None for lt in legs):
                continue
            if math.hypot(legs[0].x_m - legs[1].x_m, legs[0].y_m - legs[1].y_m) <= self.config.leg_pair_max_m:
                continue
            _keep_nearer(t, legs)

    def _two_pairs(self) -> None:
        """Two walkers side by side are four legs in a row across their line of walking, a hip's width
        apart: the two middle legs (one of each walker's) are as close as one person's. A walking person
        holding both middle legs, flanked by two people each holding one seen leg (an outer one), explains
        the four seen legs with three people, two of whom have a leg hidden while every leg is seen; two
        people with two legs each explain them with none hidden. So each flanking person takes the middle
        leg on its side where both new pairs can be one body's (:meth:`_one_body` at its velocity, the new
        midpoint in its gate), and the person in the middle, built from two people's legs, ends."""
        taken: set[int] = set()  # people changed this cycle
        for t in self.tracks:
            legs = [self.legs[k] for k in t.leg_ids]
            if t.track_id in taken or len(legs) != 2 or any(lt.det is None for lt in legs) \
                    or _line_of_walking(t) is None:
                continue
            flanks = self._flanks(t, legs, taken)
            if flanks is None:
                continue
            for flank, leg in flanks:
                flank.leg_ids.append(leg.leg_id)
                taken.add(flank.track_id)
            t.leg_ids = []
            taken.add(t.track_id)
        self.tracks = [t for t in self.tracks if t.leg_ids or t.track_id not in taken]

    def _flanks(self, t: PersonTrack, legs: list[LegTrack], taken: set[int]
                ) -> tuple[tuple[PersonTrack, LegTrack], tuple[PersonTrack, LegTrack]] | None:
        """For the walking person ``t`` holding ``legs``: two other people, each with one leg track, seen
        this cycle, that each pair with a different one of ``legs`` into one body's legs (of several such, the two
        whose own legs lie nearest); None where there are no such two."""
        c = self.config
        singles = [o for o in self.tracks if o is not t and o.track_id not in taken and len(o.leg_ids) == 1
                   and self.legs[o.leg_ids[0]].det is not None]
        fits: list[list[tuple[float, PersonTrack]]] = [[], []]  # per leg: (distance to its own leg, person)
        for o in singles:
            own = self.legs[o.leg_ids[0]]
            v = (float(o.filt.mean[2]), float(o.filt.mean[3]))
            for i, lt in enumerate(legs):
                if self._one_body((own.x_m, own.y_m), (lt.x_m, lt.y_m), v) and self._in_gate(
                        o, 0.5 * (own.x_m + lt.x_m), 0.5 * (own.y_m + lt.y_m), c.pair_sigma_m):
                    fits[i].append((math.hypot(own.x_m - lt.x_m, own.y_m - lt.y_m), o))
        options = [(da + db, a, b) for da, a in fits[0] for db, b in fits[1] if a is not b]
        if not options:
            return None
        _, a, b = min(options, key=lambda option: option[0])
        return (a, legs[0]), (b, legs[1])

    def _across_ok(self, t: PersonTrack, dx: float, dy: float) -> bool:
        """Two legs ``(dx, dy)`` apart can be the walking person ``t``'s: not walking (slower than
        ``WALK_DIR_MPS``), or within ``leg_across_max_m`` across its line of walking, widened by how
        uncertain that line is (the velocity's sigma across it over the speed, times the legs' separation
        along it, two sigma: a walker turning or stepping aside)."""
        line = _line_of_walking(t)
        if line is None:
            return True
        return across_beyond_m(dx, dy, *line) <= self.config.leg_across_max_m

    def _free(self) -> list[LegTrack]:
        """Leg tracks seen this cycle that belong to nobody, by a leg (a weak candidate continues a leg track
        and its place in a person, but joins no leg to a person: that would be a new pairing on a segment
        the detector did not take for a leg)."""
        owned = {k for t in self.tracks for k in t.leg_ids}
        return [lt for k, lt in self.legs.items() if k not in owned and lt.det is not None and not lt.det.weak]

    def _adopt(self, stamp_s: float) -> None:
        """A person with one leg takes the nearest free leg within a leg pair's reach of it whose
        midpoint with it lies in the person's gate."""
        c = self.config
        for t in self.tracks:
            if len(t.leg_ids) != 1:
                continue
            own = self.legs[t.leg_ids[0]]
            ox, oy = own.predicted(stamp_s, c.leg_memory_s)
            v = (float(t.filt.mean[2]), float(t.filt.mean[3]))
            best = None
            for lt in self._free():
                d = math.hypot(lt.x_m - ox, lt.y_m - oy)
                if self._one_body((ox, oy), (lt.x_m, lt.y_m), v) and self._in_gate(
                        t, 0.5 * (lt.x_m + ox), 0.5 * (lt.y_m + oy), c.pair_sigma_m):
                    if best is None or d < best[0]:
                        best = (d, lt)
            if best is not None:
                t.leg_ids.append(best[1].leg_id)

    def _measurement(self, t: PersonTrack) -> tuple[float, float, float, list[LegTrack]] | None:
        """(x, y, sigma, the legs seen) from the person's legs this cycle; None when none was seen. A
        hidden leg of the pair is where its track predicts it (a standing leg where it was seen; its
        noise grows with how far it may have gone since), or where it was seen if it re-locked onto a thing
        standing there; a partly hidden leg adds half a leg's radius
        (:meth:`_midpoint_sigma`); a person of one leg is that leg, known to a hip's half-width, and so is a
        pair with a leg that may have re-locked onto another thing (``LegTrack.arrived_held``) and is not
        seen in full as a leg."""
        c = self.config
        legs = [self.legs[k] for k in t.leg_ids]
        seen = [lt for lt in legs if lt.det is not None]
        if not seen:
            return None
        hidden = [lt for lt in legs if lt.det is None]
        if len(seen) == 1 and not hidden:
            return seen[0].x_m, seen[0].y_m, c.leg_sigma_m, seen
        a = seen[0]
        if hidden:
            h = hidden[0]
            if h.arrived_held:  # re-locked onto a thing standing there: its velocity measured the jump, no swing
                (bx, by), gone = (h.x_m, h.y_m), 0.0
            else:
                bx, by = h.predicted(t.stamp_s, c.leg_memory_s)
                gone = math.hypot(h.vx_mps, h.vy_mps) * min(max(t.stamp_s - h.seen_s, 0.0), c.leg_memory_s)
            sigma = min(math.hypot(c.pair_sigma_m, 0.5 * gone), c.leg_sigma_m)
        else:
            bx, by = seen[1].x_m, seen[1].y_m
            sigma = c.pair_sigma_m
        return 0.5 * (a.x_m + bx), 0.5 * (a.y_m + by), self._midpoint_sigma(sigma, legs), seen

    def _midpoint_sigma(self, sigma_m: float, legs: list[LegTrack]) -> float:
        """The noise of the midpoint of a pair's ``legs`` (seen this cycle or predicted), ``sigma_m`` with both
        seen in full: a partly hidden leg's centre lies up to a leg's radius off (where its hidden part is),
        half that in the midpoint; and a leg track that arrived where something already stood may have
        re-locked onto that thing (:meth:`_judge_arrival`): unless its detection vouches for a leg (seen in
        full, at the operating point), the pair places the person no better than a lone leg does."""
        c = self.config
        if any(lt.arrived_held and (lt.det is None or lt.det.weak or lt.det.occluded) for lt in legs):
            return max(sigma_m, c.leg_sigma_m)
        occluded = sum(lt.det is not None and lt.det.occluded for lt in legs)
        return math.hypot(sigma_m, 0.5 * c.leg_radius_m * math.sqrt(occluded))

    def _in_gate(self, t: PersonTrack, x: float, y: float, sigma_m: float | None = None,
                 likelier: tuple[np.ndarray, np.ndarray] | None = None) -> bool:
        """Within the gate of the models' combination, or of ``likelier`` (:func:`_likelier_state`: for a person
        no leg of whom is left, found again)."""
        r = np.eye(2) * (sigma_m or self.config.pair_sigma_m) ** 2
        z = np.array([x, y])
        models = [(t.filt.mean, t.filt.cov)] + ([likelier] if likelier is not None else [])
        for mean, cov in models:
            dv = z - mean[:2]
            if math.hypot(*dv) <= 2.0 * self.config.person_radius_m and \
                    float(dv @ np.linalg.solve(cov[:2, :2] + r, dv)) <= self._gate:
                return True
        return False

    def _update(self, t: PersonTrack, z: tuple[float, float, float, list[LegTrack]]) -> None:
        c = self.config
        x, y, sigma, seen = z
        walks = self._walking_share(t)  # predicted: before this detection
        self._lone_offset(t, sigma)
        t.filt.update(np.array([x, y]), np.eye(2) * sigma**2)
        # a body that moves or a static thing: the evidence's rates and the time standing (``_walking_share``);
        # only time seen counts as time standing (at most a leg's memory between detections)
        share = self._walking_share(t)
        legs = [lt for lt in seen if not lt.det.weak]
        p_leg = max(lt.det.p_leg for lt in legs or seen)
        dt = min(t.stamp_s - t.updated_s, c.leg_memory_s) if t.updated_s is not None else 0.0
        stayed = math.exp(-(1.0 - share) * max(dt, 0.0) / c.stand_dwell_s)
        if legs:
            # motion evidence and kinematics from the detector's legs alone: a weak candidate may be another
            # thing's segment (a wall piece sliding by as the robot drives, a table leg beside the track), and
            # a midpoint with one jumps: it tells nothing of whether the body moves
            ev = any(lt.det.evidence or lt.travelled for lt in legs)
            e_dyn = c.evidence_standing + share * (c.evidence_moving - c.evidence_standing)
            # the kinematics as evidence too; motion evidence measures the same displacement: counted once. A
            # partly hidden leg's centre moves with the edge of what hides it, and a leg track that arrived where
            # something else stood may have re-locked onto that thing (``_judge_arrival``): the move of either is
            # no such evidence
            drifts = len(legs) < len(seen) or any(lt.det.occluded or lt.arrived_held for lt in seen)
            kin_dyn, kin_static = (1.0, 1.0) if ev or drifts else self._kinematic_likelihoods(t, walks, 1.0 - p_leg)
            t.p_dynamic = _bayes(t.p_dynamic, (e_dyn if ev else 1.0 - e_dyn) * stayed * kin_dyn,
                                 (c.evidence_standing if ev else 1.0 - c.evidence_standing) * kin_static)
            # a gait steps one leg at a time, the other standing: two legs of one "person" leaving their
            # footprints together are two walkers' legs (side by side, paired before either had a velocity)
            steps = [lt for lt in legs if lt.stepped]
            if len(steps) == 1 and not any(lt.travelled for lt in seen if lt is not steps[0]):
                # a step, given a person: a walker's legs step on ``evidence_moving`` of its detections, a
                # standing person's as rarely as a still thing's. A detection without a step says little: most
                # of a walker's cannot show one (the leg half hidden, the place it left not seen, a step shorter
                # than a footprint), so only a step is weighed. It is the early cue of a start: the swing leg
                # has left its footprint while the legs' midpoint has moved a few cm
                t.filt.weigh_walking(c.evidence_moving, c.evidence_standing)
            for lt in steps:  # a step is judged once, for the person that holds the leg when it is seen
                lt.stepped = False
        else:
            t.p_dynamic = _bayes(t.p_dynamic, stayed, 1.0)
        t.updated_s = t.stamp_s
        t.existence = _bayes(t.existence, c.p_detect * p_leg, c.p_clutter * (1.0 - p_leg))
        t.legs, t.leg_seen = tuple((lt.x_m, lt.y_m) for lt in seen), bool(legs) or t.existence >= c.exist_confirm

    def _lone_offset(self, t: PersonTrack, sigma_m: float) -> None:
        """Before ``t``'s update with a measurement of noise ``sigma_m``: a lone leg stands up to a hip's
        half-width off the body, an offset all its detections share (not white noise: their number shrinks it out
        of the covariance, and the estimate drifts onto the leg). ``lone_share`` compounds their position gains
        (how much of the estimate they made); the first pair after them reveals the part of the offset the
        estimate took, every model's position variance widened by it: a jump of the reference, no walk."""
        if len(t.leg_ids) == 1:
            p = 0.5 * float(np.trace(t.filt.cov[:2, :2]))
            t.lone_share += p / (p + sigma_m**2) * (1.0 - t.lone_share)
        elif t.lone_share > 0.0:
            t.filt.widen_position((t.lone_share * self.config.leg_sigma_m) ** 2)
            t.lone_share = 0.0

    def _kinematic_likelihoods(self, t: PersonTrack, walks: float, other: float) -> tuple[float, float]:
        """This detection's likelihood under "a body that moves" and under "a static thing", from the IMM's
        own models (their predictive densities at the measurement, :attr:`Imm.likelihoods`): a static thing's
        detection lies where the standing model predicts it; a person's where the walking models predict it
        with probability ``walks`` (P(walking at a walking speed) before this detection,
        :meth:`_walking_share`) and where the standing model does otherwise. Under either it may be another
        thing's detection (probability ``other``: one less the detector's leg probability), anywhere in the
        gate's largest disc (twice ``person_radius_m``): a leg track that hops to a neighbouring thing once
        says little, a walk whose detections keep landing where the walking models predict them says "a
        body that moves". A standing person and a static thing explain a still detection alike: standing
        costs nothing here (that is ``stand_dwell_s``'s)."""
        c = self.config
        like = t.filt.likelihoods
        if like is None:
            return 1.0, 1.0
        floor = other / (math.pi * (2.0 * c.person_radius_m) ** 2)
        still = float(like[0])
        moves = (1.0 - walks) * still + walks * t.filt.walking_likelihood()
        return floor + (1.0 - other) * moves, floor + (1.0 - other) * still

    def _walking_share(self, t: PersonTrack) -> float:
        """P(the track walks at a walking speed): the IMM's P(walking), times how much of the slowest walk
        (``WALK_DIR_MPS``) its walking models' speed is. Motion evidence comes from displacement (a body
        standing where the laser saw free space, a leg that left its place), so P(evidence | a body that
        moves) is a walker's ``evidence_moving`` with this probability and a still body's
        ``evidence_standing`` otherwise: a person standing still shows evidence as rarely as furniture.
        (The IMM's P(walking) alone is no measure of it: its walking models fit a standing person at zero
        speed, and P(walking) hovers at 0.2, which counted every detection of a standing person against
        "a body that moves".) What tells a standing person from furniture is time: a person standing still
        walks on after ``stand_dwell_s`` on average, a static thing never, so every second a body stands
        still counts against "a body that moves" by exp(-1 / stand_dwell_s): seconds of standing hardly,
        minutes of it for furniture."""
        v = t.filt.walking()[0][2:4]
        return t.filt.p_moving * min(float(math.hypot(v[0], v[1])) / WALK_DIR_MPS, 1.0)

    def _travelled(self, lt: LegTrack) -> bool:
        """The leg, seen in full, is ``leg_travel_m`` from where it was within ``leg_memory_s``, that place
        is seen empty now or the place it came to was seen through by a recent scan (a leg walking towards
        the laser hides the place it left in its own shadow; the place it came to, in front, the laser saw
        through a moment ago), and it arrived where nothing stood before (:meth:`_arrived`)."""
        if lt.travel_m < self.config.leg_travel_m or lt.det is None or lt.det.occluded:
            return False
        if not self._arrived(lt):
            return False
        if self._seen_free is None or self._seen_free(*lt.left_xy):
            return True
        return self._seen_before is not None and bool(self._seen_before(lt.x_m, lt.y_m))

    def _arrived(self, lt: LegTrack) -> bool:
        """A leg that travelled arrived at a place that was free or unseen before it came; a leg track that
        took a detection where something else already stood (:meth:`_judge_arrival`) re-locked onto that
        thing (a neighbouring table leg, a wall's piece) and did not travel: the mirror of "the place it left
        is seen empty now"."""
        return not lt.arrived_held

    def _judge_arrival(self, stamp_s: float, lt: LegTrack, d: LegDetection, partner: LegTrack | None) -> None:
        """Before ``lt`` takes ``d`` at ``stamp_s``: whether ``d`` lies where something else stood when the
        laser last saw that place (``stood_before``). Only a detection at least ``leg_travel_m`` from each
        earlier detection of the last ``leg_memory_s`` of the track and of its person's other leg
        (``partner``) is judged: nearer, the laser's returns there may be the person's own (a leg's
        footprint and a grid cell; a slow walker's swing leg lands a short stride beside where the other
        stood); a nearer one keeps the verdict of the arrival it follows. A new leg track has arrived nowhere
        (its own body may have stood there unseen as a leg)."""
        if self._stood_before is None:
            return
        travel = self.config.leg_travel_m
        own = lt.path + (partner.path if partner is not None else [])
        if all(math.hypot(d.x_m - x, d.y_m - y) >= travel for st, x, y in own if st < stamp_s):
            lt.arrived_held = bool(self._stood_before(d.x_m, d.y_m))

    def _release(self, t: PersonTrack) -> None:
        t.leg_ids = [k for k in t.leg_ids if self.legs[k].det is None]

    def _own_legs_seen(self, t: PersonTrack) -> bool:
        """Both of the person's leg tracks are seen this cycle as legs (not weak, not re-locked onto something
        that stood there) and can be one body's at their mean velocity (two walkers' legs side by side, paired
        while neither had a velocity, cannot: :meth:`_one_body`). (A lone leg is not followed so: it lies up to a
        hip's half-width off the person, and a stop that restarts the motion state on it reads the pair found
        next as a step.)"""
        legs = [self.legs[k] for k in t.leg_ids]
        if len(legs) != 2 or any(lt.det is None or lt.det.weak or lt.arrived_held for lt in legs):
            return False
        # judged at the legs' own mean velocity (the midpoint's: the body's), not the person's, which lost them
        return self._one_body((legs[0].x_m, legs[0].y_m), (legs[1].x_m, legs[1].y_m), _mean_velocity(*legs))

    def _from_free_legs(self, stamp_s: float) -> list[PersonTrack]:
        """Free legs paired greedily (nearest first, those that can be one body's: ``_one_body`` with the
        legs' mean velocity) or alone; each such
        detection goes to a person without legs whose gate holds it (global nearest neighbour), else
        starts a person. Returns the people updated or started."""
        c = self.config
        free = self._free()
        pairs = greedy_pairs(_pair_distances([(lt.x_m, lt.y_m) for lt in free]), fits=lambda i, j: self._one_body(
            (free[i].x_m, free[i].y_m), (free[j].x_m, free[j].y_m), _mean_velocity(free[i], free[j])), one_set=True)
        used = {k for pair in pairs for k in pair}
        groups = [[free[i], free[j]] for i, j in pairs] + [[lt] for i, lt in enumerate(free) if i not in used]
        dets = [(float(np.mean([lt.x_m for lt in g])), float(np.mean([lt.y_m for lt in g])),
                 self._midpoint_sigma(c.pair_sigma_m, g) if len(g) == 2 else c.leg_sigma_m, g)
                for g in groups]
        empty = [t for t in self.tracks if not t.leg_ids]
        got: dict[int, int] = {}
        if empty and dets:
            cost = np.full((len(empty), len(dets)), np.inf)
            for ti, t in enumerate(empty):
                likelier = _likelier_state(t)
                for di, (x, y, s, _) in enumerate(dets):
                    if self._in_gate(t, x, y, s, likelier):
                        cost[ti, di] = math.hypot(x - t.filt.mean[0], y - t.filt.mean[1])
            got = assign_gated(cost)
        out = []
        for ti, di in got.items():
            t = empty[ti]
            t.leg_ids = [lt.leg_id for lt in dets[di][3]]
            self._update(t, dets[di])
            out.append(t)
        taken = set(got.values())
        for di, (x, y, s, g) in enumerate(dets):
            if di in taken:
                continue
            out.append(self._start_person(stamp_s, x, y, s, max(lt.det.p_leg for lt in g), g))
        return out

    def _from_weak_pairs(self, stamp_s: float) -> list[PersonTrack]:
        """People started from pairs of this cycle's weak candidates that no leg track took: two that can be one
        body's (within a stride) and whose midpoint lies beyond every person's largest gate disc start a person
        of two leg tracks. It starts with the existence of a pair of the lesser leg probability, and the existence
        update decides (a far person's legs are mostly weak; a leg-like pair of furniture scored near
        :func:`weak_floor` says no more than a miss; a pair whose person would start below ``exist_drop`` is not
        started). Its shape tells nothing of a body that moves (even odds, :func:`_born_dynamic`). A lone weak
        candidate starts nothing (a post, a table leg)."""
        c = self.config
        free = [d for d in self._unclaimed_weak if self._birth_existence(d.p_leg) >= c.exist_drop]

        def midpoint(i: int, j: int) -> tuple[float, float]:
            return 0.5 * (free[i].x_m + free[j].x_m), 0.5 * (free[i].y_m + free[j].y_m)

        def one_body_alone(i: int, j: int) -> bool:
            x, y = midpoint(i, j)
            return self._one_body((free[i].x_m, free[i].y_m), (free[j].x_m, free[j].y_m), (0.0, 0.0)) and all(
                math.hypot(x - t.filt.mean[0], y - t.filt.mean[1]) >= 2.0 * c.person_radius_m for t in self.tracks)

        out = []
        for i, j in greedy_pairs(_pair_distances([(d.x_m, d.y_m) for d in free]), fits=one_body_alone, one_set=True):
            legs = [self._new_leg_track(stamp_s, d) for d in (free[i], free[j])]
            x, y = midpoint(i, j)
            sigma_m = self._midpoint_sigma(c.pair_sigma_m, legs)
            out.append(self._start_person(stamp_s, x, y, sigma_m, min(free[i].p_leg, free[j].p_leg), legs))
        return out

    def _birth_existence(self, p_leg: float) -> float:
        """A new person's existence from the leg probability it is born of: ``exist_birth``, scaled down below
        even odds (a leg candidate the detector doubts starts a less likely person)."""
        return self.config.exist_birth * p_leg / max(p_leg, 0.5)

    def _start_person(self, stamp_s: float, x: float, y: float, sigma_m: float, p_leg: float,
                      legs: list[LegTrack]) -> PersonTrack:
        """A new person of ``legs`` (seen this cycle) at (x, y), known to ``sigma_m``, born of leg probability
        ``p_leg``."""
        t = PersonTrack(self._next_id, Imm(x, y, sigma_m, self.config.imm), self._birth_existence(p_leg), stamp_s,
                        [lt.leg_id for lt in legs], tuple((lt.x_m, lt.y_m) for lt in legs), leg_seen=True,
                        p_dynamic=_born_dynamic(legs))
        self._next_id += 1
        self.tracks.append(t)
        return t

    def _prune(self) -> None:
        c = self.config
        # lost: existence gone. How well its place is known bounds what it may take (``_in_gate``) and whether it
        # is reported (``max_position_sigma_m``), not whether it is there: a walker out of the laser's view is
        # where its walk took it, however wide the models' mixing has spread their covariances
        alive = [t for t in self.tracks if t.existence >= c.exist_drop]
        # a duplicate: a younger track within a leg pair's half-width of an older one that is not another
        # person there (``_two_people``; its legs go free, and the older one adopts them if they fit it)
        keep: list[PersonTrack] = []
        for t in sorted(alive, key=lambda t: t.track_id):
            xy = t.filt.mean[:2]
            if any(math.hypot(*(k.filt.mean[:2] - xy)) < 0.5 * c.leg_pair_max_m and not self._two_people(k, t)
                   for k in keep):
                continue
            keep.append(t)
        if len(keep) > c.max_tracks:
            keep = sorted(keep, key=lambda t: -t.existence)[: c.max_tracks]
        self.tracks = sorted(keep, key=lambda t: t.track_id)

    def _two_people(self, a: PersonTrack, b: PersonTrack) -> bool:
        """Two tracks near each other are two people when what each is measured from says so, whatever their
        distance (two walkers side by side are 0.4 m apart centre to centre, less than half a leg pair): each
        was measured this cycle from its own seen legs, and those legs cannot be one person's (``_one_body``
        at the tracks' mean velocity; one person's two legs held by two tracks are a duplicate); or one of
        them was not measured and its place was hidden from this scan (``visible``: a companion behind the
        walker is no detection of the walker's, and the walker's legs say nothing about where it is)."""
        sa, sb = ([lt for k in t.leg_ids if (lt := self.legs[k]).det is not None] for t in (a, b))
        if sa and sb:
            if len(sa) + len(sb) > 2:
                return True
            v = (0.5 * float(a.filt.mean[2] + b.filt.mean[2]), 0.5 * float(a.filt.mean[3] + b.filt.mean[3]))
            return not self._one_body((sa[0].x_m, sa[0].y_m), (sb[0].x_m, sb[0].y_m), v)
        hidden = [t for t, s in ((a, sa), (b, sb)) if not s]
        if len(hidden) != 1 or self._visible is None:
            return False
        return not self._visible(float(hidden[0].filt.mean[0]), float(hidden[0].filt.mean[1]))

    def known_legs(self, stamp_s: float) -> list[KnownLeg]:
        """The live leg tracks predicted to ``stamp_s`` (before this cycle's :meth:`step`), each with its
        reach (``leg_step_m`` plus ``leg_max_speed_mps`` over the time since it was seen, as the leg
        association gates it) and, if it is one of the two leg tracks of a confirmed person, walking or
        standing, that person's id: the body stage pairs such a leg only with the person's other leg
        (:func:`vipsm.bodies._may_pair`; leg_tracker's model: a person is two leg tracks whose association
        persists). A standing person's seen leg, its other leg hidden, would otherwise pair with any leg-sized
        piece beside it (a cart's corner), a "person" off its pelvis that the body tracker reads as a step."""
        c = self.config
        owner = {k: t.track_id for t in self.tracks if len(t.leg_ids) == 2 and t.confirmed for k in t.leg_ids}
        out = []
        for k, lt in self.legs.items():
            x, y = lt.predicted(stamp_s, c.leg_memory_s)
            reach = self._reach_m(lt, stamp_s)
            out.append(KnownLeg(x, y, reach, owner.get(k), *self._walking_line(k)))
        return out

    def _walking_line(self, k: int) -> tuple[tuple[float, float] | None, float]:
        """The line of walking leg track ``k`` moves along, and how uncertain its direction is (one sigma,
        radians): its person's velocity while that is a walking speed (``WALK_DIR_MPS``), the sigma its
        velocity's covariance gives across it over the speed (as :meth:`_across_ok` widens its bound); (None,
        0) for a leg of no walking person (a single leg's velocity, a difference of two noisy detections,
        gives no line)."""
        for t in self.tracks:
            if k in t.leg_ids:
                return _line_of_walking(t) or (None, 0.0)
        return None, 0.0

    # ------------------------------------------------------------------ output
    def obstacles(self, people: tuple[Person, ...], others: tuple[Obstacle, ...], laser: Pose2D,
                  standing_for: dict[int, tuple[int, float]] | None = None) -> tuple[Obstacle, ...]:
        """The moving ``people`` seen this cycle as moving obstacles, but those a body of ``others`` (the
        body tracker's reported bodies, ``Tracker.moving``) stands for: each body is the nearest moving
        person within a leg pair's reach (plus its radius) if the body tracker saw it as a leg pair, within
        a person's radius (plus its own) otherwise (:func:`_explained`): the same body, reported once and
        judged once. A second person beside it, or the person pushing a cart the body tracker holds, is
        another body. A walker seen by no leg (``PersonTrack.leg_seen``: nor by the laser where it is predicted)
        may have stopped or turned: it stays in ``people`` while its position is known, but it is no obstacle
        (the protective field on the raw scan still guards the robot). The bearing interval is the person's
        radius seen from ``laser``; scan indices -1 (a track, not one scan's segment). ``standing_for``:
        :meth:`bodies_standing_for` of the same arguments when the caller has it already (None: found here)."""
        c = self.config
        if not c.report_moving:
            return ()
        out = []
        tracks = {t.track_id: t for t in self.tracks}
        if standing_for is None:
            standing_for = self.bodies_standing_for(people, others)
        explained = {pid for pid, _ in standing_for.values()}
        for p in self._seen_moving(people):
            if p.track_id in explained:
                continue
            dx, dy = p.x_m - laser.x_m, p.y_m - laser.y_m
            b = wrap_angle(math.atan2(dy, dx) - laser.theta_rad)
            half = math.asin(min(c.person_radius_m / max(math.hypot(dx, dy), 1e-6), 1.0))
            t = tracks[p.track_id]
            cov = tuple(float(v) for v in np.asarray(t.filt.walking()[1], float)[:4, :4].ravel())
            out.append(Obstacle(p.track_id, p.x_m, p.y_m, p.vx_mps, p.vy_mps, c.person_radius_m, b - half, b + half,
                                -1, -1, age_cycles=t.age_cycles, covariance=cov, person=True))
        return tuple(out)

    def bodies_standing_for(self, people: tuple[Person, ...], others: tuple[Obstacle, ...]
                            ) -> dict[int, tuple[int, float]]:
        """Per body of ``others`` that a moving person seen this cycle stands for (as in :meth:`obstacles`),
        the person's track id and its distance from the body (``vipsm.identity`` gives both one id)."""
        c = self.config
        moving = self._seen_moving(people)
        found = _explained(moving, others, c.leg_pair_max_m, c.person_radius_m)
        return {others[k].track_id: (p.track_id, math.hypot(p.x_m - others[k].x_m, p.y_m - others[k].y_m))
                for p, k in zip(moving, found, strict=True) if k is not None}

    def _seen_moving(self, people: tuple[Person, ...]) -> list[Person]:
        """The moving ``people`` a leg of whom was seen this cycle (``PersonTrack.leg_seen``): the moving
        obstacles this stage may report."""
        seen = {t.track_id for t in self.tracks if t.leg_seen}
        return [p for p in people if p.moving and p.track_id in seen]

    def people(self, stamp_s: float) -> tuple[Person, ...]:
        """The confirmed tracks at ``stamp_s`` (positions predicted at constant velocity)."""
        out = []
        for t in self.tracks:
            m, p = t.filt.mean, t.filt.cov
            if t.moving:  # the velocity given that it walks (P(standing) would shrink it towards zero)
                m = np.concatenate([m[:2], t.filt.walking()[0][2:4]])
            if not t.confirmed or np.linalg.eigvalsh(p[:2, :2])[-1] > self.config.max_position_sigma_m**2:
                continue
            dt = stamp_s - t.stamp_s
            vx, vy = (float(m[2]), float(m[3])) if t.moving else (0.0, 0.0)
            out.append(Person(t.track_id, float(m[0] + vx * dt), float(m[1] + vy * dt), float(m[2]), float(m[3]),
                              tuple(float(v) for v in p[:2, :2].ravel()), round(t.p_moving, 4), t.moving,
                              round(t.existence, 4), t.legs))
        return tuple(out)


def _leg_cost(dist_m: float, reach_m: float, stand_sigma_m: float) -> float:
    """The negative log-likelihood of a leg's detection ``dist_m`` from its prediction under a gait's two leg
    states, even odds: standing (placed within ``stand_sigma_m``) or swinging (anywhere within its reach,
    ``reach_m`` as two sigma). Of two ways to move a person's two legs, one standing and one swinging far is
    likelier than both moving half as far."""
    def density(sigma_m: float) -> float:
        return math.exp(-0.5 * (dist_m / sigma_m) ** 2) / (2.0 * math.pi * sigma_m**2)
    return -math.log(0.5 * density(stand_sigma_m) + 0.5 * density(0.5 * reach_m) + 1e-300)


def _born_dynamic(legs: list[LegTrack]) -> float:
    """P(a body that moves) of a person born of ``legs`` (seen this cycle). The detector's probability is
    that of one segment being a person's leg, against the leg-like things of rooms without people (it is
    trained on both, with balanced classes). Two legs at or above its operating point are a person's with the
    probability the less likely of them is a leg: the person's shape, both legs of it. One leg, or a pair
    with a weak candidate, is only a leg-like segment, what a table leg, a post or a bag gives as well:
    even odds, nothing known. What the person's standing, walking and motion evidence then say is weighed
    from there (:meth:`PeopleTracker._update`)."""
    if len(legs) == 2 and not any(lt.det is None or lt.det.weak for lt in legs):
        return min(lt.det.p_leg for lt in legs if lt.det is not None)
    return 0.5


def _pair_distances(xy: list[tuple[float, float]]) -> np.ndarray:
    """Distances between the points ``xy``, each pair once (row before column; ``inf`` elsewhere)."""
    p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    d = np.hypot(p[:, None, 0] - p[None, :, 0], p[:, None, 1] - p[None, :, 1])
    d[np.tril_indices(len(p))] = np.inf
    return d


def _mean_velocity(a: LegTrack, b: LegTrack) -> tuple[float, float]:
    """The velocity of the midpoint of two legs (a body's, from its legs)."""
    return 0.5 * (a.vx_mps + b.vx_mps), 0.5 * (a.vy_mps + b.vy_mps)


def _keep_nearer(t: PersonTrack, legs: list[LegTrack]) -> None:
    """The person ``t`` keeps the one of its two ``legs`` nearer its prediction and frees the other."""
    mx, my = float(t.filt.mean[0]), float(t.filt.mean[1])
    far = max(range(2), key=lambda i: math.hypot(legs[i].x_m - mx, legs[i].y_m - my))
    t.leg_ids = [lt.leg_id for i, lt in enumerate(legs) if i != far]


def _likelier_state(t: PersonTrack) -> tuple[np.ndarray, np.ndarray]:
    """The prediction (state, covariance) of the person's likelier motion state: where its walk has taken it
    while P(walking) is at least a half (:meth:`Imm.walked_on`), where it stands otherwise. While nothing is
    seen the models' combination lies between the two, held back by the other."""
    walked = t.filt.walked_on() if t.filt.p_moving >= 0.5 else None
    return walked if walked is not None else (t.filt.means[0], t.filt.covs[0])


def _line_of_walking(t: PersonTrack) -> tuple[tuple[float, float], float] | None:
    """The walking person ``t``'s line of walking (a unit vector) and its direction's sigma (radians: the
    velocity's sigma across the line over the speed); None below a walking speed (``WALK_DIR_MPS``)."""
    v = t.filt.mean[2:4]
    speed = float(math.hypot(*v))
    if speed < WALK_DIR_MPS:
        return None
    ux, uy = float(v[0]) / speed, float(v[1]) / speed
    side = np.array([-uy, ux])
    return (ux, uy), math.sqrt(max(float(side @ t.filt.cov[2:4, 2:4] @ side), 0.0)) / speed


def _explained(people: list[Person], bodies: tuple[Obstacle, ...], pair_m: float, radius_m: float) -> list[int | None]:
    """Per person, the index of the body of ``bodies`` that stands for it, or None: each body is one person,
    the nearest (global nearest neighbour) within its radius plus ``pair_m`` (a leg pair's reach) for a
    body seen as a person, plus ``radius_m`` (a person's) for any other body: a person overlapping it.
    Two people side by side near one body (the body tracker held them as one, or holds one of them)
    leave the other unexplained, and a person pushing a cart is not the cart."""
    out: list[int | None] = [None] * len(people)
    if not people or not bodies:
        return out
    cost = np.full((len(people), len(bodies)), np.inf)
    for i, p in enumerate(people):
        for j, o in enumerate(bodies):
            d = math.hypot(o.x_m - p.x_m, o.y_m - p.y_m)
            if d <= o.radius_m + (pair_m if o.person else radius_m):
                cost[i, j] = d
    for r, k in assign_gated(cost).items():
        out[r] = k
    return out


def _bayes(prior: float, like_true: float, like_false: float) -> float:
    num = prior * like_true
    den = num + (1.0 - prior) * like_false
    return float(np.clip(num / den, 1e-4, 1.0 - 1e-4)) if den > 0.0 else prior
