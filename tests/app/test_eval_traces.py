"""``RunLog.traces()``: per-cycle data of an evaluation run in the neutral form a plotting module reads."""

from __future__ import annotations

import math

import numpy as np

from app.evaluation import runner
from app.evaluation.traces import CycleTrace, RunTrace, TrackPoint, scan_endpoints_xy
from hil_fakes.world import RobotMount
from hil_fakes.world.scenarios import paper_scenario


def test_scan_endpoints_drop_invalid_beams_and_place_the_laser_on_the_pose() -> None:
    mount = RobotMount(laser_x_m=0.2, laser_y_m=0.0, laser_theta_rad=0.0)
    ranges = np.array([1.0, math.nan, 0.0, 40.0, 2.0])
    bearings = np.array([0.0, 0.1, 0.2, 0.3, math.pi / 2])
    xy = scan_endpoints_xy(ranges, bearings, (1.0, 2.0, math.pi / 2), mount)
    assert xy.shape == (2, 2)
    np.testing.assert_allclose(xy[0], [1.0, 2.0 + 0.2 + 1.0], atol=1e-9)  # straight ahead = +y
    np.testing.assert_allclose(xy[1], [1.0 - 2.0, 2.2], atol=1e-9)  # 90 deg left of +y = -x


def test_traces_follow_the_log_cycle_by_cycle() -> None:
    sc = paper_scenario("2", {"duration_s": 1.0, "world": "ideal", "obstacle_start_s": 0.0})
    log = runner.run_scenario(sc, keep_scans=True)
    traces = log.traces()
    assert [t.label for t in traces] == list(log.methods)
    for tr in traces:
        assert isinstance(tr, RunTrace)
        assert len(tr.cycles) == len(log.times_s) > 5
        assert len(tr.walls_xy_m) == len(sc.walls)
        m = log.methods[tr.label]
        for k, c in enumerate(tr.cycles):
            assert isinstance(c, CycleTrace)
            assert c.stamp_s == log.times_s[k] and c.pose_est == m.poses[k] and c.pose_true == log.true_poses[k]
            assert c.scan_xy_m.ndim == 2 and c.scan_xy_m.shape[1] == 2 and c.scan_xy_m.shape[0] > 100
            assert np.all(np.isfinite(c.scan_xy_m))
            assert len(c.obstacles_true) == len(sc.obstacles)
            assert all(r == o.radius_m for (_, _, r), o in zip(c.obstacles_true, sc.obstacles, strict=True))
            assert [(p.x_m, p.y_m) for p in c.obstacles_est] == m.obstacles[k]
            assert all(isinstance(p, TrackPoint) for p in c.obstacles_est)


def test_traces_without_kept_scans_have_empty_scans() -> None:
    log = runner.run_scenario(paper_scenario("1", {"duration_s": 0.5, "world": "ideal"}))
    (c0, *_), *_ = [t.cycles for t in log.traces()]
    assert c0.scan_xy_m.shape == (0, 2)


def test_track_point_carries_id_velocity_and_radius_of_an_estimate() -> None:
    from app.evaluation.traces import track_point
    from vipsm.types import Obstacle

    o = Obstacle(7, 1.5, -0.5, 0.2, -0.1, 0.4, 0.0, 0.1, 10, 20, age_cycles=12)
    assert track_point(o) == TrackPoint(7, 1.5, -0.5, 0.2, -0.1, 0.4)
