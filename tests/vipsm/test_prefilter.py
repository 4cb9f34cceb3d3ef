"""vipsm.prefilter: mixed pixels and lone returns dropped, real objects kept."""

from __future__ import annotations

import numpy as np

from vipsm.prefilter import PrefilterConfig, drop_veiling, veiling_masks

from .sim import UTM_BEARINGS, Circle, box_room

CFG = PrefilterConfig()


def test_a_mixed_pixel_between_two_surfaces_is_dropped_and_the_surfaces_kept() -> None:
    r = np.full(20, 5.0)
    r[8:12] = 2.0  # a body in front of a wall
    r[12] = 3.4  # the footprint straddled the body's edge: a range between the two surfaces
    b = UTM_BEARINGS[:20]
    out = drop_veiling(r, b, CFG)
    assert np.isnan(out[12])
    assert np.array_equal(out[np.arange(20) != 12], r[np.arange(20) != 12])


def test_two_mixed_pixels_and_a_lone_return_are_dropped() -> None:
    r = np.full(30, 6.0)
    r[10:14] = 2.0
    r[14:16] = (3.0, 4.5)  # two veiling points, both strictly between
    r[22] = 1.0  # a lone spurious return in front of the wall
    out = drop_veiling(r, UTM_BEARINGS[:30], CFG)
    assert np.isnan(out[14:16]).all() and np.isnan(out[22])
    assert np.isfinite(out[10:14]).all() and np.isfinite(out[16:22]).all()
    mixed, lone = veiling_masks(r, UTM_BEARINGS[:30], CFG)  # told apart: the static map keeps lone ones
    assert np.flatnonzero(mixed).tolist() == [14, 15] and np.flatnonzero(lone).tolist() == [22]


def test_a_real_scan_of_legs_and_walls_keeps_every_body_beam() -> None:
    from vipsm.types import Pose2D

    world = box_room(8.0, 6.0)
    world.circles = [Circle(2.0, 0.3, 0.06), Circle(2.1, -0.1, 0.06), Circle(3.0, 1.5, 0.3)]
    _, ident = world.cast(0.0, 0.0, UTM_BEARINGS)
    scan = world.scan(Pose2D(0.0, 0.0, 0.0))
    out = drop_veiling(scan.ranges_m, scan.bearings_rad, CFG)
    dropped = np.isnan(out) & np.isfinite(scan.ranges_m)
    assert not dropped[ident < 0].any()  # no beam on a leg or the body is lost
    assert dropped.sum() <= 4  # only single-beam returns off wall corners


def test_disabled_filter_is_the_identity() -> None:
    r = np.array([5.0, 5.0, 3.0, 2.0, 2.0, 2.0, 5.0])
    out = drop_veiling(r, UTM_BEARINGS[:7], PrefilterConfig(enabled=False))
    assert np.array_equal(out, r) and out is not r
