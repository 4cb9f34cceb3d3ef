"""De-skew (``vipsm.motion.deskew``): a scanner that turns and drives during its sweep sees the scene stretched
in bearing and displaced; matched without correction, each turn is underestimated (a heading bias growing
with the turn rate squared, the leg_tracker drive's slow 7.5 Hz lasers lost 3-9 deg over one loop)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vipsm.estimator import Estimator, EstimatorConfig
from vipsm.geometry import between, compose
from vipsm.motion import Twist2D, deskew, laser_twist
from vipsm.types import Pose2D, Scan

from .sim import box_room

PERIOD_S = 1 / 7.5
STEP_RAD = math.radians(360.0 / 1024)  # the leg_tracker drive's 768-beam scanners: 1024 steps a turn
BEARINGS = -math.radians(134.82) + STEP_RAD * np.arange(768)
BEAM_DT_S = PERIOD_S / 1024
V_MPS, W_RADPS = 0.6, 0.8
START = Pose2D(-0.5, -0.8, 0.3)


def _pose(t_s: float) -> Pose2D:
    """An arc at constant velocity from START."""
    th = W_RADPS * t_s
    r = V_MPS / W_RADPS
    return compose(START, Pose2D(r * math.sin(th), r * (1.0 - math.cos(th)), th))


def _swept(world, t_s: float, rng: np.random.Generator | None = None, chunk: int = 4) -> Scan:
    """The scan measured beam by beam (beam i at t_s + i * BEAM_DT_S) from the moving laser."""
    r = np.empty(BEARINGS.size)
    for i in range(0, BEARINGS.size, chunk):
        p = _pose(t_s + (i + 0.5 * (chunk - 1)) * BEAM_DT_S)
        d, _ = world.cast(p.x_m, p.y_m, BEARINGS[i:i + chunk] + p.theta_rad)
        r[i:i + chunk] = d
    if rng is not None:
        r = r + rng.normal(0.0, 0.01, r.size)
    r[~np.isfinite(r)] = np.nan
    return Scan(r, BEARINGS.copy(), t_s, 0, BEAM_DT_S)


def test_deskew_gives_the_scan_seen_from_the_first_beams_pose() -> None:
    world = box_room(8.0, 7.0, x0=-3.0, y0=-3.5)
    scan = _swept(world, 1.0, chunk=1)
    ideal = world.scan(_pose(1.0), BEARINGS).ranges_m
    out, _ = deskew(scan.ranges_m, BEARINGS, BEAM_DT_S, Twist2D(V_MPS, 0.0, W_RADPS), 0.2, 3.0)
    ok = np.isfinite(out) & np.isfinite(ideal)
    raw_err = np.abs(scan.ranges_m - ideal)[np.isfinite(scan.ranges_m) & np.isfinite(ideal)]
    err = np.abs(out - ideal)[ok]
    assert ok.sum() > 0.97 * np.isfinite(ideal).sum()  # edges keep their returns
    assert np.median(raw_err) > 0.03  # the sweep's motion is not negligible ...
    assert np.median(err) < 0.002 and np.percentile(err, 90) < 0.01  # ... and is removed


def test_deskew_without_motion_or_timing_is_the_identity_and_weights_follow() -> None:
    r = np.array([1.0, 1.0, np.nan, 2.0, 2.0])
    b = np.linspace(-0.1, 0.1, 5)
    w = np.array([1.0, 0.0, 1.0, 1.0, 0.5])
    for dt, tw in ((0.0, Twist2D(1.0, 0.0, 1.0)), (1e-4, Twist2D())):
        out, wo = deskew(r, b, dt, tw, 0.2, 3.0, w)
        np.testing.assert_array_equal(out, r)
        np.testing.assert_array_equal(wo, w)
    out, wo = deskew(r, b, 1e-4, Twist2D(0.0, 0.0, 0.5), 0.2, 3.0, w)
    assert np.isnan(out[2]) and wo is not None and wo[2] == 0.0  # no return to move there
    assert wo[1] == 0.0  # a beam cut by the restoration stays cut


def test_laser_twist_is_the_mounted_lasers_own_motion() -> None:
    mount = Pose2D(0.2, -0.3, math.radians(-90.0))
    tw = Twist2D(0.5, 0.0, 0.8)
    dt = 1e-5
    moved = between(compose(Pose2D(0.0, 0.0, 0.0), mount), compose(Pose2D(tw.vx_mps * dt, 0.0, tw.w_radps * dt), mount))
    lt = laser_twist(tw, mount)
    assert lt.vx_mps == pytest.approx(moved.x_m / dt, rel=1e-4)
    assert lt.vy_mps == pytest.approx(moved.y_m / dt, rel=1e-4)
    assert lt.w_radps == tw.w_radps


@pytest.mark.parametrize("mode", ["no_odometry", "always"])
def test_a_turning_drive_without_odometry_keeps_its_heading_only_when_deskewed(mode: str) -> None:
    world = box_room(8.0, 7.0, x0=-3.0, y0=-3.5)
    rng = np.random.default_rng(3)
    scans = [_swept(world, k * PERIOD_S, rng) for k in range(45)]  # 6 s, 275 deg of turn
    drift = {}
    for m in ("off", mode):
        est = Estimator(EstimatorConfig(deskew=m))
        poses = [est.step(scan, None).pose for scan in scans]
        # from scan 10 on (the first scans are matched before any motion is known, the robot never
        # stood still here): the estimated motion against the true one
        k0 = 10
        rel = between(between(_pose(scans[k0].stamp_s), _pose(scans[-1].stamp_s)), between(poses[k0], poses[-1]))
        drift[m] = (math.hypot(rel.x_m, rel.y_m), abs(rel.theta_rad))
    # the bias: w^2 / mirror rate = 0.8^2 / 47 rad/s over 4.5 s, about 3.5 deg
    assert drift["off"][1] > math.radians(2.5)
    assert drift[mode][1] < math.radians(0.7) and drift[mode][0] < 0.05


def test_deskew_mode_is_checked() -> None:
    with pytest.raises(ValueError, match="deskew"):
        EstimatorConfig(deskew="sometimes")


def test_the_skew_left_in_a_scan_is_the_turn_rate_the_deskew_did_not_assume() -> None:
    """The motion evidence allows for the heading error the sweep's skew leaves (vipsm.seen_through): all of
    w x sweep without de-skew, only the change of turn rate since the last cycle with it."""
    world = box_room(8.0, 7.0, x0=-3.0, y0=-3.5)
    scans = [_swept(world, k * PERIOD_S) for k in range(15)]
    sweep_s = BEAM_DT_S * (BEARINGS.size - 1)
    left = {}
    for mode in ("off", "no_odometry"):
        est = Estimator(EstimatorConfig(deskew=mode))
        for s in scans:
            est.step(s, None)
        left[mode] = est._skew_rad  # noqa: SLF001 - the cycle's skew, as the evidence stages got it
    assert left["off"] == pytest.approx(W_RADPS * sweep_s, rel=0.1)
    assert left["no_odometry"] < 0.1 * left["off"]


def test_nearest_return_within_a_window() -> None:
    from vipsm.estimator import _nearest_within

    r = np.array([5.0, np.nan, 2.0, 5.0, 5.0, 5.0])
    assert np.array_equal(_nearest_within(r, 0), r, equal_nan=True)
    got = _nearest_within(r, 1)
    assert np.isnan(got[1]) and got.tolist()[2:] == [2.0, 2.0, 5.0, 5.0] and got[0] == 5.0
