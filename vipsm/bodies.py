"""Body extraction: which segments of the scan may be moving bodies, and people as leg pairs.

Each segment of the (pre-filtered) scan that is narrower than a body and stands in front of what lies
beside it is a foreground segment: a body. Only a body with motion evidence can start a track (any body
can continue one, so a walker who pauses or a slow body inside its own footprint keeps its track):

* **free-space violation** (:mod:`vipsm.static_map`): at least ``min_free_share`` of its points lie
  where the laser recently saw free floor and nothing occupied: something moved there;
* **camera**: it lies in a bearing interval where optical flow saw independent motion (the paper's
  cue), or, for a body wider than a leg, it stands clearly in front of what the keyframe saw in the
  same direction (a body coming head-on along the beams, which the camera barely sees move and which
  hits its own cells of the free-space grid all the time; thin furniture legs, which one scan sees and
  another misses between two beams, are left out of this cue). The camera alone never confirms a
  track (:mod:`vipsm.tracker` also needs displacement), so a flow error on furniture cannot make a
  phantom; it makes a slow body's confirmation faster.

At the laser's height a walking person is two legs (0.08-0.2 m wide) that scissor: leg-sized
foreground segments within ``leg_pair_max_m`` (the people stage's key: :class:`Derived`) of each other
are one person, placed at the midpoint of the two leg centres (the pelvis); a lone leg (the other hidden)
is a person at that leg. Wider segments (up to ``max_body_width_m``) are round bodies when a circle fits
them (centre behind the points, a body's radius): a straight wall piece or a room corner is not. A pair counts as a
candidate when either leg shows evidence: the stance leg stands still while the swing leg moves. A
leg-sized thing that has stood alone for a while (a post: ``_fixtures``) is never a leg of a pair.

Segments bridge a gap of up to ``max_gap_beams`` beams with no echo (a dropout inside a leg), never
one where the pre-filter removed a return (a thin thing in front).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from .assignment import assign_gated
from .flow import FlowConfig
from .geometry import scan_points
from .person import PersonKeys, PersonSize, across_beyond_m
from .restore import BearingInterval, _beams_in
from .seen_through import ScanMemory
from .static_map import FreeSpaceGrid, StaticMapConfig
from .tracker import TrackerConfig, locate_body, locate_round
from .types import Pose2D

#: the fewest returns a segment needs to be a body: three points define a circle (the round-body fit) and
#: are what the fixed-radius refinement of a leg's centre needs (:func:`vipsm.tracker.locate_body`); not
#: a tuned value
MIN_BEAMS = 3


@dataclass(frozen=True)
class BodiesConfig:
    """The body stage's own keys; each is a size, a distance or a count of the world or the sensor. Keys
    removed in the reduction of issue 29 are listed in ``REMOVED_KEYS`` (a config file that still sets
    one is refused with the reason); the quantities the stage takes from other stages are :class:`Derived`."""

    #: two neighbouring returns further apart in range than this are two surfaces (a leg 0.15 m in front
    #: of a wall is apart from it) ...
    seg_jump_m: float = 0.15
    #: ... or than this many times the beam spacing at their range (a surface seen at up to ~70 deg
    #: incidence, tan = 3, stays one segment)
    seg_jump_range_factor: float = 3.0
    #: a run of at most this many beams with no return between two returns on one surface does not
    #: split the segment (a dropout inside a leg: each half would see the other as the same surface
    #: beside it and neither would be a body); a gap where the pre-filter removed a return is never
    #: bridged (a thin thing in front)
    max_gap_beams: int = 2
    #: a leg at the laser's height (shin, trousered): 0.05-0.25 m across the segment
    max_leg_width_m: float = 0.25
    #: the widest body tracked (a cart, a person with a bag); wider foreground segments are furniture or walls
    max_body_width_m: float = 1.2
    #: a foreground segment stands at least this far in front of its neighbours (or next to no return)
    foreground_m: float = 0.10
    #: a return beside a straight segment this close to its line continues the same surface (5x the
    #: UTM-30LX's range noise: a wall at grazing incidence broken into pieces by range jumps)
    surface_tol_m: float = 0.05
    #: a segment with at least this share of its returns where the laser recently saw free floor (and
    #: saw through at beam resolution) moved there: motion evidence
    min_free_share: float = 0.5
    #: a leg-sized segment whose returns lie in cells the laser has seen occupied in at least this many
    #: (decayed) scans has stood there (15 is ~1.7 s at 10 scans a second under the grid's 6 s memory; a
    #: walker's stance leg stays ~0.6 s, and the cells of a tracked mover get no occupancy); one that
    #: stood alone is a fixture (a post): no motion evidence, never one leg of a person's pair (a post
    #: beside a passer-by made a "person" between them whose track followed the post). See ``_fixtures``
    fixture_occupied: float = 15.0

    #: keys removed (issue 29: fewer tuned parameters), with what replaced each: a config file that sets one
    #: is refused naming the key and this reason (``app.config``), never silently misread
    REMOVED_KEYS: ClassVar[dict[str, str]] = {
        "min_beams": "now a constant, 3: three points define a circle (vipsm.bodies.MIN_BEAMS)",
        "neighbour_beams": "derived: max_gap_beams + 2 (the return after the narrowest gap that splits a segment)",
        "leg_radius_m": "one key for one person: estimator.people.leg_radius_m",
        "leg_pair_max_m": "one key for one person: estimator.people.leg_pair_max_m",
        "person_radius_m": "one key for one person: estimator.people.person_radius_m",
        "camera_interval_max_m": "derived: bodies.max_body_width_m + tracker.max_speed_mps x flow.baseline_s",
        "fixture_own_m": "derived: half of bodies.max_leg_width_m + half a static_map cell's diagonal",
    }

    def __post_init__(self) -> None:
        if self.max_gap_beams < 0:
            raise ValueError(f"need max_gap_beams >= 0, got {self.max_gap_beams}")
        if not 0.0 < self.max_leg_width_m < self.max_body_width_m:
            raise ValueError(f"need 0 < max_leg_width_m < max_body_width_m, got {self.max_leg_width_m}, "
                             f"{self.max_body_width_m}")

    @property
    def neighbour_beams(self) -> int:
        """How far beside a segment its neighbour is looked for: across the narrowest run of missing
        returns that splits a segment (``max_gap_beams`` + 1 beams) to the return after it. A wider gap
        is open space beside the segment."""
        return self.max_gap_beams + 2


@dataclass(frozen=True)
class Derived:
    """The quantities the body stage takes from other stages' keys, so that one physical quantity has one
    key (:func:`derive` states each derivation)."""

    #: a leg's radius at the laser's height: its centre lies this far behind the returns
    leg_radius_m: float
    #: two legs of one person: centres at most this far apart (stride at the laser's height)
    leg_pair_max_m: float
    #: a person's radius (shoulders seen from above)
    person_radius_m: float
    #: two legs of a walking person: centres at most this far apart across its line of walking
    leg_across_max_m: float
    #: a camera interval is motion evidence for a segment only when, at the segment's range, it is no wider
    #: than this: the widest body plus the background it uncovers in the flow's baseline at the fastest
    #: speed a body moves. A wider one is not about this segment: the flow merged the passing body with the
    #: far side of the image (47 deg, 3.6 m wide at a box 4.3 m away, which became a track)
    camera_interval_max_m: float
    #: a fixture's own cells: within this of its points' mean (its returns lie within half the widest
    #: leg of their mean, and a return's cell centre within half a cell's diagonal of it); a long-occupied
    #: cell further away, within ``leg_pair_max_m``, where this scan's beam no longer ends was another leg
    fixture_own_m: float


def derive(bodies: BodiesConfig, people: PersonKeys, tracker: TrackerConfig, flow_baseline_s: float,
           cell_m: float) -> Derived:
    """:class:`Derived` from the people stage's person (``PeopleConfig``: ``leg_radius_m``,
    ``leg_pair_max_m``, ``person_radius_m``), the tracker's fastest body, the flow's baseline and the
    static map's cell. Raises ValueError when a leg's own reach is not inside a leg pair's."""
    own = 0.5 * bodies.max_leg_width_m + 0.5 * math.sqrt(2.0) * cell_m
    if not own < people.leg_pair_max_m:
        raise ValueError(f"need max_leg_width_m / 2 + cell diagonal / 2 ({own:.3f} m) < people.leg_pair_max_m "
                         f"({people.leg_pair_max_m} m)")
    return Derived(people.leg_radius_m, people.leg_pair_max_m, people.person_radius_m, people.leg_across_max_m,
                   bodies.max_body_width_m + tracker.max_speed_mps * flow_baseline_s, own)


def default_derived(bodies: BodiesConfig, tracker: TrackerConfig) -> Derived:
    """:func:`derive` with the other stages' default keys."""
    return derive(bodies, PersonSize(), tracker, FlowConfig().baseline_s, StaticMapConfig().cell_m)


@dataclass(frozen=True)
class Body:
    x_m: float
    y_m: float
    radius_m: float
    radius_fitted: bool
    kind: str  # "person", "leg" (a person with one leg seen) or "body"
    free_share: float  # share of its points in seen-free space
    camera: bool  # inside a camera motion interval
    #: motion evidence (free-space violation or camera): only such a body can start a track; any
    #: foreground body can continue one
    scan_index_start: int
    scan_index_stop: int
    bearing_min_rad: float
    bearing_max_rad: float
    evidence: bool = True
    #: partly hidden by something nearer beside it (not by its own other leg): its visible part, and
    #: so its estimated centre, moves with the occluder's edge, not with the body
    occluded: bool = False
    #: a fitted circle's: the world-frame direction from its visible returns (their mean) to its centre, the
    #: line along which the centre lies its radius behind the visible surface (NaN: not fitted). For a round
    #: body seen whole it is the view line from the laser; for a flat face seen obliquely (a door leaf, a
    #: box's side) it is the face's normal, which the view line is not
    behind_rad: float = math.nan
    #: a leg pair's or a lone leg's: the centres of its legs (world frame), one per leg seen
    legs_xy: tuple[tuple[float, float], ...] = ()


@dataclass(frozen=True)
class _Segment:
    start: int
    stop: int
    points: np.ndarray  # world frame
    width_m: float
    free_share: float
    camera: bool
    #: beams of nearer returns right beside it: something in front hides part of it
    occluders: tuple[int, ...] = ()
    #: leg-sized and in cells long occupied (``BodiesConfig.fixture_occupied``); ``vacated_near``: a
    #: long-occupied cell within a leg pair's reach where this scan's beam no longer ends
    stood: bool = False
    vacated_near: bool = False
    #: stood, alone: a fixture (see :func:`_fixtures`)
    fixture: bool = False


def segments(r: np.ndarray, b: np.ndarray, cfg: BodiesConfig, dropped: np.ndarray | None = None
             ) -> list[tuple[int, int]]:
    """[start, stop) runs of returns on one surface: consecutive, or across at most ``max_gap_beams``
    beams that had no echo when the returns on both sides of the gap are within the jump threshold
    (its range-scaled part widened by the gap's beams, the fixed part not: a leg 0.15 m in front of a
    wall stays apart from it across the mixed pixel dropped between them). ``dropped`` (per beam,
    optional): the pre-filter removed a return there (a thin thing in front, a mixed pixel): a gap
    holding one is an occluder's, never bridged. A segment starts and ends with a return; it may hold
    NaN beams."""
    n = r.size
    idx = np.flatnonzero(np.isfinite(r))
    if idx.size == 0:
        return []
    dphi = float(abs(b[-1] - b[0]) / max(n - 1, 1))
    rv = r[idx]
    gap = np.diff(idx)  # beams from one return to the next
    thr = np.maximum(cfg.seg_jump_m, cfg.seg_jump_range_factor * rv[1:] * dphi * gap)
    brk = (gap > cfg.max_gap_beams + 1) | (np.abs(np.diff(rv)) >= thr)
    if dropped is not None:
        removed = np.concatenate([[0], np.cumsum(dropped)])  # removed[i]: dropped beams before i
        brk |= removed[idx[1:]] - removed[idx[:-1] + 1] > 0
    cut = np.flatnonzero(brk) + 1  # positions in idx where a new segment starts
    starts = np.concatenate([[0], cut])
    stops = np.concatenate([cut, [idx.size]])
    return [(int(idx[s0]), int(idx[s1 - 1]) + 1) for s0, s1 in zip(starts, stops, strict=True)]


def _foreground(r: Sequence[float], a: int, z: int, cfg: BodiesConfig) -> tuple[bool, list[int]]:
    """The segment stands in front of what lies beside it. Each side's neighbour is the nearest return
    within ``neighbour_beams`` (a dropped mixed pixel does not hide the surface next to it), judged
    against the segment's own return at that end: a side on the same surface (within ``foreground_m``)
    means the segment is part of something larger; nearer neighbours on both sides mean it is
    background seen between two occluders (a wall between a person's legs); one nearer side is a body
    partly hidden by another, which is kept. (Judged against the segment's nearest return instead, a
    box seen by its corner, 0.4 m deeper at its ends, was "the same surface" as a leg beside an end
    that hid it: no body while its pusher's leg stood there.) Returns (foreground, the beams of the
    nearer neighbours: its occluders). The edge of the scanner's field of view hides like a nearer
    neighbour (its beam index is -1 or the scan's size): a body leaving the field of view shows a
    shrinking part whose centre moves with the edge, not with the body."""
    occluders: list[int] = []  # the beam of each nearer neighbour
    nb, n = cfg.neighbour_beams, len(r)
    sides = (range(a - 1, max(a - nb, 0) - 1, -1), range(z, min(z + nb, n)))
    # a segment starts and ends with a return
    ends_m = (next(float(r[k]) for k in range(a, z) if math.isfinite(r[k])),
              next(float(r[k]) for k in range(z - 1, a - 1, -1) if math.isfinite(r[k])))
    for idx, edge, end_m in zip(sides, (-1, n), ends_m, strict=True):
        first = next((k for k in idx if math.isfinite(r[k])), None)
        if first is None:
            if len(idx) < nb:  # the scan's first or last beam is beside it: the field of view's edge
                occluders.append(edge)
            continue
        if r[first] >= end_m + cfg.foreground_m:
            continue
        if r[first] > end_m - cfg.foreground_m:
            return False, []
        occluders.append(first)
    return sum(0 <= k < n for k in occluders) < 2, occluders


def _continues_a_surface(pts: np.ndarray, r: np.ndarray, b: np.ndarray, a: int, z: int, laser: Pose2D,
                         cfg: BodiesConfig) -> bool:
    """The segment is a piece of a straight surface that goes on beside it (a wall seen at grazing
    incidence breaks into short pieces with range jumps between them): the nearest return on either
    side lies on the segment's own line."""
    if pts.shape[0] < 3:
        return False
    centre = pts.mean(axis=0)
    d = pts - centre
    sxx, sxy, syy = float(d[:, 0] @ d[:, 0]), float(d[:, 0] @ d[:, 1]), float(d[:, 1] @ d[:, 1])
    # the scatter's eigenvalues (the squared singular values of the centred points), in closed form
    spread = math.hypot(0.5 * (sxx - syy), sxy)
    if 0.5 * (sxx + syy) - spread > 0.09 * (0.5 * (sxx + syy) + spread):  # not a line (a round body's short arc)
        return False
    along = 0.5 * math.atan2(2.0 * sxy, sxx - syy)  # the line's direction; its normal is across it
    nx, ny = -math.sin(along), math.cos(along)
    mx, my = float(centre[0]), float(centre[1])
    c, s = math.cos(laser.theta_rad), math.sin(laser.theta_rad)
    for j in (*range(a - 1, max(a - cfg.neighbour_beams, 0) - 1, -1), *range(z, min(z + cfg.neighbour_beams, r.size))):
        rj = float(r[j])
        if not math.isfinite(rj):
            continue
        bj = float(b[j])
        xl, yl = rj * math.cos(bj), rj * math.sin(bj)
        px, py = laser.x_m + c * xl - s * yl, laser.y_m + s * xl + c * yl
        if abs((px - mx) * nx + (py - my) * ny) < cfg.surface_tol_m:
            return True
    return False


def _violating(world: np.ndarray, finite: np.ndarray, grid: FreeSpaceGrid, memory: ScanMemory | None) -> np.ndarray:
    """Per beam: its return lies where the grid saw free space and, at beam resolution, a recent scan
    saw through (``memory``; a thin leg uncovered from behind another sits in cells the grid took
    for free)."""
    violating = np.zeros(finite.size, bool)  # asked once per scan, not once per segment
    violating[finite] = grid.violates(world[finite])
    if memory is not None:
        idx = np.flatnonzero(violating)
        violating[idx] = memory.seen_through(world[idx])
    return violating


def _candidate_segments(r: np.ndarray, b: np.ndarray, laser: Pose2D, grid: FreeSpaceGrid,
                        camera: list[BearingInterval], cfg: BodiesConfig, der: Derived, ahead: np.ndarray | None,
                        memory: ScanMemory | None, dropped: np.ndarray | None) -> list[_Segment]:
    finite = np.isfinite(r)
    in_camera = [_beams_in(iv, np.where(finite, r, np.nan), b, 0.0) for iv in camera]
    world = scan_points(laser, r, b)  # nan: no return
    violating = _violating(world, finite, grid, memory)
    occupied = np.zeros(r.size, np.float32)  # asked once per scan, not once per segment
    occupied[finite] = grid.occupied(world[finite])
    r_list = r.tolist()  # the per-segment tests read single returns
    out = []
    for a, z in segments(r, b, cfg, dropped):
        beams = a + np.flatnonzero(finite[a:z])  # a bridged gap's beams hold no return
        if beams.size < MIN_BEAMS:
            continue
        fg, occluders = _foreground(r_list, a, z, cfg)
        if not fg:
            continue
        pts = world[beams]
        width = float(np.hypot(*(pts[-1] - pts[0])))
        if width > cfg.max_body_width_m or _continues_a_surface(pts, r, b, a, z, laser, cfg):
            continue
        share = np.count_nonzero(violating[beams]) / beams.size
        near_m = _median(r[beams]) if camera else 0.0
        narrow = [m for m, iv in zip(in_camera, camera, strict=True)
                  if (iv.bearing_max_rad - iv.bearing_min_rad) * near_m <= der.camera_interval_max_m]
        cue = _camera_cue(narrow, beams, [k for k in occluders if 0 <= k < r.size])
        if ahead is not None and width > cfg.max_leg_width_m:
            cue = cue or bool(np.mean(ahead[beams]) >= 0.6)
        stood = width <= cfg.max_leg_width_m and _median(occupied[beams]) >= cfg.fixture_occupied
        vacated = stood and _vacated_near(pts, r, b, laser, grid, cfg, der)
        out.append(_Segment(a, z, pts, width, share, cue, tuple(occluders), stood, vacated))
    return out


def _median(x: np.ndarray) -> float:
    """``np.median`` of a short finite array, in its dtype (the mean of the two middle values of an even
    count is taken as numpy takes it), from a partial sort: np.median's overhead is most of its cost
    on a segment's few returns."""
    h = x.size // 2
    if x.size % 2:
        return float(np.partition(x, h)[h])
    part = np.partition(x, (h - 1, h))
    return float((part[h - 1] + part[h]) / 2)


def _vacated_near(pts: np.ndarray, r: np.ndarray, b: np.ndarray, laser: Pose2D, grid: FreeSpaceGrid,
                  cfg: BodiesConfig, der: Derived) -> bool:
    """A long-occupied cell within a leg pair's reach of the segment where this scan's beam does not
    end: it returns from more than a cell beyond it (what stood there left) or nearer than it (the
    other leg of a person who stood, now stepping towards the laser, hides its own old cell)."""
    cx, cy = (float(v) for v in pts.mean(axis=0))
    cells = grid.occupied_cells_around(cx, cy, der.fixture_own_m, der.leg_pair_max_m, cfg.fixture_occupied)
    if not cells.size:
        return False
    dist = np.hypot(cells[:, 0] - laser.x_m, cells[:, 1] - laser.y_m)
    bearing = np.arctan2(cells[:, 1] - laser.y_m, cells[:, 0] - laser.x_m) - laser.theta_rad
    bearing = np.arctan2(np.sin(bearing), np.cos(bearing))
    k = np.clip(np.searchsorted(b, bearing), 0, b.size - 1)
    ranges = r[k]
    cell_m = grid.config.cell_m
    left = np.isfinite(ranges) & (np.abs(ranges - dist) > cell_m)
    return bool(np.any(left & (np.abs(b[k] - bearing) < cell_m / dist)))


def _fixtures(legs: list[tuple[_Segment, float, float]], der: Derived) -> list[tuple[_Segment, float, float]]:
    """The legs with each fixture marked and stripped of motion evidence: a leg-sized thing that has
    stood here for a while alone, with no other such thing within a leg pair's reach (a standing
    person's other leg) and no long-occupied cell there where this scan's beam no longer ends (the
    other leg of a person who stood and took the first step). A post stands alone."""
    out = []
    for i, (sg, x, y) in enumerate(legs):
        partner = any(o.stood and math.hypot(ox - x, oy - y) <= der.leg_pair_max_m
                      for j, (o, ox, oy) in enumerate(legs) if j != i)
        if sg.stood and not sg.vacated_near and not partner:
            sg = replace(sg, free_share=0.0, camera=False, fixture=True)
        out.append((sg, x, y))
    return out


def _camera_cue(in_camera: list[np.ndarray], beams: np.ndarray, occluders: list[int]) -> bool:
    """Half the segment's beams (those with a return) lie in camera intervals, not counting an
    interval that also holds one of its occluders: the camera sees motion of the front surface, and a
    nearer body moving beside a partly hidden one covers and uncovers it at its edge (a box behind the
    passing cylinder), which the flow sees as motion there."""
    own = [m for m in in_camera if not any(m[k] for k in occluders)]
    return bool(own) and float(np.mean(np.logical_or.reduce(own)[beams])) >= 0.5


@dataclass(frozen=True)
class KnownLeg:
    """A leg the people stage (:mod:`vipsm.people`) tracks, predicted to this scan: where it should be, how
    far from that its detection may lie (a leg's reach in the elapsed time), and the confirmed person (walking
    or standing) whose two leg tracks it is one of (None: a leg of no such person)."""

    x_m: float
    y_m: float
    reach_m: float
    person: int | None
    #: the line of walking this leg moves along (a unit vector), None when it does not walk: a leg steps and
    #: swings along its person's line of walking, a hip's width beside its other leg (``leg_across_max_m``)
    line: tuple[float, float] | None = None
    #: how uncertain the line's direction is (one sigma, radians)
    line_sigma_rad: float = 0.0


def _leg_people(legs: list[tuple[_Segment, float, float]], known: list[KnownLeg]) -> list[KnownLeg | None]:
    """Per leg, the tracked leg it continues: global nearest neighbour of the leg centres to the tracked
    legs' predictions within their reach (:func:`vipsm.assignment.assign`); None for a leg that continues
    none."""
    out: list[KnownLeg | None] = [None] * len(legs)
    if not legs or not known:
        return out
    cost = np.full((len(legs), len(known)), np.inf)
    for i, (_, x, y) in enumerate(legs):
        for j, k in enumerate(known):
            d = math.hypot(x - k.x_m, y - k.y_m)
            if d <= k.reach_m:
                cost[i, j] = d
    for r, k in assign_gated(cost).items():
        out[r] = known[k]
    return out


def _may_pair(a: KnownLeg | None, b: KnownLeg | None, dx: float, dy: float, across_max_m: float) -> bool:
    """Two legs ``(dx, dy)`` apart that continue the tracked legs ``a`` and ``b`` (None: a new leg) can be one
    person's: a person who holds two leg tracks has both its legs, so its legs pair only with each other;
    the other legs pair among themselves, and only within ``across_max_m`` across the line of walking
    of either, widened by the line's uncertainty (:func:`vipsm.person.across_beyond_m`; the feet swing along
    it a hip's width apart; two walkers side by side have each leg 0.4 m across from the other's same leg)."""
    if (None if a is None else a.person) != (None if b is None else b.person):
        return False
    return all(k is None or k.line is None or across_beyond_m(dx, dy, k.line, k.line_sigma_rad) <= across_max_m
               for k in (a, b))


def _pair_legs(legs: list[tuple[_Segment, float, float]], der: Derived, known: list[KnownLeg] | None = None
               ) -> list[tuple[int, int | None]]:
    """Greedy nearest pairs of leg centres within ``leg_pair_max_m``, never a fixture, never two legs that
    cannot be one person's by the people stage's leg tracks (``known``; :func:`_may_pair`): a person's two leg
    tracks pair only with each other (leg_tracker's model: a person is two leg tracks whose association
    persists), and no two legs lie further apart across the line of walking of either than
    ``leg_across_max_m`` (two people walking side by side in step have each leg 0.4 m across from the other's
    same leg, nearer than their own other leg a stride away); the rest alone."""
    owner = _leg_people(legs, known or [])
    near = ((math.hypot(legs[i][1] - legs[j][1], legs[i][2] - legs[j][2]), i, j)
            for i in range(len(legs)) for j in range(i + 1, len(legs)))
    pairs = sorted(p for p in near if p[0] <= der.leg_pair_max_m)
    used: set[int] = set()
    out: list[tuple[int, int | None]] = []
    for _, i, j in pairs:
        if i in used or j in used or legs[i][0].fixture or legs[j][0].fixture:
            continue
        dx, dy = legs[j][1] - legs[i][1], legs[j][2] - legs[i][2]
        if not _may_pair(owner[i], owner[j], dx, dy, der.leg_across_max_m):
            continue
        used |= {i, j}
        out.append((i, j))
    out += [(i, None) for i in range(len(legs)) if i not in used]
    return out


def extract_bodies(ranges_m: np.ndarray, bearings_rad: np.ndarray, laser: Pose2D, grid: FreeSpaceGrid,
                   camera: list[BearingInterval], cfg: BodiesConfig, tracker_cfg: TrackerConfig,
                   ahead: np.ndarray | None = None, memory: ScanMemory | None = None,
                   dropped: np.ndarray | None = None, derived: Derived | None = None,
                   known_legs: list[KnownLeg] | None = None) -> list[Body]:
    """The foreground bodies of one scan (world frame, placed with the matched laser pose), each with
    its motion evidence. ``ahead`` (per beam, optional): the return stands clearly in front of what the
    keyframe saw in that direction (counts like the camera's motion cue). ``memory`` (optional): recent
    scans; a free-space violation must then also have been seen through at beam resolution.
    ``dropped`` (per beam, optional): the pre-filter removed a return there (see :func:`segments`).
    ``derived``: the quantities taken from the other stages' keys (:func:`derive`; None: their defaults).
    ``known_legs`` (optional): the people stage's tracked legs predicted to this scan; two legs that
    continue two different people's are never paired (:func:`_pair_legs`)."""
    sensor = (laser.x_m, laser.y_m)
    der = derived or default_derived(cfg, tracker_cfg)
    segs = _candidate_segments(ranges_m, bearings_rad, laser, grid, camera, cfg, der, ahead, memory, dropped)
    legs, bodies = [], []
    for sg in segs:
        if sg.width_m <= cfg.max_leg_width_m:
            lx, ly = locate_round(sg.points, sensor, der.leg_radius_m)
            legs.append((sg, lx, ly))
        else:
            cx, cy, rad, fitted = locate_body(sg.points, sensor, None)
            if fitted:  # a round body; a wall piece or a room corner fits no circle behind its points
                mx, my = (float(v) for v in sg.points.mean(axis=0))
                bodies.append(replace(_body(cx, cy, rad, fitted, "body", [sg], bearings_rad, cfg),
                                      behind_rad=math.atan2(cy - my, cx - mx)))
    legs = _fixtures(legs, der)
    for i, j in _pair_legs(legs, der, known_legs):
        group = [legs[i]] + ([legs[j]] if j is not None else [])
        x = float(np.mean([g[1] for g in group]))
        y = float(np.mean([g[2] for g in group]))
        kind = "person" if j is not None else "leg"
        bodies.append(_body(x, y, der.person_radius_m, False, kind, [g[0] for g in group], bearings_rad, cfg,
                            tuple((g[1], g[2]) for g in group)))
    return bodies


def _body(x: float, y: float, radius: float, fitted: bool, kind: str, segs: list[_Segment],
          bearings_rad: np.ndarray, cfg: BodiesConfig, legs_xy: tuple[tuple[float, float], ...] = ()) -> Body:
    a = min(sg.start for sg in segs)
    z = max(sg.stop for sg in segs)
    n_pts = sum(sg.points.shape[0] for sg in segs)
    share = sum(sg.free_share * sg.points.shape[0] for sg in segs) / max(n_pts, 1)
    evidence = any(sg.free_share >= cfg.min_free_share or sg.camera for sg in segs)
    # an occluder that is another segment of this body (one leg in front of the other) hides nothing
    occluded = any(not any(o.start <= k < o.stop for o in segs) for sg in segs for k in sg.occluders)
    return Body(x, y, radius, fitted, kind, float(share), any(sg.camera for sg in segs), a, z,
                float(bearings_rad[a]), float(bearings_rad[z - 1]), evidence, occluded, legs_xy=legs_xy)
