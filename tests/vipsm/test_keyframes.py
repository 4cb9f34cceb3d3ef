"""The keyframe's cut beams filled from the old keyframe's view (:func:`vipsm.keyframes.fill_hidden`)."""

from __future__ import annotations

import math

import numpy as np

from tests.vipsm.sim import UTM_BEARINGS, Circle, World
from vipsm.estimator import EstimatorConfig
from vipsm.keyframes import Keyframe, KeyframeMatcher, fill_hidden
from vipsm.psm import prepare_scan
from vipsm.types import Pose2D

CFG = EstimatorConfig()
#: a corridor 3 m wide along x, closed by an end wall at x = 8 m; its side walls run far beyond the range
CORRIDOR = [(-40.0, 1.5, 8.0, 1.5), (-40.0, -1.5, 8.0, -1.5), (8.0, -1.5, 8.0, 1.5)]


def _world(extra_walls: list[tuple[float, float, float, float]] = (), circles: list[Circle] = ()) -> World:
    return World(np.array(CORRIDOR + list(extra_walls), float), list(circles))


def _prepared(world: World, pose: Pose2D, cut_circles: bool) -> tuple[object, np.ndarray]:
    """The scan at ``pose`` prepared for matching, the beams on a circle cut (weight 0) as the restoration
    cuts a moving body; (prepared scan, measured ranges)."""
    d, ident = world.cast(pose.x_m, pose.y_m, UTM_BEARINGS + pose.theta_rad)
    r = np.where(np.isfinite(d), d, np.nan)
    w = np.where(cut_circles & (ident < 0), 0.0, 1.0)
    return prepare_scan(r, UTM_BEARINGS, CFG.psm, w), r


def _end_wall_beams(pose: Pose2D) -> np.ndarray:
    b = UTM_BEARINGS + pose.theta_rad
    y_at_wall = pose.y_m + (8.0 - pose.x_m) * np.tan(b)
    return (np.abs(b) < math.pi / 2) & (np.abs(y_at_wall) < 1.45)


def test_a_cut_body_is_filled_with_the_wall_the_old_keyframe_saw_behind_it() -> None:
    old_pose, new_pose = Pose2D(0.0, 0.0, 0.0), Pose2D(0.4, 0.1, math.radians(3.0))
    old_prep, old_seen = _prepared(_world(), old_pose, False)
    old = Keyframe(old_prep, old_pose, np.zeros((3, 3)), old_prep.n_usable, old_seen)
    body = Circle(3.5, 0.0, 0.6)
    cur, seen = _prepared(_world(circles=[body]), new_pose, True)
    hidden = (cur.weights == 0.0) & _end_wall_beams(new_pose)
    assert hidden.sum() > 20
    filled = fill_hidden(cur, new_pose, seen, seen, old, CFG.laser_mount, CFG.restore.bump_m,
                         CFG.restore.max_body_chord_m, CFG.psm)
    truth, _ = _world().cast(new_pose.x_m, new_pose.y_m, UTM_BEARINGS + new_pose.theta_rad)
    inner = hidden & np.roll(hidden, 2) & np.roll(hidden, -2)  # away from the cut's ends (the median's window)
    assert np.all(filled.weights[inner] == 1.0)
    np.testing.assert_allclose(filled.ranges_m[inner], truth[inner], atol=0.02)
    # the beams outside the cut are as prepared before
    keep = cur.weights > 0.0
    np.testing.assert_array_equal(filled.weights[keep], cur.weights[keep])


def test_no_fill_where_the_old_keyframe_saw_something_nearer_than_the_body_now() -> None:
    """What the old keyframe saw in front of today's body has gone: it is no background behind the body."""
    pose = Pose2D(0.0, 0.0, 0.0)
    old_prep, old_seen = _prepared(_world(extra_walls=[(2.0, -0.5, 2.0, 0.5)]), pose, False)
    old = Keyframe(old_prep, pose, np.zeros((3, 3)), old_prep.n_usable, old_seen)
    cur, seen = _prepared(_world(circles=[Circle(4.0, 0.0, 0.3)]), pose, True)
    filled = fill_hidden(cur, pose, seen, seen, old, CFG.laser_mount, CFG.restore.bump_m,
                         CFG.restore.max_body_chord_m, CFG.psm)
    assert filled is cur


def test_an_old_keyframes_body_is_no_background_for_the_new_one() -> None:
    """A narrow thing the old keyframe saw (a person its cut missed) fills nothing: only segments wider than a
    body (``restore.max_body_chord_m``) are background."""
    pose = Pose2D(0.0, 0.0, 0.0)
    person = Circle(5.0, 0.0, 0.2)
    old_prep, old_seen = _prepared(_world(circles=[person]), pose, False)
    old = Keyframe(old_prep, pose, np.zeros((3, 3)), old_prep.n_usable, old_seen)
    cur, seen = _prepared(_world(circles=[Circle(3.0, 0.0, 0.6)]), pose, True)
    filled = fill_hidden(cur, pose, seen, seen, old, CFG.laser_mount, CFG.restore.bump_m,
                         CFG.restore.max_body_chord_m, CFG.psm)
    _, ident = _world(circles=[person]).cast(0.0, 0.0, UTM_BEARINGS)
    behind_person = (ident < 0) & (cur.weights == 0.0)
    assert behind_person.sum() >= 5
    assert np.all(filled.weights[behind_person] == 0.0)  # nothing known behind it: still cut
    wall = (cur.weights == 0.0) & ~behind_person & _end_wall_beams(pose)
    assert np.mean(filled.weights[wall] == 1.0) > 0.8  # the end wall beside it is filled


def test_the_travel_along_a_corridor_is_measured_after_a_keyframe_whose_end_wall_a_body_hid() -> None:
    """The end wall is all that constrains the travel along a corridor. A body hides it while a keyframe is
    taken (cut there). Once the body has gone, the matches against that keyframe still measure the travel
    (the end wall is in the keyframe, filled from the one before), rather than leaving that direction to
    whatever else the scan holds (in a crowd: legs the cut missed, which pulled the pose along with them)."""
    matcher = KeyframeMatcher(CFG)
    last, cov = None, np.zeros((3, 3))
    hidden_keyframe, measured = False, []
    for k in range(16):
        true = Pose2D(0.05 * k, 0.0, 0.0)
        hidden = 0.3 <= true.x_m <= 0.45
        cur, seen = _prepared(_world(circles=[Circle(true.x_m + 3.0, 0.0, 1.5)] if hidden else []), true, True)
        predicted = true if last is None else Pose2D(last.x_m + 0.05, last.y_m, last.theta_rad)
        out = matcher.match(cur, cur.n_usable, predicted, last, cov, True, False, seen, False, seen)
        if out.keyframe_replaced:
            hidden_keyframe = hidden
        elif hidden_keyframe and not hidden:
            measured.append(float(np.linalg.eigvalsh(out.result.info_xy)[0]))
        last, cov = out.pose, out.cov
    assert measured  # matches against the keyframe taken while the end wall was hidden, the body gone
    assert min(measured) >= CFG.weak_info_min  # along the corridor the scan measures (the odometry is kept below)
    assert abs(last.x_m - true.x_m) < 0.005
