"""Polar scan matching on ray-cast scans with exact ground truth."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from vipsm.geometry import between, compose
from vipsm.psm import (
    TAG_INVALID,
    TAG_RANGE,
    TAG_SEGMENT,
    PsmConfig,
    PsmRefusal,
    match,
    median_filter_valid,
    prepare_scan,
    segment_scan,
)
from vipsm.types import Pose2D, Scan

from .sim import UTM_BEARINGS, Circle, World, box_room, corridor

# Scans up to 0.5 m / 30 deg apart from a zero initial guess: the original's wide settings
# (1 m residual gate, C = 0.7^2, a +-40 deg first orientation search).
WIDE = PsmConfig(max_error_m=1.0, weight_c_m2=0.49, search_window_first_beams=160, search_window_beams=20)


def _err(truth: Pose2D, est: Pose2D) -> tuple[float, float]:
    e = between(truth, est)
    return math.hypot(e.x_m, e.y_m), abs(math.degrees(e.theta_rad))


def _pair(world: World, p0: Pose2D, rel: Pose2D, noise: float = 0.01, seed: int = 0) -> tuple[Scan, Scan]:
    rng = np.random.default_rng(seed)
    return world.scan(p0, noise_m=noise, rng=rng), world.scan(compose(p0, rel), noise_m=noise, rng=rng)


CASES = [
    Pose2D(0.5, 0.0, 0.0),
    Pose2D(0.0, 0.5, 0.0),
    Pose2D(-0.35, 0.35, 0.0),
    Pose2D(0.0, 0.0, math.radians(30.0)),
    Pose2D(0.0, 0.0, math.radians(-30.0)),
    Pose2D(0.3, -0.2, math.radians(15.0)),
    Pose2D(-0.25, -0.25, math.radians(-20.0)),
    Pose2D(0.2, 0.3, math.radians(25.0)),
]


@pytest.mark.parametrize("rel", CASES, ids=lambda p: f"{p.x_m:+.2f},{p.y_m:+.2f},{math.degrees(p.theta_rad):+.0f}")
def test_room_pairs_recovered_from_zero_guess(rel: Pose2D) -> None:
    world = box_room(8.0, 6.0)
    s0, s1 = _pair(world, Pose2D(0.4, 0.2, 0.3), rel)
    res = match(s0, s1, Pose2D(0.0, 0.0, 0.0), WIDE)
    assert not res.refused, res.reason
    et, er = _err(rel, res.pose)
    assert et <= 0.01 and er <= 0.1, (et, er, res)


# derandomized: the same examples on every run and machine (a random draw once found a pose recovered to
# 0.106 deg, within a match's heading noise on these scans, and CI must not fail by chance)
@settings(max_examples=12, deadline=None, derandomize=True)
@given(
    x=st.floats(-0.3, 0.3),
    y=st.floats(-0.3, 0.3),
    th=st.floats(-25.0, 25.0),
    start_th=st.floats(-math.pi, math.pi),
)
@example(x=-0.0859, y=0.0, th=10.625, start_th=2.656)
def test_property_random_poses_recovered(x: float, y: float, th: float, start_th: float) -> None:
    world = box_room(7.0, 5.0)
    rel = Pose2D(x, y, math.radians(th))
    s0, s1 = _pair(world, Pose2D(0.5, 0.5, start_th), rel, seed=3)
    res = match(s0, s1, Pose2D(0.0, 0.0, 0.0), WIDE)
    assert not res.refused
    et, er = _err(rel, res.pose)
    # 1 cm and 0.15 deg (0.6 of the 0.25 deg beam step): the scans carry range noise
    assert et <= 0.01 and er <= 0.15


def test_default_config_with_odometry_guess_is_millimetre_accurate() -> None:
    world = box_room(8.0, 6.0)
    rel = Pose2D(0.03, 0.004, math.radians(1.5))
    s0, s1 = _pair(world, Pose2D(1.0, -0.5, 2.0), rel)
    guess = Pose2D(0.05, -0.01, math.radians(0.5))  # odometry 2 cm / 1 deg off
    res = match(s0, s1, guess)
    et, er = _err(rel, res.pose)
    assert not res.refused and res.converged
    assert et <= 0.003 and er <= 0.05
    assert res.beams_used >= 700 and 0.0 < res.residual_m < 0.02 and res.iterations >= 2


def test_partial_overlap_handled() -> None:
    # L-shaped space: after the move half of the current view is new area
    walls = np.array(
        [(-1, -1, 6, -1), (6, -1, 6, 1), (6, 1, 2, 1), (2, 1, 2, 6), (2, 6, -1, 6), (-1, 6, -1, -1)], dtype=float
    )
    world = World(walls)
    rel = Pose2D(0.45, 0.1, math.radians(25.0))
    s0, s1 = _pair(world, Pose2D(0.5, 0.0, 0.0), rel)
    res = match(s0, s1, Pose2D(0.3, 0.0, math.radians(15.0)), WIDE)
    assert not res.refused
    et, er = _err(rel, res.pose)
    assert et <= 0.01 and er <= 0.1


def test_corridor_does_not_diverge_and_is_flagged() -> None:
    world = corridor(length_m=40.0, width_m=2.0)
    rel = Pose2D(0.3, 0.05, math.radians(3.0))
    s0, s1 = _pair(world, Pose2D(10.0, 0.0, 0.0), rel)  # far from the door recess: no along-corridor cue
    guess = Pose2D(0.25, 0.0, 0.0)  # odometry 5 cm short
    res = match(s0, s1, guess)
    assert not res.refused
    e = between(rel, res.pose)
    assert abs(e.y_m) <= 0.01 and abs(math.degrees(e.theta_rad)) <= 0.1  # across: measured
    assert abs(e.x_m) <= 0.10  # along: bounded, no runaway
    assert res.corridor
    lam = np.linalg.eigvalsh(res.info_xy)
    assert lam[0] < 0.05 * lam[1]  # the normal-based information exposes the weak direction
    evals = np.linalg.eigvalsh(res.covariance[:2, :2])
    assert evals[-1] >= 1.0  # covariance stretched along the corridor (heuristic floor, >= (1 m)^2)


def test_occlusion_by_pillars() -> None:
    world = box_room(8.0, 6.0)
    world.circles = [Circle(1.2, 0.6, 0.25), Circle(0.5, -1.0, 0.2), Circle(2.5, -0.3, 0.3)]
    rel = Pose2D(0.4, 0.25, math.radians(12.0))
    s0, s1 = _pair(world, Pose2D(0.0, 0.0, 0.0), rel)
    res = match(s0, s1, Pose2D(0.3, 0.2, math.radians(8.0)), WIDE)
    et, er = _err(rel, res.pose)
    assert not res.refused and et <= 0.01 and er <= 0.1


def test_large_moving_body_pulls_plain_psm_and_zero_weights_fix_it() -> None:
    # a 1.4 m wide body 1 m ahead covers ~90 deg of the scan and moves 15 cm between the scans
    world = box_room(8.0, 5.0, x0=-1.0, y0=-2.5, pillars=False)
    body = Circle(1.0, 0.3, 0.7)
    world.circles = [body]
    p0 = Pose2D(0.0, 0.0, 0.0)
    rel = Pose2D(0.10, 0.0, 0.0)
    s0 = world.scan(p0, noise_m=0.005, rng=np.random.default_rng(1))
    body.y_m = 0.15
    s1 = world.scan(compose(p0, rel), noise_m=0.005, rng=np.random.default_rng(2))
    guess = Pose2D(0.10, 0.0, 0.0)
    plain = match(s0, s1, guess)
    et_p, er_p = _err(rel, plain.pose)

    def body_weights(scan: Scan, pose: Pose2D, cy: float) -> np.ndarray:
        bx, by = 1.0 - pose.x_m, cy - pose.y_m
        b = math.atan2(by, bx)
        half = math.asin(0.7 / math.hypot(bx, by)) + math.radians(3.0)
        return np.where(np.abs(scan.bearings_rad - b) <= half, 0.0, 1.0)

    w0 = body_weights(s0, p0, 0.3)
    w1 = body_weights(s1, compose(p0, rel), 0.15)
    fixed = match(s0, s1, guess, PsmConfig(), ref_weights=w0, cur_weights=w1)
    et, er = _err(rel, fixed.pose)
    assert not fixed.refused and et <= 0.005 and er <= 0.05
    assert et_p >= 0.015 and et_p >= 4 * et, (et_p, er_p, et, er)


@pytest.mark.parametrize(
    "ranges",
    [np.zeros(0), np.full(1081, np.nan), np.full(1081, 0.01)],
    ids=["empty", "all-invalid", "all-below-min"],
)
def test_degenerate_scans_are_refused_not_raised(ranges: np.ndarray) -> None:
    bearings = UTM_BEARINGS if ranges.size else np.zeros(0)
    scan = Scan(ranges, bearings, 0.0)
    good = box_room(6.0, 6.0).scan(Pose2D(0, 0, 0))
    guess = Pose2D(0.1, 0.0, 0.0)
    for a, b in ((scan, good), (good, scan)):
        res = match(a, b, guess)
        assert res.refused and res.reason is PsmRefusal.EMPTY_SCAN
        assert res.pose == guess and res.covariance.shape == (3, 3)


def test_too_few_beams_refused() -> None:
    """Below the floor: a 3-parameter fit on a handful of beams is refused, whatever the share."""
    world = box_room(6.0, 6.0)
    s = world.scan(Pose2D(0, 0, 0))
    r = s.ranges_m.copy()
    r[15:] = np.nan
    few = Scan(r, s.bearings_rad, 0.0)
    res = match(few, few, Pose2D(0, 0, 0))
    assert res.refused and res.reason in (PsmRefusal.TOO_FEW_BEAMS, PsmRefusal.NO_VALID_SHIFT)


def test_little_overlap_refused_but_a_range_limited_scan_matched() -> None:
    """The acceptance counts the beams both scans offer: 200 valid beams matched against themselves
    (a range-limited scanner) pass; a scan that shows none of what the reference saw does not."""
    world = box_room(6.0, 6.0)
    s = world.scan(Pose2D(0, 0, 0))
    r = s.ranges_m.copy()
    r[200:] = np.nan
    limited = Scan(r, s.bearings_rad, 0.0)
    res = match(limited, limited, Pose2D(0.02, 0.0, 0.0))
    assert not res.refused and math.hypot(res.dx_m, res.dy_m) < 0.005
    r2 = s.ranges_m.copy()
    r2[:300] = np.nan
    res = match(limited, Scan(r2, s.bearings_rad, 0.0), Pose2D(0.0, 0.0, 0.0))
    assert res.refused


def test_bad_bearings_refused() -> None:
    s = box_room(6.0, 6.0).scan(Pose2D(0, 0, 0))
    nan = s.bearings_rad.copy()
    nan[7] = np.nan
    for b in (s.bearings_rad[::-1].copy(), nan):  # descending, NaN
        bad = Scan(s.ranges_m, b, 0.0)
        for res in (match(s, bad, Pose2D(0, 0, 0)), match(bad, s, Pose2D(0, 0, 0))):
            assert res.refused and res.reason is PsmRefusal.BAD_INPUT
    with pytest.raises(ValueError, match="ascending"):
        prepare_scan(s.ranges_m, s.bearings_rad[::-1].copy(), PsmConfig())
    with pytest.raises(ValueError, match="shape"):  # a table that does not fit is never read past its end
        prepare_scan(s.ranges_m, s.bearings_rad[:-3].copy(), PsmConfig())


def test_bearings_come_from_the_scan() -> None:
    # a 180-beam 1-degree scanner (Intel-like) in the same room
    bearings = np.radians(np.arange(-90.0, 90.0, 1.0))
    world = box_room(8.0, 6.0)
    rel = Pose2D(0.2, 0.05, math.radians(4.0))
    s0 = world.scan(Pose2D(0.2, 0.1, 0.5), bearings=bearings, noise_m=0.005, rng=np.random.default_rng(0))
    s1 = world.scan(compose(Pose2D(0.2, 0.1, 0.5), rel), bearings=bearings, noise_m=0.005, rng=np.random.default_rng(1))
    res = match(s0, s1, Pose2D(0.15, 0.0, 0.0), PsmConfig.sick_1deg())
    et, er = _err(rel, res.pose)
    assert not res.refused and et <= 0.02 and er <= 0.3


def test_deterministic() -> None:
    world = box_room(8.0, 6.0)
    s0, s1 = _pair(world, Pose2D(0.0, 0.0, 1.0), Pose2D(0.2, 0.1, 0.1))
    a = match(s0, s1, Pose2D(0, 0, 0), WIDE)
    b = match(s0, s1, Pose2D(0, 0, 0), WIDE)
    assert a.pose == b.pose and np.array_equal(a.covariance, b.covariance) and a.iterations == b.iterations


def test_covariance_is_symmetric_positive_and_above_the_floor() -> None:
    world = box_room(8.0, 6.0)
    s0, s1 = _pair(world, Pose2D(0.0, 0.0, 0.0), Pose2D(0.05, 0.0, 0.02))
    res = match(s0, s1, Pose2D(0.0, 0.0, 0.0))
    c = res.covariance
    assert np.allclose(c, c.T)
    assert np.all(np.linalg.eigvalsh(c) > 0)
    cfg = PsmConfig()
    assert c[0, 0] >= cfg.cov_floor_sigma_xy_m**2 * 0.999 and c[2, 2] >= cfg.cov_floor_sigma_theta_rad**2 * 0.999
    no_floor = match(s0, s1, Pose2D(0.0, 0.0, 0.0), dataclasses.replace(cfg, use_cov_floor=False))
    assert no_floor.covariance[0, 0] < 1e-4  # the normal-equation estimate alone is millimetric here


def test_orientation_gain_blends_the_refined_angle() -> None:
    world = box_room(8.0, 6.0)
    s0, s1 = _pair(world, Pose2D(0.0, 0.0, 0.0), Pose2D(0.0, 0.0, math.radians(2.0)), noise=0.0)
    half = match(s0, s1, Pose2D(0, 0, 0), dataclasses.replace(PsmConfig(), orientation_gain=0.5, max_iterations=1))
    full = match(s0, s1, Pose2D(0, 0, 0), dataclasses.replace(PsmConfig(), orientation_gain=1.0, max_iterations=1))
    assert full.dtheta_rad == pytest.approx(math.radians(2.0), abs=math.radians(0.1))
    assert half.dtheta_rad == pytest.approx(0.5 * full.dtheta_rad, rel=1e-9)


# ---------------------------------------------------------------------------------------- preprocessing
def test_median_filter_removes_two_beam_clutter_and_ignores_invalid() -> None:
    r = np.full(20, 3.0)
    r[8:10] = 1.0  # a chair leg, two beams wide
    r[15] = np.nan
    valid = np.isfinite(r)
    med, ok = median_filter_valid(r, valid, 5)
    assert np.allclose(med[8:10], 3.0)
    assert not ok[15] and np.allclose(med[14], 3.0) and np.allclose(med[16], 3.0)
    r2 = np.full(20, 3.0)
    r2[5:8] = np.nan  # three invalid neighbours: the middle valid beams stay, far values do not leak in
    med2, ok2 = median_filter_valid(r2, np.isfinite(r2), 5)
    assert np.all(np.isfinite(med2[ok2])) and np.allclose(med2[ok2], 3.0)


def test_segmentation_jump_extrapolation_and_minimum_length() -> None:
    n = 60
    r = np.full(n, 2.0)
    r[20:40] = 5.0  # a step: two breaks
    r[45] = 8.0  # an isolated far point
    good = np.ones(n, dtype=bool)
    seg = segment_scan(r, good, math.radians(0.25), 0.2, 3.0)
    assert seg[19] != seg[20] and seg[39] != seg[40]
    assert seg[44] != seg[45] != seg[46]
    # a grazing wall: large steady range increments stay one segment (the extrapolation test)
    ramp = 2.0 + 0.3 * np.arange(n)
    seg2 = segment_scan(ramp, good, math.radians(0.25), 0.2, 3.0)
    assert np.all(seg2 == seg2[0])
    prep = prepare_scan(r, np.radians(np.linspace(-10, 10, n)), PsmConfig(median_window=1))
    assert prep.tags[45] & TAG_SEGMENT and not prep.good[45]


def test_range_gating_and_invalid_tags() -> None:
    r = np.full(30, 2.0)
    r[3] = 15.0
    r[4] = 0.05
    r[5] = np.nan
    prep = prepare_scan(r, np.radians(np.linspace(-5, 5, 30)), PsmConfig(median_window=1, max_range_m=10.0))
    assert prep.tags[3] & TAG_RANGE and prep.tags[4] & TAG_INVALID and prep.tags[5] & TAG_INVALID
    assert prep.good[10]


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 40), st.floats(0.05, 1.0))
def test_the_pruned_orientation_search_equals_the_exhaustive_one(seed: int, window: int, gate_m: float) -> None:
    """The compiled search abandons shifts that cannot win; its answer must be the exhaustive
    search's (numpy, every shift in full, ties to the smaller shift)."""
    from vipsm.psm_kernel import orientation_search, usable_reference

    rng = np.random.default_rng(seed)
    n = 181
    ref_r = 2.0 + np.cumsum(rng.normal(0.0, 0.05, n))
    ref_ok = rng.random(n) > 0.1
    proj_r = np.roll(ref_r, int(rng.integers(-window, window + 1))) + rng.normal(0.0, 0.02, n)
    proj_ok = rng.random(n) > 0.1
    proj_w = np.where(rng.random(n) > 0.05, 1.0, 0.0)
    got = orientation_search(usable_reference(ref_r, ref_ok), int(ref_ok.sum()), proj_r, proj_ok, proj_w, window,
                             gate_m, 0.3, np.empty(n), np.empty(n + 1, dtype=np.int64))
    refp = np.where(ref_ok, ref_r, 1e6)
    idx = np.flatnonzero(proj_ok & (proj_w > 0))
    min_cnt = max(1, math.ceil(0.3 * min(int(ref_ok.sum()), idx.size)))
    costs = []
    for d in range(-window, window + 1):
        r = idx + d
        keep = (r >= 0) & (r < n)
        g = np.abs(refp[r[keep]] - proj_r[idx[keep]])
        g = g[g < gate_m]
        costs.append(g.sum() / g.size if g.size >= min_cnt else np.inf)
    costs = np.asarray(costs)
    if not np.isfinite(costs).any():
        assert not got[3]
        return
    k = int(np.argmin(costs))
    assert got[3]
    assert abs(got[0] - (k - window)) < 1.0  # the best whole shift, then at most one step of refinement
    assert got[1] == pytest.approx(costs[k], rel=1e-12, abs=1e-15)


def _sym(a: float, b: float, c: float) -> np.ndarray:
    return np.array([[a, b], [b, c]])


_spd = st.tuples(st.floats(1e-6, 1e3), st.floats(1e-6, 1e3), st.floats(-0.999, 0.999), st.floats(0.0, math.pi))
#: the covariance floors PSM uses are isotropic or a corridor's (4 m / 0.3 m: 178:1 in variance);
#: whitening by a floor conditioned worse than 1e5 would lose the digits this test compares
_floor = st.tuples(st.floats(1e-3, 1e2), st.floats(1e-3, 1e2), st.just(0.0), st.floats(0.0, math.pi))


def _spd_matrix(t: tuple[float, float, float, float]) -> tuple[float, float, float]:
    """A symmetric positive definite 2x2 from two eigenvalues and a rotation (the correlation term
    scales the second, so near-singular matrices are drawn too)."""
    l0, l1, corr, ang = t
    from vipsm.psm import _sym2_rotated

    return _sym2_rotated(ang, l0, l1 * (1.0 - abs(corr)) + 1e-9)


@settings(max_examples=200, deadline=None)
@given(_floor, _spd)
def test_the_2x2_covariance_helpers_agree_with_numpy(fa: tuple, ca: tuple) -> None:
    """The scalar 2x2 helpers the covariance uses: eigen decomposition, and the Loewner maximum
    (floor-whitened, eigenvalues raised to 1, coloured back) computed with numpy's eigh."""
    from vipsm.psm import _sym2_eig, _sym2_loewner_max

    floor, cov = _spd_matrix(fa), _spd_matrix(ca)
    lo, hi, vx, vy = _sym2_eig(cov)
    m = _sym(*cov)
    lam = np.linalg.eigvalsh(m)
    scale = max(abs(lam).max(), 1e-300)
    assert lo == pytest.approx(lam[0], abs=1e-9 * scale) and hi == pytest.approx(lam[1], abs=1e-9 * scale)
    assert np.linalg.norm(m @ np.array([vx, vy]) - lo * np.array([vx, vy])) <= 1e-7 * scale
    f = _sym(*floor)
    evals, evecs = np.linalg.eigh(f)
    sq, isq = evecs * np.sqrt(evals), evecs / np.sqrt(evals)
    w = isq.T @ m @ isq
    lw, vw = np.linalg.eigh(0.5 * (w + w.T))
    want = sq @ ((vw * np.maximum(lw, 1.0)) @ vw.T) @ sq.T
    got = _sym(*_sym2_loewner_max(floor, cov))
    assert np.allclose(got, want, rtol=1e-6, atol=1e-9 * max(abs(want).max(), 1e-12))
    assert np.all(np.linalg.eigvalsh(got - f) >= -1e-7 * abs(f).max())  # at least the floor
    assert np.all(np.linalg.eigvalsh(got - m) >= -1e-7 * max(abs(m).max(), abs(f).max()))  # and the input


def test_the_vectorised_bearing_is_atan2_within_2e_14_rad() -> None:
    """The projection's branch-free atan2 against ``math.atan2``: every direction (dense), the axes
    and the octant boundaries, tiny and huge magnitudes, and the origin (0, as atan2(0, 0))."""
    from vipsm.psm_kernel import bearings_of

    ang = np.linspace(-math.pi, math.pi, 200_001)
    mag = np.geomspace(1e-6, 1e4, ang.size)
    t8 = 3.0 * math.tan(math.pi / 8)
    x = np.concatenate((mag * np.cos(ang), [0.0, 0.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 0.0, 3.0]))
    y = np.concatenate((mag * np.sin(ang), [1.0, -1.0, 0.0, 0.0, 1.0, 1.0, -1.0, -1.0, 0.0, t8]))
    got = np.empty(x.size)
    bearings_of(x, y, got)
    want = np.arctan2(y, x)
    err = np.abs(np.remainder(got - want + math.pi, 2 * math.pi) - math.pi)  # +-pi are the same bearing
    assert err.max() <= 2e-14
