"""Scan restoration: selection, cut, bridge, invalid bridges, refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vipsm.restore import BearingInterval, RestoreConfig, restore
from vipsm.types import Pose2D

from .sim import UTM_BEARINGS, Circle, World, box_room


def _interval_around(x: float, y: float, r: float, pad_deg: float = 0.0) -> BearingInterval:
    b = math.atan2(y, x)
    half = math.asin(r / math.hypot(x, y)) + math.radians(pad_deg)
    return BearingInterval(b - half, b + half)


def test_body_in_front_of_a_wall_is_cut_and_bridged_with_zero_weight() -> None:
    world = World(np.array([(3.0, -5.0, 3.0, 5.0)], dtype=float), [Circle(1.5, 0.0, 0.3)])
    scan = world.scan(Pose2D(0, 0, 0))
    res = restore(scan.ranges_m, scan.bearings_rad, [_interval_around(1.5, 0.0, 0.3)])
    assert not res.too_large and not res.bridge_invalid
    assert len(res.obstacles) == 1
    ob = res.obstacles[0]
    hit = np.flatnonzero(scan.ranges_m < 2.0)
    assert ob.start == hit[0] and ob.stop == hit[-1] + 1  # exactly the body's beams
    lo, hi = res.cut[0]
    assert lo <= ob.start and hi >= ob.stop
    assert np.all(res.weights[lo:hi] == 0.0) and np.all(res.weights[:lo] == 1.0)
    # the bridge lies on the wall behind (straight line in range between the neighbours)
    wall = 3.0 / np.cos(scan.bearings_rad[lo:hi])
    assert np.max(np.abs(res.ranges_m[lo:hi] - wall)) < 0.01
    assert np.all(np.isfinite(res.ranges_m[lo:hi]))


def test_bridge_across_two_surfaces_is_invalidated() -> None:
    # the body stands in front of a depth step of the background: a chord would be a fake wall
    walls = np.array([(3.0, -5.0, 3.0, 0.0), (5.0, 0.0, 5.0, 5.0), (3.0, 0.0, 5.0, 0.0)], dtype=float)
    world = World(walls, [Circle(1.5, 0.0, 0.3)])
    scan = world.scan(Pose2D(0, 0, 0))
    res = restore(scan.ranges_m, scan.bearings_rad, [_interval_around(1.5, 0.0, 0.3)])
    assert res.bridge_invalid
    lo, hi = res.cut[0]
    assert np.all(np.isnan(res.ranges_m[lo:hi])) and np.all(res.weights[lo:hi] == 0.0)
    assert len(res.obstacles) == 1


def test_interval_at_the_scan_edge() -> None:
    world = box_room(6.0, 6.0, x0=-3.0, y0=-3.0, pillars=False)
    world.circles = [Circle(-0.7, -0.9, 0.25)]  # at about -128 deg, near the first beam
    scan = world.scan(Pose2D(0, 0, 0))
    iv = BearingInterval(math.radians(-140.0), math.radians(-120.0))
    res = restore(scan.ranges_m, scan.bearings_rad, [iv])
    assert not res.too_large
    lo, hi = res.cut[0]
    assert lo == 0  # the cut reaches the first beam: nothing to bridge from on that side
    assert np.all(np.isnan(res.ranges_m[lo:hi])) and np.all(res.weights[lo:hi] == 0.0)
    assert not res.bridge_invalid  # an edge cut is not a two-surface bridge
    assert len(res.obstacles) == 1 and res.obstacles[0].start == 0  # the body is cut by the FOV edge
    # the far edge of the scan as well
    iv2 = BearingInterval(math.radians(130.0), math.radians(140.0))
    res2 = restore(scan.ranges_m, scan.bearings_rad, [iv2])
    assert res2.cut[-1][1] == UTM_BEARINGS.size


def test_obstacle_covering_most_of_the_view_is_refused() -> None:
    world = box_room(6.0, 6.0, x0=-3.0, y0=-3.0, pillars=False)
    world.circles = [Circle(0.9, 0.0, 0.8)]
    scan = world.scan(Pose2D(0, 0, 0))
    iv = BearingInterval(math.radians(-100.0), math.radians(100.0))
    res = restore(scan.ranges_m, scan.bearings_rad, [iv])
    assert res.too_large and res.cut_fraction > 0.5
    assert np.all(res.weights == 1.0) and res.cut == ()
    np.testing.assert_array_equal(np.isnan(res.ranges_m), np.isnan(scan.ranges_m))


def test_no_interval_and_empty_scan() -> None:
    scan = box_room(6.0, 6.0).scan(Pose2D(0, 0, 0))
    res = restore(scan.ranges_m, scan.bearings_rad, [])
    assert res.cut == () and np.all(res.weights == 1.0) and not res.too_large
    empty = restore(np.zeros(0), np.zeros(0), [BearingInterval(-0.1, 0.1)])
    assert empty.cut == () and empty.obstacles == ()
    nan = restore(np.full(1081, np.nan), UTM_BEARINGS, [BearingInterval(-0.1, 0.1)])
    assert nan.obstacles == () and not nan.too_large


def test_camera_offset_parallax_selects_the_right_beams() -> None:
    # interval seen from a camera 0.5 m left of the laser: the body's bearing differs from the laser's
    world = World(np.array([(4.0, -5.0, 4.0, 5.0)], dtype=float), [Circle(1.5, 0.5, 0.2)])
    scan = world.scan(Pose2D(0, 0, 0))
    cam = (0.0, 0.5)
    b = math.atan2(0.5 - cam[1], 1.5 - cam[0])
    half = math.asin(0.2 / 1.5)
    iv = BearingInterval(b - half, b + half, cam[0], cam[1])
    res = restore(scan.ranges_m, scan.bearings_rad, [iv], RestoreConfig())
    assert len(res.obstacles) == 1
    ob = res.obstacles[0]
    hit = np.flatnonzero(scan.ranges_m < 3.0)
    assert ob.start == hit[0] and ob.stop == hit[-1] + 1


def test_two_bodies_two_obstacles_and_overlapping_intervals_merge() -> None:
    world = World(np.array([(4.0, -5.0, 4.0, 5.0)], dtype=float), [Circle(2.0, 1.0, 0.3), Circle(2.0, -1.0, 0.3)])
    scan = world.scan(Pose2D(0, 0, 0))
    ivs = [_interval_around(2.0, 1.0, 0.3), _interval_around(2.0, -1.0, 0.3), _interval_around(2.0, 1.0, 0.35)]
    res = restore(scan.ranges_m, scan.bearings_rad, ivs)
    assert len(res.obstacles) == 2
    assert res.obstacles[0].stop <= res.obstacles[1].start


def test_a_track_interval_with_a_range_window_cuts_the_body_not_the_furniture_beside_it() -> None:
    # a tracked body at 2 m; a box face 1 m behind it, just beside it in bearing, inside the track's
    # (wide: radius + margin + prediction error) interval
    walls = np.array([(4.0, -5.0, 4.0, 5.0), (3.0, 0.35, 3.0, 0.9)], dtype=float)
    world = World(walls, [Circle(2.0, 0.0, 0.3)])
    scan = world.scan(Pose2D(0, 0, 0))
    b = scan.bearings_rad
    face = np.flatnonzero((np.abs(scan.ranges_m * np.cos(b) - 3.0) < 0.01) & (scan.ranges_m * np.sin(b) > 0.3))
    body = np.flatnonzero(scan.ranges_m < 2.5)
    assert face.size > 10 and body.size > 10
    iv = _interval_around(2.0, 0.0, 0.3, pad_deg=12.0)
    assert iv.bearing_max_rad > b[face[-1]]  # the face lies wholly inside the bearing interval
    without = restore(scan.ranges_m, b, [iv])
    assert np.all(without.weights[face] == 0.0)  # bearings alone: the face is cut with the body
    windowed = BearingInterval(iv.bearing_min_rad, iv.bearing_max_rad, source="track", track_id=1,
                               range_min_m=2.0 - 0.45, range_max_m=2.0 + 0.45)
    res = restore(scan.ranges_m, b, [windowed])
    beside = face[face > body[-1] + RestoreConfig().edge_beams]  # past the body's mixed edge returns
    assert beside.size > 10 and np.all(res.weights[beside] == 1.0)  # the box face stays for the matcher
    assert np.all(res.weights[body] == 0.0)  # the body is cut
    assert len(res.obstacles) == 1 and res.obstacles[0].start == body[0] and res.obstacles[0].stop == body[-1] + 1


def test_interval_range_window_must_be_ordered() -> None:
    with pytest.raises(ValueError):
        BearingInterval(0.0, 0.1, range_min_m=2.0, range_max_m=1.0)
    with pytest.raises(ValueError):
        BearingInterval(0.0, 0.1, range_min_m=-1.0)
