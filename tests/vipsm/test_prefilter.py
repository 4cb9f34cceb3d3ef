"""vipsm.prefilter: mixed pixels and lone returns dropped, real objects kept."""

from __future__ import annotations

import numpy as np

from vipsm.prefilter import PrefilterConfig, drop_veiling, ramp_mask, ramp_masks, veiling_masks

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


def _leg_before_wall(between: tuple[float, ...], wall_m: float = 2.2) -> np.ndarray:
    """A leg (10 returns at 2.0-2.01 m) with the wall ``wall_m`` behind on both sides, and ``between``
    returns between the leg's last return and the wall on its right."""
    leg = 2.0 + 0.01 * np.abs(np.linspace(-1.0, 1.0, 10))
    return np.concatenate([np.full(8, wall_m), leg, between, np.full(8, wall_m)])


def test_a_mixed_pixel_too_close_to_both_surfaces_for_a_range_jump_is_dropped() -> None:
    # a leg 0.2 m before a wall: the mixed pixel halfway lies 0.1 m from each, below ``jump_m``, and would
    # join the leg to the wall in one segment
    r = _leg_before_wall((2.11,))
    mixed, lone = veiling_masks(r, UTM_BEARINGS[: r.size], CFG)
    assert np.flatnonzero(mixed).tolist() == [18] and not lone.any()


def test_a_ramp_of_two_or_three_mixed_pixels_is_dropped() -> None:
    for between in ((2.07, 2.14), (2.3, 2.5, 2.75)):
        r = _leg_before_wall(between, wall_m=2.2 if len(between) == 2 else 2.9)
        mixed, _ = veiling_masks(r, UTM_BEARINGS[: r.size], CFG)
        assert np.flatnonzero(mixed).tolist() == list(range(18, 18 + len(between))), between


def test_a_pulled_return_and_a_step_below_the_jump_are_kept() -> None:
    # within 10 % of the gap from the leg: the leg's own echo pulled towards the wall's (kept)
    r = _leg_before_wall((2.06,), wall_m=2.9)
    assert not veiling_masks(r, UTM_BEARINGS[: r.size], CFG)[0].any()
    # a 6 cm step with a point between: no two surfaces as far apart as ``jump_m``
    r = np.concatenate([np.full(6, 3.0), [3.03], np.full(6, 3.06)])
    assert not veiling_masks(r, UTM_BEARINGS[: r.size], CFG)[0].any()


def test_noisy_walls_at_any_incidence_and_legs_lose_no_return() -> None:
    from vipsm.types import Pose2D

    rng = np.random.default_rng(3)
    for k in range(40):
        world = box_room(6.0 + 0.1 * k, 4.0 + 0.05 * k, x0=-1.0 - 0.05 * k, y0=-2.0 - 0.03 * k, pillars=False)
        world.circles = [Circle(1.5 + 0.1 * k, -0.5 + 0.02 * k, 0.06)]
        scan = world.scan(Pose2D(0.0, 0.0, 0.07 * k))
        r = scan.ranges_m + (0.0022 + 0.0007 * scan.ranges_m) * rng.standard_normal(scan.ranges_m.size)
        ramps = ramp_mask(r, CFG.surface_tol_m, CFG.jump_m)
        assert not ramps.any(), np.flatnonzero(ramps)


def test_ramp_rule_needs_surfaces_on_both_sides() -> None:
    r = np.array([np.nan, 2.0, 2.11, 2.2, 2.2, 2.2])  # one return of the near side, then no echo
    assert not ramp_mask(r, 0.02, 0.1).any()
    r = np.array([2.0, 2.0, 2.11, 2.2, np.nan, 2.2])
    assert not ramp_mask(r, 0.02, 0.1).any()


def test_config_is_checked() -> None:
    import pytest

    for bad in ({"jump_m": 0.0}, {"max_island_beams": 0}, {"surface_tol_m": 0.0}, {"jump_range_factor": -1.0}):
        with pytest.raises(ValueError):
            PrefilterConfig(**bad)


def test_recorded_utm30lx_mixed_pixels_are_dropped(shared_data) -> None:
    """Every clear mixed pixel of the recorded UTM-30LX (one return in the middle 60 % of a 0.15-1 m step
    between two flat runs of three returns) is dropped; few other returns are."""
    from app.evaluation.psm_real import DIOSI_FILE, read_diosi_scans

    path = shared_data / DIOSI_FILE
    if not path.exists():
        import pytest

        pytest.skip(f"{path} absent")
    clear = dropped = returns = removed = 0
    for scan in read_diosi_scans(path):
        r = scan.ranges_m
        mixed, lone = veiling_masks(r, scan.bearings_rad, CFG)
        returns += int(np.isfinite(r).sum())
        removed += int((mixed | lone).sum())
        for i in range(3, r.size - 3):
            near, far = sorted((r[i - 1], r[i + 1]))
            flat = bool(np.all(np.abs(np.diff(r[i - 3 : i])) <= 0.01)
                        and np.all(np.abs(np.diff(r[i + 1 : i + 4])) <= 0.01))
            if flat and 0.15 <= far - near <= 1.0 and 0.2 < (r[i] - near) / (far - near) < 0.8:
                clear += 1
                dropped += int(mixed[i])
    assert clear >= 10 and dropped == clear
    assert removed <= 0.04 * returns


def test_the_ramp_rule_can_be_left_out_and_is_off_with_the_stage() -> None:
    r = _leg_before_wall((2.11,))
    b = UTM_BEARINGS[: r.size]
    assert not veiling_masks(r, b, CFG, ramps=False)[0].any()  # the island rule alone misses it
    assert np.flatnonzero(ramp_masks(r, b, CFG)).tolist() == [18]
    off = PrefilterConfig(enabled=False)
    assert not ramp_masks(r, b, off).any() and not veiling_masks(r, b, off)[0].any()
