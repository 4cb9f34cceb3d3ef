"""Self returns (``vipsm.sensor.SelfReturns``): the leg_tracker robot's lasers see parts of the robot at the
edges of their view (0.12-0.73 m, in 84-97 % of the drive's scans); moving with the robot they were reported
as moving obstacles and pulled matches towards no motion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vipsm.estimator import Estimator, EstimatorConfig
from vipsm.sensor import SelfReturns
from vipsm.types import Pose2D, Scan

from .sim import box_room
from .test_deskew import BEAM_DT_S, BEARINGS, PERIOD_S, _pose, _swept

BODY = slice(0, 12)  # the first 12 beams (4 deg at -135) see a part of the robot at 0.4 m


def _with_body(scan: Scan, rng: np.random.Generator, seen: float = 1.0) -> Scan:
    r = scan.ranges_m.copy()
    if rng.random() < seen:
        r[BODY] = 0.4 + rng.normal(0.0, 0.005, 12)
    return Scan(r, scan.bearings_rad, scan.stamp_s, scan.seq, scan.beam_dt_s)


def test_a_return_fixed_in_the_laser_frame_over_turns_is_masked_and_walls_are_not() -> None:
    world = box_room(8.0, 7.0, x0=-3.0, y0=-3.5)
    rng = np.random.default_rng(1)
    sr = SelfReturns()
    masks = []
    for k in range(45):  # 6 s turning at 0.8 rad/s
        t = k * PERIOD_S
        scan = _with_body(world.scan(_pose(t), BEARINGS, noise_m=0.01, rng=rng), rng, seen=0.85)
        masks.append(sr.update(scan.ranges_m, _pose(t).theta_rad))
    assert not masks[0].any()
    assert sr.found()[BODY].all() and not sr.found()[20:].any()  # no wall beam is found
    assert all(not m[BODY.stop + 3 :].any() for m in masks)  # masked: the body and its outline only
    # something in front of the found range: no body there, forgotten at the next check
    r = world.scan(_pose(6.0), BEARINGS).ranges_m
    r[BODY] = 0.2
    sr.update(r, _pose(6.0).theta_rad)
    assert not sr.update(r, _pose(6.0).theta_rad + math.radians(40.0))[BODY].any()
    assert not sr.found()[BODY].any()


def test_a_still_or_straight_driving_laser_finds_nothing() -> None:
    world = box_room(8.0, 7.0, x0=-3.0, y0=-3.5)
    rng = np.random.default_rng(2)
    sr = SelfReturns()
    for k in range(60):  # 6 s still, then 3 m straight on
        pose = Pose2D(-1.5 + 0.1 * max(k - 30, 0), -0.5, 0.0)
        scan = world.scan(pose, BEARINGS, noise_m=0.01, rng=rng)
        assert not sr.update(scan.ranges_m, pose.theta_rad).any()


def test_the_estimator_cuts_the_robots_own_returns_from_the_scan_every_stage_sees() -> None:
    world = box_room(8.0, 7.0, x0=-3.0, y0=-3.5)
    rng = np.random.default_rng(4)
    scans = [_with_body(_swept(world, k * PERIOD_S, rng), rng) for k in range(45)]
    for turn in (0.0, math.radians(30.0)):
        est = Estimator(EstimatorConfig(self_returns_turn_rad=turn))
        for s in scans:
            est.step(s, None)
        last = est._matcher.last  # noqa: SLF001 - the ranges the last cycle's stages were given
        assert last is not None and last.seen_m is not None
        cut = np.isnan(last.seen_m[BODY])
        assert cut.all() if turn else not cut.any()
        assert np.isfinite(last.seen_m[BODY.stop + 4 : BODY.stop + 40]).all()  # the wall beside it stays


def test_self_returns_settings_are_checked() -> None:
    with pytest.raises(ValueError):
        SelfReturns(turn_rad=0.0)
    with pytest.raises(ValueError, match="self_returns"):
        EstimatorConfig(self_returns_tol_m=0.0)
    assert BEAM_DT_S > 0.0
