"""vipsm.seen_through: the free-space test at beam resolution (a thin leg uncovered from behind
another was never seen through, though its 10 cm grid cell was crossed)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from vipsm.seen_through import ScanMemory, SeenThroughConfig
from vipsm.static_map import FreeSpaceGrid
from vipsm.types import Pose2D

from .sim import UTM_BEARINGS, Circle, box_room

A = Pose2D(0.0, 0.0, 0.0)


def _points(scan, pose: Pose2D) -> np.ndarray:
    ang = pose.theta_rad + scan.bearings_rad
    return np.stack([pose.x_m + scan.ranges_m * np.cos(ang), pose.y_m + scan.ranges_m * np.sin(ang)], axis=1)


def test_a_table_leg_uncovered_from_behind_a_chair_leg_was_never_seen_through() -> None:
    world = box_room(8.0, 6.0, pillars=False)
    world.circles = [Circle(1.5, 0.0, 0.0125), Circle(3.0, 0.0, 0.0225)]  # chair leg hides the table leg
    grid, memory = FreeSpaceGrid(), ScanMemory()
    for k in range(10):
        scan = world.scan(A)
        grid.integrate(0.1 * k, (0.0, 0.0), 0.0, scan.ranges_m, scan.bearings_rad)
        memory.push(A, scan.ranges_m, scan.bearings_rad)
    b = Pose2D(0.0, 0.4, 0.0)  # the robot moved aside: the table leg comes into view
    pts = _points(world.scan(b), b)
    leg = pts[np.hypot(pts[:, 0] - 3.0, pts[:, 1]) < 0.05]
    assert leg.shape[0] >= 3
    assert grid.violates(leg).all()  # the grid's cells around it were crossed by beams beside the shadow
    assert not memory.seen_through(leg).any()  # no beam ever passed beyond the leg itself


def test_space_the_beams_passed_is_seen_through_surfaces_and_unknown_space_are_not() -> None:
    world = box_room(8.0, 6.0, pillars=False)
    memory = ScanMemory()
    scan = world.scan(A)
    memory.push(A, scan.ranges_m, scan.bearings_rad)
    pts = np.array([[2.0, 0.5], [5.95, 0.0], [6.5, 0.0], [-1.0, 0.1], [2.0, 0.0]])
    # open floor / at the far wall (x = 6) / behind it / behind the laser (outside its 270 deg) / open floor
    assert memory.seen_through(pts).tolist() == [True, False, False, False, True]


def test_a_beam_without_return_is_no_evidence_of_free_space() -> None:
    world = box_room(8.0, 6.0, pillars=False)
    scan = world.scan(A)
    r = scan.ranges_m.copy()
    k = int(np.argmin(np.abs(scan.bearings_rad)))
    r[k - 3 : k + 4] = np.nan  # dropped (a mixed pixel, a dark surface)
    memory = ScanMemory()
    memory.push(A, r, scan.bearings_rad)
    assert not memory.seen_through(np.array([[3.0, 0.0]]))[0]
    assert memory.seen_through(np.array([[3.0, 0.5]]))[0]


def test_a_beam_without_return_counts_as_beyond_only_when_seen_from_the_same_place() -> None:
    """Open space beyond the range returns nothing: a point in front of it was seen through when the laser
    looked from where it looks now (a thing standing there then, seen from the same place, would have echoed
    as it does now, or not at all), but not from another viewpoint, where a dark thing may send no echo back
    and still stand there."""
    world = box_room(8.0, 6.0, pillars=False)
    scan = world.scan(A)
    r = scan.ranges_m.copy()
    k = int(np.argmin(np.abs(scan.bearings_rad)))
    r[k - 12 : k + 13] = np.nan  # nothing echoed around the point's bearing
    point = np.array([[3.0, 0.0]])
    for observer, seen in ((A, True), (Pose2D(0.0, 0.0, math.radians(30.0)), False),
                           (Pose2D(0.6, 0.0, 0.0), False)):
        memory = ScanMemory()
        memory.push(A, r, scan.bearings_rad, sigma_rad=0.0)
        memory.observe(observer, 0.0)
        assert not memory.seen_through(point)[0]  # by default a missing echo is no evidence
        assert memory.seen_through(point, same_view_echoless=True)[0] == seen


def test_any_kept_scan_counts_and_the_memory_is_bounded() -> None:
    world = box_room(8.0, 6.0, pillars=False)
    memory = ScanMemory(SeenThroughConfig(scans=3))
    world.circles = [Circle(3.0, 0.0, 0.2)]
    scan = world.scan(A)
    memory.push(A, scan.ranges_m, scan.bearings_rad)  # the body stood there
    world.circles = []
    empty = world.scan(A)
    memory.push(A, empty.ranges_m, empty.bearings_rad)  # then the space was free
    assert memory.seen_through(np.array([[2.9, 0.0]]))[0]
    for _ in range(5):
        memory.push(A, scan.ranges_m, scan.bearings_rad)
    assert len(memory) == 3 and not memory.seen_through(np.array([[2.9, 0.0]]))[0]


def test_only_the_scans_since_the_given_stamp_are_asked() -> None:
    world = box_room(8.0, 6.0, pillars=False)
    memory = ScanMemory()
    empty = world.scan(A)
    memory.push(A, empty.ranges_m, empty.bearings_rad, stamp_s=0.0)  # the space was free ...
    world.circles = [Circle(3.0, 0.0, 0.2)]
    scan = world.scan(A)
    memory.push(A, scan.ranges_m, scan.bearings_rad, stamp_s=1.0)  # ... then a body stood there
    point = np.array([[2.9, 0.0]])
    assert memory.seen_through(point)[0] and memory.seen_through(point, since_s=0.0)[0]
    assert not memory.seen_through(point, since_s=0.5)[0]


def test_a_moved_laser_is_taken_into_account() -> None:
    world = box_room(8.0, 6.0, pillars=False)
    pose = Pose2D(1.0, 1.0, math.radians(30.0))
    scan = world.scan(pose)
    memory = ScanMemory()
    memory.push(pose, scan.ranges_m, scan.bearings_rad)
    wall = _points(scan, pose)[540]
    ahead = pose.x_m + 0.5 * (wall[0] - pose.x_m), pose.y_m + 0.5 * (wall[1] - pose.y_m)
    assert memory.seen_through(np.array([ahead]))[0] and not memory.seen_through(wall[None, :])[0]


def test_bad_input_is_refused() -> None:
    with pytest.raises(ValueError):
        ScanMemory(SeenThroughConfig(scans=0))
    with pytest.raises(ValueError):
        ScanMemory().push(A, np.ones(5), UTM_BEARINGS)
    assert ScanMemory().seen_through(np.zeros((0, 2))).shape == (0,)
    empty = ScanMemory()
    empty.push(A, np.zeros(0), np.zeros(0))  # an unusable, empty scan saw nothing through
    assert not empty.seen_through(np.array([[1.0, 0.0]]))[0]


def test_a_scan_in_falling_bearing_order_is_read_the_same() -> None:
    world = box_room(8.0, 6.0, pillars=False)
    scan = world.scan(A)
    fwd, rev = ScanMemory(), ScanMemory()
    fwd.push(A, scan.ranges_m, scan.bearings_rad)
    rev.push(A, scan.ranges_m[::-1], scan.bearings_rad[::-1])
    pts = np.array([[2.0, 0.5], [5.95, 0.0], [1.0, -1.0], [6.5, 0.0]])
    assert fwd.seen_through(pts).tolist() == rev.seen_through(pts).tolist() == [True, False, True, False]


def test_a_heading_error_after_a_turn_is_no_evidence_but_real_motion_still_is() -> None:
    """A post 4 m away, seen before a 90 deg turn and again after it with the heading 1 deg off: its
    outline lands 7 cm beside itself, where the earlier scan's beams passed beyond. That is the pose's
    error, not motion: the window widens by the heading uncertainty between the two scans (one match error
    per keyframe step of turn between them). A body that really moved into the seen-free space is still
    found."""
    world = box_room(8.0, 6.0, x0=-2.0, y0=-3.0, pillars=False)
    world.circles = [Circle(4.0, 0.0, 0.10)]
    memory = ScanMemory()
    before = world.scan(A)
    memory.push(A, before.ranges_m, before.bearings_rad, 0.0)
    turned = Pose2D(0.0, 0.0, math.pi / 2)
    seen_as = Pose2D(0.0, 0.0, math.pi / 2 + math.radians(1.0))  # the matched pose, 1 deg off
    after = world.scan(turned, UTM_BEARINGS)
    pts = _points(after, seen_as)
    post = pts[np.hypot(pts[:, 0] - 4.0, pts[:, 1]) < 0.25]
    assert post.shape[0] >= 5
    moved = np.array([[3.0, 0.6], [2.0, -1.0]])  # a body where the beams passed before the turn
    assert memory.seen_through(post).any()  # without the pose's uncertainty: a false violation
    memory.observe(seen_as, 0.0)
    assert not memory.seen_through(post).any()
    assert memory.seen_through(moved).all()
    # a still laser keeps the plain window; the uncertainty grows with the turn and the distance between
    assert memory.relative_heading_sigma_rad(A, 0.0, A, 0.0) == 0.0
    step = SeenThroughConfig().heading_sigma_rad
    assert memory.relative_heading_sigma_rad(A, 0.0, turned, 0.0) == pytest.approx(step * math.sqrt(9.0))
    assert memory.relative_heading_sigma_rad(A, 0.0, Pose2D(1.2, 0.0, 0.0), 0.0) == pytest.approx(2.0 * step)


def test_a_skewed_scan_widens_the_window_and_bad_settings_are_refused() -> None:
    memory = ScanMemory()
    plain = memory.relative_heading_sigma_rad(A, 0.0, A, 0.0)
    assert memory.relative_heading_sigma_rad(A, 0.02, A, 0.0) > plain
    with pytest.raises(ValueError):
        memory.observe(A, -0.1)
    with pytest.raises(ValueError):
        ScanMemory(SeenThroughConfig(step_angle_rad=0.0))
    with pytest.raises(ValueError):
        ScanMemory(SeenThroughConfig(pose_tol_m=0.06))


def test_a_still_laser_keeps_the_plain_window() -> None:
    """Heading noise that moves a return by less than pose_tol_m (held in lateral_tol_m) widens nothing: the
    answers with the observer's pose given equal those without, point for point."""
    world = box_room(8.0, 6.0, x0=-2.0, y0=-3.0, pillars=True)
    world.circles = [Circle(3.0, 0.5, 0.06), Circle(2.0, -1.0, 0.03)]
    memory = ScanMemory()
    scan = world.scan(A)
    memory.push(A, scan.ranges_m, scan.bearings_rad, math.radians(0.05))
    grid = np.stack(np.meshgrid(np.linspace(0.5, 5.5, 60), np.linspace(-2.5, 2.5, 60)), axis=-1).reshape(-1, 2)
    plain = memory.seen_through(grid)
    memory.observe(Pose2D(0.002, 0.0, math.radians(0.02)), math.radians(0.05))
    assert np.array_equal(memory.seen_through(grid), plain)
    with pytest.raises(ValueError):
        ScanMemory(SeenThroughConfig(heading_sigma_rad=-0.01))


def test_ahead_of_the_keyframe_allows_for_the_scanners_range_noise() -> None:
    """A still laser with 4 cm range noise before a room: two scans' ranges differ by more than the fixed
    5 cm now and then on every wall; a step towards the laser counts only beyond the scatter the match's
    own residual shows. A box put 0.4 m in front of the wall still stands ahead."""
    from vipsm.estimator import Estimator, EstimatorConfig
    from vipsm.types import Odometry

    world = box_room(8.0, 6.0, x0=-2.0, y0=-3.0, pillars=False)
    rng = np.random.default_rng(11)
    est = Estimator(EstimatorConfig())
    odo = Odometry(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    for k in range(4):
        est.step(world.scan(A, noise_m=0.04, rng=rng, stamp_s=0.1 * k), replace(odo, stamp_s=0.1 * k))
    scan = world.scan(A, noise_m=0.04, rng=rng, stamp_s=0.4)
    r = scan.ranges_m.copy()
    box = np.abs(scan.bearings_rad) < math.radians(3.0)
    r[box] -= 0.4
    scan = replace(scan, ranges_m=r)
    est.step(scan, replace(odo, stamp_s=0.4))
    ahead = est._ahead_of_keyframe(scan, est.last_debug.match)  # noqa: SLF001 - the evidence stage's input
    assert ahead is not None and ahead[box].mean() > 0.9
    assert ahead[~box].mean() < 0.002  # a fixed 5 cm margin flags 1.6 % of the wall beams here


def test_a_position_error_after_driving_is_no_evidence() -> None:
    """The robot drove 1.2 m past a post 1.3 m beside its path and the match placed it 7 cm too far along:
    the post's outline lands where the earlier scan's beams passed beside it. One match's position error per
    keyframe step (a random walk, here 2 sigma = 8 cm) widens the window; a body 0.5 m into the seen-free
    space still counts."""
    world = box_room(8.0, 6.0, x0=-2.0, y0=-3.0, pillars=False)
    world.circles = [Circle(0.0, 1.3, 0.05)]
    memory = ScanMemory()
    before = world.scan(A)
    memory.push(A, before.ranges_m, before.bearings_rad, 0.0)
    there = Pose2D(1.2, 0.0, 0.0)
    seen_as = Pose2D(1.27, 0.0, 0.0)  # the matched pose, 7 cm too far along the path
    pts = _points(world.scan(there), seen_as)
    post = pts[np.hypot(pts[:, 0] - 0.07, pts[:, 1] - 1.3) < 0.08]
    assert post.shape[0] >= 3
    assert memory.seen_through(post).any()  # without the position's uncertainty: a false violation
    memory.observe(seen_as, 0.0)
    assert memory.relative_position_sigma_m(A, seen_as) == pytest.approx(0.02 * math.sqrt(1.27 / 0.3))
    assert not memory.seen_through(post).any()
    assert memory.seen_through(np.array([[0.6, 1.3]])).all()
