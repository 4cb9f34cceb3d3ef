"""No odometry: the matcher seeded by constant velocity (``vipsm.motion``), a refusal never freezes the
pose (retries against the keyframe with a wider search, the previous keyframe and the last scan; else the
prediction, flagged ``POSE_UNCERTAIN``)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from vipsm.estimator import Estimator, EstimatorConfig
from vipsm.geometry import between, compose
from vipsm.motion import ConstantVelocity
from vipsm.types import EstimateFlag, Odometry, Pose2D, Scan

from .sim import box_room

PERIOD_S = 1 / 7.5  # the leg_tracker drive's scanners


def _truth(k: int, jump_at: int | None = None, jump_rad: float = 0.0) -> Pose2D:
    """0.6 m/s straight for 1.5 s, then an arc at 1.0 rad/s (7.6 deg per scan, as the leg_tracker drive's
    fastest turns); ``jump_at``: from that scan on the heading is ``jump_rad`` further (a bump the
    constant velocity cannot predict)."""
    pose = Pose2D(-0.5, -0.8, 0.3)
    for i in range(k):
        w = 0.0 if i < 11 else 1.0
        pose = compose(pose, Pose2D(0.6 * PERIOD_S, 0.0, w * PERIOD_S))
        if jump_at is not None and i + 1 == jump_at:
            pose = compose(pose, Pose2D(0.0, 0.0, jump_rad))
    return pose


def _drive(n: int, blank: tuple[int, ...] = (), jump_at: int | None = None, jump_rad: float = 0.0
           ) -> list[tuple[Scan, Pose2D]]:
    world = box_room(8.0, 7.0, x0=-3.0, y0=-3.5)
    rng = np.random.default_rng(5)
    out = []
    for k in range(n):
        t = k * PERIOD_S
        truth = _truth(k, jump_at, jump_rad)
        scan = world.scan(truth, noise_m=0.01, rng=rng, stamp_s=t)
        if k in blank:  # the scanner blinded for one scan (no return at all)
            scan = Scan(np.full(scan.ranges_m.size, np.nan), scan.bearings_rad, t)
        out.append((scan, truth))
    return out


def _errors(est: Estimator, seq: list[tuple[Scan, Pose2D]], odometry: bool = False):
    first = seq[0][1]
    out = []
    for scan, truth in seq:
        odo = Odometry(0.0, 0.0, 0.0, 0.0, 0.0, scan.stamp_s) if odometry else None
        e = est.step(scan, odo)
        rel = between(between(first, truth), e.pose)
        out.append((e, math.hypot(rel.x_m, rel.y_m), abs(rel.theta_rad)))
    return out


def test_a_drive_without_odometry_is_tracked_by_constant_velocity() -> None:
    seq = _drive(45)
    est = Estimator(EstimatorConfig())
    run = _errors(est, seq)
    assert not any(e.flags & (EstimateFlag.ODOMETRY_FALLBACK | EstimateFlag.POSE_UNCERTAIN) for e, _, _ in run[1:])
    assert max(d for _, d, _ in run) < 0.05 and max(a for _, _, a in run) < math.radians(1.0)
    assert est._matcher.recoveries == 0  # noqa: SLF001 - every prediction was inside the normal search
    # the prediction is the arc: after the turn has begun, the guess is off by far less than a scan's motion
    cv = Estimator(EstimatorConfig())
    for scan, _ in seq[:30]:
        cv.step(scan, None)
    pred = cv._motion.predict(seq[30][0].stamp_s)  # noqa: SLF001
    rel = between(between(seq[0][1], seq[30][1]), pred)
    assert math.hypot(rel.x_m, rel.y_m) < 0.01 and abs(rel.theta_rad) < math.radians(0.5)


def test_motion_prior_constant_velocity_is_the_same_as_no_odometry() -> None:
    seq = _drive(20)
    cv = _errors(Estimator(EstimatorConfig(motion_prior="constant_velocity")), seq, odometry=True)
    none = _errors(Estimator(EstimatorConfig()), seq)
    assert [e.pose for e, _, _ in cv] == [e.pose for e, _, _ in none]
    with pytest.raises(ValueError, match="motion_prior"):
        EstimatorConfig(motion_prior="wheels")


def test_a_blind_scan_is_predicted_flagged_and_the_match_resumes() -> None:
    seq = _drive(40, blank=(20,))
    run = _errors(Estimator(EstimatorConfig()), seq)
    e19, e20, e21 = (run[k][0] for k in (19, 20, 21))
    assert e20.flags & EstimateFlag.ODOMETRY_FALLBACK and e20.flags & EstimateFlag.POSE_UNCERTAIN
    moved = between(e19.pose, e20.pose)
    assert math.hypot(moved.x_m, moved.y_m) == pytest.approx(0.6 * PERIOD_S, abs=0.02)  # not frozen
    assert not e21.flags & (EstimateFlag.ODOMETRY_FALLBACK | EstimateFlag.POSE_UNCERTAIN)
    assert run[-1][1] < 0.05 and run[-1][2] < math.radians(1.0)


def test_a_turn_beyond_the_search_window_is_recovered_by_the_wider_search() -> None:
    cfg = EstimatorConfig()
    jump = math.radians(35.0)  # far beyond the +-7.5 deg first search around the prediction
    assert jump > cfg.psm.search_window_first_rad
    run = _errors(Estimator(cfg), _drive(35, jump_at=25, jump_rad=jump))
    assert not any(e.flags & EstimateFlag.ODOMETRY_FALLBACK for e, _, _ in run[1:])
    assert run[-1][1] < 0.05 and run[-1][2] < math.radians(1.0)
    # without the retries the same bump is refused (the test can fail)
    narrow = dataclasses.replace(cfg, recovery_window_rad=0.0, recovery_max_error_m=0.0)
    run = _errors(Estimator(narrow), _drive(35, jump_at=25, jump_rad=jump))
    assert run[25][0].flags & EstimateFlag.ODOMETRY_FALLBACK


def test_constant_velocity_predicts_an_arc_and_not_across_a_gap() -> None:
    cv = ConstantVelocity(max_gap_s=0.5)
    assert cv.predict(0.0) is None
    step = Pose2D(0.08, 0.0, 0.06)
    p0 = Pose2D(1.0, 2.0, 0.5)
    cv.update(p0, 0.0)
    cv.update(compose(p0, step), 0.1)
    pred = cv.predict(0.2)
    want = compose(compose(p0, step), step)
    assert pred is not None and math.hypot(pred.x_m - want.x_m, pred.y_m - want.y_m) < 1e-12
    half = cv.predict(0.15)  # half a period: half the motion
    assert half is not None and between(compose(p0, step), half).x_m == pytest.approx(0.04)
    assert cv.predict(0.7) == compose(p0, step)  # a 0.6 s gap: not extrapolated
    cv.update(Pose2D(0.0, 0.0, 0.0), 1.0)  # after a gap the velocity is unknown
    assert cv.twist.vx_mps == 0.0 and cv.predict(1.1) == Pose2D(0.0, 0.0, 0.0)
    with pytest.raises(ValueError):
        ConstantVelocity(max_gap_s=0.0)


def test_refinement_steps_apply_only_without_odometry() -> None:
    cfg = EstimatorConfig()
    assert cfg.psm.refine_iterations == 0 and cfg.no_odometry_refine_iterations == 5
    seq = _drive(12)
    with_odo, without = Estimator(cfg), Estimator(cfg)
    used = {}
    for est, odometry in ((with_odo, True), (without, False)):
        calls = []
        orig = est._matcher._psm  # noqa: SLF001

        def spy(*a, _orig=orig, _calls=calls, _est=est, **k):  # the settings each match ran with
            _calls.append(_est._matcher._configs[_est._matcher._no_odometry][0].refine_iterations)  # noqa: SLF001
            return _orig(*a, **k)

        est._matcher._psm = spy  # noqa: SLF001
        _errors(est, seq, odometry=odometry)
        used[odometry] = set(calls)
    assert used == {True: {0}, False: {5}}
    # the refinement without odometry is the two-way cost (vipsm.plicp; docs/psm.md)
    assert cfg.psm.refine_symmetric and without._matcher._configs[True][0].refine_symmetric  # noqa: SLF001
    with pytest.raises(ValueError, match="no_odometry_refine_iterations"):
        EstimatorConfig(no_odometry_refine_iterations=-1)
