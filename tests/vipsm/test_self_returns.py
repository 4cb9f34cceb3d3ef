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
    # the part taken off: the beams see the room from then on, and the footprint is forgotten once the part
    # is held in fewer than half the checks that could have seen it
    heading = _pose(6.0).theta_rad
    for _ in range(1, 40):
        heading += math.radians(35.0)
        r = world.scan(Pose2D(0.0, 0.0, heading), BEARINGS).ranges_m
        sr.update(r, heading)
    assert not sr.found()[BODY].any()


def _scan_at(world, heading: float, part_m: float | None) -> np.ndarray:
    r = world.scan(Pose2D(0.0, 0.0, heading), BEARINGS).ranges_m
    if part_m is not None:
        r[BODY] = part_m
    return r


def test_a_part_seen_only_at_every_other_check_is_found() -> None:
    """A part seen now and then (vibration, a thin rod): at every other check the beams pass it and see the
    room. An exact repeat over two checks in a row never happens; its share of the looks is 1/2."""
    world = box_room(8.0, 7.0, x0=-3.0, y0=-3.5)
    sr = SelfReturns()
    for k in range(11):  # the first scan anchors; 10 checks, the part at 5 of them
        heading = math.radians(35.0) * k
        sr.update(_scan_at(world, heading, 0.6 if k % 2 == 0 else None), heading)
    assert sr.found()[BODY].all() and not sr.found()[BODY.stop :].any()
    assert sr.footprint_m()[BODY] == pytest.approx(0.6, abs=0.05)
    heading = math.radians(35.0) * 10.5  # no check: the mask only
    assert sr.update(_scan_at(world, heading, 0.6), heading)[BODY].all()  # the part: masked
    assert not sr.update(_scan_at(world, heading, None), heading)[BODY].any()  # the room behind it: kept
    assert not sr.update(_scan_at(world, heading, 0.9), heading)[BODY].any()  # beyond the footprint: the world


def test_the_footprint_is_bounded_by_the_robots_reach() -> None:
    """A return fixed in the laser frame beyond ``max_range_m`` (a person walking along at 1.5 m) is not the
    robot's body."""
    world = box_room(8.0, 7.0, x0=-3.0, y0=-3.5)
    sr = SelfReturns(max_range_m=1.0)
    for k in range(12):
        heading = math.radians(35.0) * k
        sr.update(_scan_at(world, heading, 1.5), heading)
    assert not sr.found().any()


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
    with pytest.raises(ValueError, match="self_returns"):
        EstimatorConfig(self_returns_max_range_m=0.01)
    with pytest.raises(ValueError, match="self_returns"):
        EstimatorConfig(self_returns_share=0.0)
    with pytest.raises(ValueError):
        SelfReturns(min_share=1.5)
    assert BEAM_DT_S > 0.0


def test_a_beam_blocked_by_the_robot_is_cut_whole_also_where_it_returns_beyond_the_part() -> None:
    """The drive's right laser: beams on a shiny part of the robot at 0.7 m return, in about one scan in
    six, an echo at 3.72 m that is fixed in the laser frame (the beam sent on by the part); a turn sweeps it
    through space the laser saw free and it was reported as a moving obstacle. A beam the robot blocks in
    most scans is cut whole."""
    world = box_room(8.0, 7.0, x0=-3.0, y0=-3.5)
    rng = np.random.default_rng(6)
    est = Estimator(EstimatorConfig())
    ghost_cut = []
    for k in range(45):
        s = _with_body(_swept(world, k * PERIOD_S, rng), rng)
        echo = k % 6 == 5
        if echo:
            r = s.ranges_m.copy()
            r[BODY] = 3.72 + rng.normal(0.0, 0.005, BODY.stop)
            s = Scan(r, s.bearings_rad, s.stamp_s, s.seq, s.beam_dt_s)
        e = est.step(s, None)
        assert not e.obstacles
        last = est._matcher.last  # noqa: SLF001 - the ranges the cycle's stages were given
        if echo and est._self_returns.found()[BODY].all():  # noqa: SLF001
            ghost_cut.append(bool(np.isnan(last.seen_m[BODY]).all()))
    assert ghost_cut and all(ghost_cut)
