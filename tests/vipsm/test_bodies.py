"""vipsm.bodies: leg pairs become one person, background between legs is no body, evidence."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vipsm.bodies import BodiesConfig, default_derived, extract_bodies
from vipsm.static_map import FreeSpaceGrid
from vipsm.tracker import TrackerConfig
from vipsm.types import Pose2D

from .sim import UTM_BEARINGS, Circle, box_room

CFG = BodiesConfig()
DERIVED = default_derived(CFG, TrackerConfig())
ORIGIN = Pose2D(0.0, 0.0, 0.0)


def _seen_empty(world) -> FreeSpaceGrid:
    grid = FreeSpaceGrid()
    for k in range(10):
        scan = world.scan(ORIGIN)
        grid.integrate(0.1 * k, (0.0, 0.0), 0.0, scan.ranges_m, scan.bearings_rad)
    return grid


def test_a_leg_pair_is_one_person_at_the_pelvis() -> None:
    world = box_room(8.0, 6.0, pillars=False)
    grid = _seen_empty(world)
    world.circles = [Circle(2.5, 0.6, 0.06), Circle(2.7, 0.35, 0.06)]  # mid-stride, 0.32 m apart
    scan = world.scan(ORIGIN)
    bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], CFG, TrackerConfig())
    people = [b for b in bodies if b.kind == "person"]
    assert len(people) == 1 and people[0].evidence
    assert abs(people[0].x_m - 2.6) < 0.03 and abs(people[0].y_m - 0.475) < 0.03


def test_wall_between_the_legs_is_no_body_and_a_resting_leg_has_no_evidence() -> None:
    world = box_room(8.0, 6.0, pillars=False)
    world.circles = [Circle(1.5, 0.12, 0.06), Circle(1.5, -0.12, 0.06), Circle(3.0, -2.0, 0.0125)]
    grid = _seen_empty(world)  # the legs and the chair leg stood there all along
    scan = world.scan(ORIGIN)
    bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], CFG, TrackerConfig())
    assert not any(abs(b.x_m - 6.0) < 0.2 for b in bodies)  # the wall seen between the legs
    assert bodies and not any(b.evidence for b in bodies)  # standing things: no motion evidence


def test_a_straight_wall_piece_is_no_body() -> None:
    world = box_room(8.0, 6.0, pillars=False)
    world.walls = np.vstack([world.walls, [[2.0, 1.0, 2.4, 1.0]]])  # a 0.4 m box face, flat
    grid = FreeSpaceGrid()
    scan = world.scan(ORIGIN)
    bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], CFG, TrackerConfig())
    assert not any(b.kind == "body" and abs(b.y_m - 1.0) < 0.4 for b in bodies)


def test_a_thin_leg_uncovered_from_behind_another_has_no_evidence_with_the_scan_memory() -> None:
    """Issue 11: a table leg hidden behind a chair leg sits in grid cells the beams beside the shadow
    crossed; uncovered, it "violated" free space. At beam resolution it never was seen through."""
    from vipsm.seen_through import ScanMemory

    world = box_room(8.0, 6.0, pillars=False)
    world.circles = [Circle(1.5, 0.0, 0.0125), Circle(3.0, 0.0, 0.0225)]
    grid, memory = FreeSpaceGrid(), ScanMemory()
    for k in range(10):
        scan = world.scan(ORIGIN)
        grid.integrate(0.1 * k, (0.0, 0.0), 0.0, scan.ranges_m, scan.bearings_rad)
        memory.push(ORIGIN, scan.ranges_m, scan.bearings_rad)
    aside = Pose2D(0.0, 0.4, 0.0)
    scan = world.scan(aside)
    args = (scan.ranges_m, scan.bearings_rad, aside, grid, [], CFG, TrackerConfig())
    near = [b for b in extract_bodies(*args) if abs(b.x_m - 3.0) < 0.15 and abs(b.y_m) < 0.15]
    assert near and near[0].evidence  # the grid alone is fooled
    near = [b for b in extract_bodies(*args, None, memory) if abs(b.x_m - 3.0) < 0.15 and abs(b.y_m) < 0.15]
    assert near and not near[0].evidence


def test_a_body_partly_hidden_by_a_nearer_one_is_occluded_a_leg_behind_its_partner_is_not() -> None:
    world = box_room(8.0, 6.0, pillars=False)
    world.circles = [Circle(2.0, 0.0, 0.2), Circle(4.0, 0.25, 0.3)]  # the near body hides the far one's edge
    scan = world.scan(ORIGIN)
    bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, FreeSpaceGrid(), [], CFG, TrackerConfig())
    far = [b for b in bodies if b.x_m > 3.0]
    near = [b for b in bodies if b.x_m < 3.0]
    assert far and far[0].occluded and near and not near[0].occluded
    world.circles = [Circle(2.5, 0.0, 0.06), Circle(2.75, 0.08, 0.06)]  # one leg half behind the other
    scan = world.scan(ORIGIN)
    bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, FreeSpaceGrid(), [], CFG, TrackerConfig())
    people = [b for b in bodies if b.kind == "person"]
    assert len(people) == 1 and not people[0].occluded


def test_a_body_cut_by_the_edge_of_the_field_of_view_is_occluded() -> None:
    """A body leaving the scanner's 270 deg shows a shrinking sliver whose centre moves with the edge: a
    passing cylinder's track followed the sliver, lost it and took furniture as its own."""
    world = box_room(8.0, 6.0, pillars=False)
    edge = float(np.min(world.scan(ORIGIN).bearings_rad))
    cut = (2.0 * np.cos(edge + 0.05), 2.0 * np.sin(edge + 0.05))  # a 0.3 m body straddling the edge
    whole = (2.0 * np.cos(edge + 0.8), 2.0 * np.sin(edge + 0.8))
    world.circles = [Circle(*cut, 0.3), Circle(*whole, 0.3)]
    scan = world.scan(ORIGIN)
    bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, FreeSpaceGrid(), [], CFG, TrackerConfig())
    at_edge = [b for b in bodies if b.scan_index_start == 0]
    inside = [b for b in bodies if np.hypot(b.x_m - whole[0], b.y_m - whole[1]) < 0.1]
    assert at_edge and at_edge[0].occluded
    assert inside and not inside[0].occluded


def test_a_camera_interval_that_holds_a_bodys_occluder_gives_the_hidden_body_no_cue() -> None:
    """A body passing in front of another: the flow's blob of a cylinder passing in front of a box
    spread over the box's edge, which the cylinder covered and uncovered; the box got camera evidence,
    its partial fit drifted, and it was confirmed. The camera sees the front surface move."""
    from vipsm.restore import BearingInterval

    world = box_room(8.0, 6.0, pillars=False)
    world.circles = [Circle(2.0, 0.0, 0.2), Circle(4.0, 0.25, 0.3)]  # the near body hides the far one's edge
    scan = world.scan(ORIGIN)

    def far_cue(lo_deg: float, hi_deg: float) -> bool:
        cam = [BearingInterval(np.radians(lo_deg), np.radians(hi_deg))]
        bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, FreeSpaceGrid(), cam, CFG, TrackerConfig())
        far = [b for b in bodies if b.x_m > 3.0]
        assert far and far[0].occluded
        return far[0].camera

    assert not far_cue(-7.0, 9.0)  # the interval holds the near body: its motion, not the far one's
    assert far_cue(6.2, 9.0)  # only the far body's own beams


def test_a_camera_interval_wider_than_any_body_at_the_segments_range_gives_it_no_cue() -> None:
    """A camera interval wider than any body at the segment's range: the flow merged a passing
    cylinder with the far side of the image, one interval 47 deg wide, and a box 4.3 m away inside it
    got camera evidence and became a track. At 4.3 m that interval is 3.6 m wide, wider than a body
    and the background it uncovers; at 1.7 m (the cylinder) 1.4 m, still a body's."""
    from vipsm.restore import BearingInterval

    world = box_room(12.0, 8.0, pillars=False)
    world.circles = [Circle(1.7, -0.5, 0.3), Circle(4.3, 1.5, 0.25)]
    scan = world.scan(ORIGIN)
    cam = [BearingInterval(np.radians(-27.0), np.radians(21.5)), BearingInterval(np.radians(16.0), np.radians(24.0))]

    def cues(intervals: list) -> dict[str, bool]:
        bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, FreeSpaceGrid(), intervals, CFG,
                                TrackerConfig())
        return {("near" if b.x_m < 3.0 else "far"): b.camera for b in bodies}

    assert cues(cam[:1]) == {"near": True, "far": False}
    assert cues(cam) == {"near": True, "far": True}  # a narrow interval of its own still counts


def _beams_on(scan, x_m: float, y_m: float, radius_m: float) -> np.ndarray:
    """Beams whose return lies on the circle (within 2 cm of its rim)."""
    px = scan.ranges_m * np.cos(scan.bearings_rad)
    py = scan.ranges_m * np.sin(scan.bearings_rad)
    return np.flatnonzero(np.abs(np.hypot(px - x_m, py - y_m) - radius_m) < 0.02)


def test_a_leg_with_a_dropped_return_inside_is_still_a_leg_of_the_person() -> None:
    """A dropout (or a lone spurious return the pre-filter removed) inside a leg split it in two halves,
    each with the other as the same surface beside it: no body for that scan."""
    world = box_room(8.0, 6.0, pillars=False)
    grid = _seen_empty(world)
    world.circles = [Circle(2.5, 0.6, 0.06), Circle(2.7, 0.35, 0.06)]
    scan = world.scan(ORIGIN)
    on = _beams_on(scan, 2.7, 0.35, 0.06)
    assert on.size >= 7
    ranges = scan.ranges_m.copy()
    ranges[on[on.size // 2]] = np.nan
    bodies = extract_bodies(ranges, scan.bearings_rad, ORIGIN, grid, [], CFG, TrackerConfig())
    people = [b for b in bodies if b.kind == "person"]
    assert len(people) == 1 and abs(people[0].x_m - 2.6) < 0.03 and abs(people[0].y_m - 0.475) < 0.03
    split = BodiesConfig(max_gap_beams=0)  # the old segmentation: the split leg is no body, one leg is left
    bodies = extract_bodies(ranges, scan.bearings_rad, ORIGIN, grid, [], split, TrackerConfig())
    assert [b.kind for b in bodies] == ["leg"]


def test_a_leg_before_a_wall_stays_apart_across_the_dropped_mixed_pixel() -> None:
    """The pre-filter drops the mixed pixel at a leg's edge; the gap it leaves is bridged only between
    returns of one surface: a leg 0.2 m in front of a wall stays its own body."""
    from vipsm.bodies import segments

    world = box_room(8.0, 6.0, pillars=False)
    world.circles = [Circle(3.86, 0.0, 0.06)]  # its front 0.2 m before the wall at x = 4
    scan = world.scan(ORIGIN)
    on = _beams_on(scan, 3.86, 0.0, 0.06)
    ranges = scan.ranges_m.copy()
    ranges[on[-1] + 1] = np.nan  # the mixed pixel beside the leg, dropped
    ranges[on[0] - 1] = np.nan
    segs = segments(ranges, scan.bearings_rad, CFG)
    assert (int(on[0]), int(on[-1]) + 1) in segs
    bodies = extract_bodies(ranges, scan.bearings_rad, ORIGIN, FreeSpaceGrid(), [], CFG, TrackerConfig())
    assert any(b.kind == "leg" and abs(b.x_m - 3.86) < 0.03 and abs(b.y_m) < 0.03 for b in bodies)


def test_a_gap_the_pre_filter_made_is_an_occluders_and_is_never_bridged() -> None:
    """A thin occluder, a chair leg 0.8 m in front of a box, shows as one or two returns the
    pre-filter removes (a lone return, a mixed pixel); bridged, the box was whole in one scan and cut
    by the leg in the next, its circle fit jumped 0.1 m between the two and the static box was
    reported moving. Only a gap with no echo (a dropout) is bridged."""
    from vipsm.bodies import segments

    world = box_room(8.0, 6.0, pillars=False)
    world.circles = [Circle(3.0, 0.5, 0.3)]
    scan = world.scan(ORIGIN)
    on = _beams_on(scan, 3.0, 0.5, 0.3)
    mid = int(on[on.size // 2])
    ranges = scan.ranges_m.copy()
    ranges[mid] = np.nan
    dropped = np.zeros(ranges.size, bool)
    assert (int(on[0]), int(on[-1]) + 1) in segments(ranges, scan.bearings_rad, CFG)  # a dropout: bridged
    dropped[mid] = True  # the pre-filter removed a thin thing's return there
    segs = segments(ranges, scan.bearings_rad, CFG, dropped)
    assert (int(on[0]), mid) in segs and (mid + 1, int(on[-1]) + 1) in segs


def test_a_post_that_stood_there_is_a_fixture_never_a_passers_leg_partner() -> None:
    """A walker's leg passing 0.6 m from a post (on a recorded pedestrian path): the two were paired into
    a "person" between them, the track moved onto the post and predicted it into the robot's path."""
    world = box_room(8.0, 6.0, pillars=False)
    world.circles = [Circle(2.5, -1.2, 0.05)]  # the post, seen for 3 s
    grid = FreeSpaceGrid()
    for k in range(30):
        scan = world.scan(ORIGIN)
        grid.integrate(0.1 * k, (0.0, 0.0), 0.0, scan.ranges_m, scan.bearings_rad)
    world.circles = [Circle(2.5, -1.2, 0.05), Circle(2.7, -1.75, 0.06)]  # a leg steps into seen-free space
    scan = world.scan(ORIGIN)
    bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], CFG, TrackerConfig())
    assert sorted(b.kind for b in bodies) == ["leg", "leg"]
    post = min(bodies, key=lambda b: math.hypot(b.x_m - 2.5, b.y_m + 1.2))
    leg = min(bodies, key=lambda b: math.hypot(b.x_m - 2.7, b.y_m + 1.75))
    assert not post.evidence and leg.evidence
    loose = BodiesConfig(fixture_occupied=1e9)  # without the rule: one "person" between post and leg
    bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], loose, TrackerConfig())
    assert [b.kind for b in bodies] == ["person"]


def test_a_leg_that_stood_for_a_step_is_no_fixture() -> None:
    """A stance leg stays ~0.6 s: it pairs with the swinging one as before."""
    world = box_room(8.0, 6.0, pillars=False)
    grid = _seen_empty(world)
    world.circles = [Circle(2.5, 0.6, 0.06)]
    for k in range(6):
        scan = world.scan(ORIGIN)
        grid.integrate(1.0 + 0.1 * k, (0.0, 0.0), 0.0, scan.ranges_m, scan.bearings_rad)
    world.circles = [Circle(2.5, 0.6, 0.06), Circle(2.7, 0.35, 0.06)]
    scan = world.scan(ORIGIN)
    bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], CFG, TrackerConfig())
    assert [b.kind for b in bodies] == ["person"] and bodies[0].evidence


def test_a_person_who_stood_and_takes_the_first_step_is_still_a_pair() -> None:
    """curve_crossing: a person stood for seconds by the wall, then walked; both legs' cells were long
    occupied. The stance leg is no fixture: its partner stood beside it (standing), then left a
    long-occupied cell the laser now sees through (the first step)."""
    world = box_room(8.0, 6.0, pillars=False)
    grid = _seen_empty(world)
    world.circles = [Circle(2.5, 0.6, 0.06), Circle(2.5, 0.35, 0.06)]  # standing, feet 0.25 m apart
    for k in range(30):
        scan = world.scan(ORIGIN)
        grid.integrate(1.0 + 0.1 * k, (0.0, 0.0), 0.0, scan.ranges_m, scan.bearings_rad)
    scan = world.scan(ORIGIN)
    bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], CFG, TrackerConfig())
    assert [b.kind for b in bodies] == ["person"] and not bodies[0].evidence  # standing: no candidate
    world.circles = [Circle(2.5, 0.6, 0.06), Circle(2.35, 0.1, 0.06)]  # the right foot swings ahead
    scan = world.scan(ORIGIN)
    bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], CFG, TrackerConfig())
    assert [b.kind for b in bodies] == ["person"] and bodies[0].evidence



def test_a_long_occupied_cell_left_or_hidden_counts_as_vacated_one_still_ending_a_beam_does_not() -> None:
    """A walker's first step straight at the laser (head-on): the swing leg hid its own
    long-occupied cell from the beam; a cell whose beam ends nearer (hidden) or farther (seen
    through) than it no longer holds what stood there; one whose beam still ends in it does (a box
    beside a post)."""
    from vipsm.bodies import _vacated_near

    grid = FreeSpaceGrid()
    grid.integrate(0.0, (0.0, 0.0), 0.0, np.array([np.nan]), np.array([0.0]))  # anchor the grid at the origin
    i, j, _ = grid._cells(np.array([[2.55, 0.45]]))
    grid.occ[i[0], j[0]] = 30.0  # the other leg stood here
    bearings = UTM_BEARINGS
    stance = np.array([[2.54, 0.68], [2.54, 0.70], [2.54, 0.72]])
    cell_bearing = math.atan2(0.45, 2.55)
    near_cell = np.abs(bearings - cell_bearing) < math.radians(1.0)
    dist = math.hypot(2.55, 0.45)
    for beam_m, vacated in ((dist, False), (2.2, True), (4.0, True)):
        ranges = np.full(bearings.size, 4.0)
        ranges[near_cell] = beam_m
        assert _vacated_near(stance, ranges, bearings, ORIGIN, grid, CFG, DERIVED) is vacated, beam_m


def test_the_derived_quantities_follow_the_keys_they_come_from() -> None:
    """Issue 29: one physical quantity, one key. The person's sizes are the people stage's keys, the widest
    camera interval about one body is the widest body plus what the fastest body uncovers in the flow's
    baseline, a fixture's own reach half the widest leg plus half a cell's diagonal, the neighbour search
    the narrowest splitting gap plus one."""
    from dataclasses import replace

    from vipsm.estimator import EstimatorConfig
    from vipsm.flow import FlowConfig
    from vipsm.people import PeopleConfig
    from vipsm.static_map import StaticMapConfig

    d = EstimatorConfig().bodies_derived
    assert (d.leg_radius_m, d.leg_pair_max_m, d.person_radius_m, d.leg_across_max_m) == (0.06, 0.65, 0.25, 0.3)
    assert d.camera_interval_max_m == pytest.approx(1.2 + 2.5 * 0.3)
    assert d.fixture_own_m == pytest.approx(0.125 + 0.05 * math.sqrt(2.0))
    cfg = EstimatorConfig(people=PeopleConfig(leg_radius_m=0.05, leg_pair_max_m=0.5, person_radius_m=0.3,
                                              leg_across_max_m=0.25),
                          tracker=replace(TrackerConfig(), max_speed_mps=1.5), flow=FlowConfig(baseline_s=0.2),
                          bodies=BodiesConfig(max_body_width_m=1.0, max_leg_width_m=0.2),
                          static_map=StaticMapConfig(cell_m=0.2))
    d = cfg.bodies_derived
    assert (d.leg_radius_m, d.leg_pair_max_m, d.person_radius_m, d.leg_across_max_m) == (0.05, 0.5, 0.3, 0.25)
    assert d.camera_interval_max_m == pytest.approx(1.0 + 1.5 * 0.2)
    assert d.fixture_own_m == pytest.approx(0.1 + 0.1 * math.sqrt(2.0))
    assert BodiesConfig(max_gap_beams=0).neighbour_beams == 2 and CFG.neighbour_beams == 4
    with pytest.raises(ValueError, match="people.leg_pair_max_m"):
        EstimatorConfig(people=PeopleConfig(leg_pair_max_m=0.15))


def test_the_people_stages_pair_distance_is_the_one_the_body_stage_pairs_legs_with() -> None:
    """Two legs 0.32 m apart are one person with the default stride, two lone legs when the people stage's
    ``leg_pair_max_m`` is shorter than that: the body stage has no key of its own for it."""
    from vipsm.bodies import derive
    from vipsm.people import PeopleConfig

    world = box_room(8.0, 6.0, pillars=False)
    grid = _seen_empty(world)
    world.circles = [Circle(2.5, 0.6, 0.06), Circle(2.7, 0.35, 0.06)]
    scan = world.scan(ORIGIN)
    args = (scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], CFG, TrackerConfig(), None, None, None)
    assert [b.kind for b in extract_bodies(*args, DERIVED)] == ["person"]
    short = derive(CFG, PeopleConfig(leg_pair_max_m=0.3), TrackerConfig(), 0.3, 0.1)
    assert [b.kind for b in extract_bodies(*args, short)] == ["leg", "leg"]


def _in_step(t_s: float) -> tuple[list[tuple[float, float]], list[tuple[float, float]]]:
    """Two walkers side by side 0.4 m apart (pelvises at y = +-0.2), walking along +x at 1 m/s in step:
    (the pelvises, the four legs: walker 0's two, then walker 1's). Each leg stands for half a gait cycle
    (1 s) and swings for the other half, up to 0.6 m along and a hip's 0.16 m across from its other leg."""
    x = 2.0 + 1.0 * t_s
    phase = (t_s % 1.0) / 1.0
    along = 0.3 * (1.0 - 4.0 * phase if phase < 0.5 else 4.0 * phase - 3.0)  # +0.3 -> -0.3 -> +0.3
    pelvis = [(x, 0.2), (x, -0.2)]
    legs = [(px + s * along, py + s * 0.08) for px, py in pelvis for s in (1.0, -1.0)]
    return pelvis, legs


def test_two_walkers_side_by_side_in_step_each_get_a_pair_of_their_own_legs() -> None:
    """In step, each leg has the other walker's same leg 0.4 m across, nearer than its own other leg (up
    to a stride and a hip's width away): nearest-first pairing alone pairs one leg of each walker into a
    "person" between them. With the people stage's leg tracks (a person is two leg tracks whose
    association persists, leg_tracker's model), a moving person's legs pair only with each other: once the
    people stage has told the walkers apart (they walk from the first scan), every leg pair is one walker's
    own, at its pelvis."""
    from app.legmodel import default_leg_model
    from vipsm.people import LegDetection, PeopleConfig, PeopleTracker

    world = box_room(10.0, 6.0, pillars=False)
    grid = _seen_empty(world)
    people = PeopleTracker(PeopleConfig(), default_leg_model())
    rng = np.random.default_rng(29)
    own = cross = alone_off = 0
    for k in range(30):
        t = 0.1 * k
        pelvis, legs = _in_step(t)
        world.circles = [Circle(x, y, 0.06) for x, y in legs]
        scan = world.scan(ORIGIN, t_s=t, stamp_s=t)
        known = people.known_legs(t)
        bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], CFG, TrackerConfig(),
                                known_legs=known)
        plain = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], CFG, TrackerConfig())
        # the people stage's legs (its detector is tested in test_people.py): each leg, 2 cm of noise
        people.step(t, [LegDetection(x + rng.normal(0, 0.02), y + rng.normal(0, 0.02), 0.9, 2 * i, 2 * i + 1)
                        for i, (x, y) in enumerate(legs)])
        if t < 1.0:  # the people stage tells the walkers apart once they walk (stage 6b)
            continue
        for b in (b for b in bodies if b.kind == "person"):
            near = min(math.hypot(b.x_m - px, b.y_m - py) for px, py in pelvis)
            own += near < 0.05
            alone_off += near >= 0.05
        cross += sum(b.kind == "person" and min(math.hypot(b.x_m - px, b.y_m - py) for px, py in pelvis) > 0.1
                     for b in plain)
    assert cross >= 6  # nearest-first alone: a pair between the walkers whenever the strides are long (8 of 40)
    assert own == 40 and alone_off == 0  # two pairs, each at its walker's pelvis, in each of the 20 scans


def test_two_legs_side_by_side_across_their_line_of_walking_are_two_walkers_not_one_person() -> None:
    """A leg steps and swings along its person's line of walking, a hip's width beside its other leg
    (``people.leg_across_max_m``). Two legs 0.4 m apart side by side across the line both walk along (two
    walkers in step, each seen by one leg, the other hidden) are two lone legs once the people stage's leg
    tracks say they walk; with no line known (standing, or new legs) they are one person by distance. A
    walker's own two legs, a stride apart along the line, stay one person."""
    from vipsm.bodies import KnownLeg

    world = box_room(8.0, 6.0, pillars=False)
    grid = _seen_empty(world)

    def kinds(legs: list[tuple[float, float]], line: tuple[float, float] | None, sigma_rad: float = 0.0) -> list[str]:
        world.circles = [Circle(x, y, 0.06) for x, y in legs]
        scan = world.scan(ORIGIN)
        known = [KnownLeg(x, y, 0.1, None, line, sigma_rad) for x, y in legs]
        return sorted(b.kind for b in extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], CFG,
                                                     TrackerConfig(), known_legs=known))

    side_by_side = [(3.0, 0.3), (3.0, -0.1)]  # 0.4 m across a walk along x
    assert kinds(side_by_side, None) == ["person"]  # nothing known: one standing person's stance
    assert kinds(side_by_side, (1.0, 0.0)) == ["leg", "leg"]  # both walk along x: two walkers
    assert kinds(side_by_side, (0.0, 1.0)) == ["person"]  # walking along y: a stride along the line
    own = [(3.3, 0.18), (2.8, 0.02)]  # a stride along x, a hip's 0.16 m across
    assert kinds(own, (1.0, 0.0)) == ["person"]
    # a line 0.2 rad off (a young track's velocity) still keeps a walker's own legs one person
    tilted = (math.cos(0.2), math.sin(0.2))
    assert kinds(own, tilted) == ["person"]
    # a stride along y judged against a line 0.6 rad off lies 0.34 m across it: two legs if the line were
    # sure, one person when the line's direction is uncertain by 0.2 rad (the bound widens by two sigma
    # times the offset along it); side by side (nothing along) the uncertainty changes nothing
    stride, off = [(3.0, 0.4), (3.0, -0.2)], (math.sin(0.6), math.cos(0.6))
    assert kinds(stride, off) == ["leg", "leg"] and kinds(stride, off, 0.2) == ["person"]
    assert kinds(side_by_side, (1.0, 0.0), 0.2) == ["leg", "leg"]


def test_the_people_stage_gives_each_walking_leg_its_line_of_walking() -> None:
    """``PeopleTracker.known_legs``: a leg track of a walking person carries the person's line of walking,
    a leg seen once carries none (no velocity yet)."""
    from app.legmodel import default_leg_model
    from vipsm.people import LegDetection, PeopleConfig, PeopleTracker

    people = PeopleTracker(PeopleConfig(), default_leg_model())
    assert all(k.line is None for k in people.known_legs(0.0))
    for k in range(12):
        t = 0.1 * k
        _, legs = _in_step(t)
        people.step(t, [LegDetection(x, y, 0.9, 2 * i, 2 * i + 1) for i, (x, y) in enumerate(legs[:2])])
        if k == 0:
            assert [k.line for k in people.known_legs(0.1)] == [None, None]
    lines = [k.line for k in people.known_legs(1.2)]
    assert len(lines) == 2 and all(line is not None and line[0] > 0.95 for line in lines)  # along +x


def test_a_box_beside_a_leg_as_near_as_its_corner_is_a_body_partly_hidden() -> None:
    """A box seen by its corner (a cart turned 45 deg, its corner 1.68 m out, its far end 2.14 m) with a
    leg (its pusher's) beside that end, 1.64 m out: the leg hides the box's end, so the box is a body
    partly hidden by it. Judged against the box's nearest return (the corner), the leg looked like the
    same surface going on, and the box was part of something larger: no body (the cart lost for scans
    while its pusher's leg stood beside it)."""
    world = box_room(8.0, 6.0, pillars=False)
    cx, h = 2.1, 0.3 * math.sqrt(2.0)
    corners = [(cx - h, 0.0), (cx, -h), (cx + h, 0.0), (cx, h)]
    world.walls = np.vstack([world.walls, [[*corners[i], *corners[(i + 1) % 4]] for i in range(4)]])
    world.circles = [Circle(1.7 * math.cos(-0.225), 1.7 * math.sin(-0.225), 0.06)]
    scan = world.scan(ORIGIN)
    bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, FreeSpaceGrid(), [], CFG, TrackerConfig())
    box = [b for b in bodies if b.kind == "body" and math.hypot(b.x_m - cx, b.y_m) < 0.1]
    assert len(box) == 1 and box[0].occluded
    assert any(b.kind == "leg" and math.hypot(b.x_m - 1.66, b.y_m + 0.38) < 0.05 for b in bodies)


def test_a_standing_persons_seen_leg_pairs_only_with_its_own_other_leg() -> None:
    """A person standing still, tracked by the people stage as two leg tracks, has one leg hidden (behind
    the other, or by the robot's turn) while a leg-sized piece of something else stands 0.45 m beside the
    seen leg, beyond a leg's reach since it was last seen (a cart's corner come into view). Nearest first,
    the seen leg pairs with the piece: a "person" 0.3 m off the pelvis, which the body tracker read as a
    step. A person's two leg tracks are one person's, standing or walking (leg_tracker's model): the seen
    leg pairs only with its own other leg, so the leg and the piece stay two lone legs, and with both legs
    seen the person is a pair at its pelvis."""
    from app.legmodel import default_leg_model
    from vipsm.people import LegDetection, PeopleConfig, PeopleTracker

    world = box_room(8.0, 6.0, pillars=False)
    grid = _seen_empty(world)
    people = PeopleTracker(PeopleConfig(), default_leg_model())
    legs = [(3.0, 0.1), (3.0, -0.1)]
    for k in range(20):
        people.step(0.1 * k, [LegDetection(x, y, 0.9, 2 * i, 2 * i + 1) for i, (x, y) in enumerate(legs)])
    t = 2.0

    def kinds(circles: list[tuple[float, float]], known: bool) -> list[str]:
        world.circles = [Circle(x, y, 0.06) for x, y in circles]
        scan = world.scan(ORIGIN, t_s=t, stamp_s=t)
        return sorted(b.kind for b in extract_bodies(scan.ranges_m, scan.bearings_rad, ORIGIN, grid, [], CFG,
                                                     TrackerConfig(),
                                                     known_legs=people.known_legs(t) if known else None))

    piece = (3.0, 0.55)
    assert kinds([legs[0], piece], known=False) == ["person"]  # nearest first: the leg and the piece
    assert kinds([legs[0], piece], known=True) == ["leg", "leg"]
    assert kinds(legs, known=True) == ["person"]


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_segment_median_is_numpys_median(dtype) -> None:
    from vipsm.bodies import _median

    rng = np.random.default_rng(7)
    for n in range(1, 40):
        for _ in range(20):
            x = (rng.normal(size=n) * 10.0).astype(dtype)
            x[: n // 3] = np.round(x[: n // 3])  # ties
            assert _median(x) == float(np.median(x))


@pytest.mark.parametrize("slope_deg", [30.0, 80.0, 95.0, 150.0])
def test_a_piece_of_a_straight_surface_that_goes_on_beside_it_is_told_from_a_round_body(slope_deg: float) -> None:
    """A wall piece seen at grazing incidence, with the wall's next return beside it, continues a surface at
    any slope; the front arc of a round body, with the same return beside it, does not; nor does a straight
    piece with the return beside it off its line."""
    from vipsm.bodies import _continues_a_surface

    cfg = BodiesConfig()
    laser = Pose2D(0.0, 0.0, 0.0)
    u = np.array([math.cos(math.radians(slope_deg)), math.sin(math.radians(slope_deg))])
    start = np.array([3.0, 0.5])
    wall = np.array([start + t * u for t in np.linspace(0.0, 0.3, 7)] + [start + 0.45 * u])
    r, b = np.hypot(wall[:, 0], wall[:, 1]), np.arctan2(wall[:, 1], wall[:, 0])
    order = np.argsort(b)
    r, b = r[order], b[order]
    beside = int(np.flatnonzero(order == 7)[0])  # the wall's return beside the piece
    a, z = (0, 7) if beside == 7 else (1, 8)
    pts = np.stack([r[a:z] * np.cos(b[a:z]), r[a:z] * np.sin(b[a:z])], axis=1)
    assert _continues_a_surface(pts, r, b, a, z, laser, cfg)
    off = r.copy()
    off[beside] += 0.3  # the return beside lies well behind the piece's line
    assert not _continues_a_surface(pts, off, b, a, z, laser, cfg)
    arc = np.array([[3.0 - 0.2 * math.cos(t), 0.5 + 0.2 * math.sin(t)] for t in np.linspace(-1.0, 1.0, 7)])
    assert not _continues_a_surface(arc, r, b, a, z, laser, cfg)
