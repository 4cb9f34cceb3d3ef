"""Loop health statistics, the safety zone, odometry interpolation."""

from __future__ import annotations

import math

import pytest

from app.health import LoopHealth, OdometryHistory, SafetyMonitor
from vipsm.types import Obstacle, Odometry


def obstacle(x: float, y: float, vx: float = 0.0, vy: float = 0.0, r: float = 0.4) -> Obstacle:
    return Obstacle(1, x, y, vx, vy, r, 0.0, 0.0, 0, 0)


def test_health_counts_misses_and_percentiles() -> None:
    h = LoopHealth(0.1, window=100)
    for i in range(200):
        h.record(jitter_s=0.001 if i % 100 else 0.05, compute_s=0.002, missed=(i == 5))
    s = h.summary()
    assert s["cycles"] == 200 and s["deadline_misses"] == 1
    assert 1.0 <= s["loop_jitter_p99_ms"] <= 50.0
    assert s["compute_median_ms"] == pytest.approx(2.0)
    assert len(h._jitter) == 100  # noqa: SLF001 - bounded window


def test_latency_whole_and_host_part() -> None:
    h = LoopHealth(0.025, window=50)
    for i in range(100):
        h.record_latency(0.010 + 0.001 * (i % 10), 0.004 + 0.001 * (i % 10))
    h.record_latency(0.02)  # a scan whose read time is unknown counts in the whole only
    s = h.summary()
    assert s["scan_to_obstacles_ms_median"] == pytest.approx(14.5, abs=0.6)
    assert s["scan_received_to_obstacles_ms_median"] == pytest.approx(8.5, abs=0.6)
    assert s["scan_received_to_obstacles_ms_p99"] <= 13.0
    assert len(h._latency) == 50 and len(h._host_latency) == 50  # noqa: SLF001 - bounded windows


def test_safety_stops_on_predicted_intrusion_and_resumes_after_clear() -> None:
    m = SafetyMonitor(radius_m=0.5, horizon_s=2.0, resume_after_clear_s=1.0)
    # obstacle 3 m ahead, still: robot at 0.2 m/s reaches 0.4 m in 2 s -> clear
    assert m.update(0.0, 0, 0, 0, 0.2, [obstacle(3.0, 0.0)]) is False
    # obstacle crossing towards the robot's path: predicted to meet it within the horizon
    assert m.update(0.1, 0, 0, 0, 0.2, [obstacle(0.6, 1.0, 0.0, -0.6)]) is True
    # gone: stays stopped until the zone has been clear for 1 s
    assert m.update(0.2, 0, 0, 0, 0.0, []) is True
    assert m.update(1.1, 0, 0, 0, 0.0, []) is True
    assert m.update(1.25, 0, 0, 0, 0.0, []) is False


def test_odometry_interpolates_and_refuses_far_extrapolation() -> None:
    h = OdometryHistory(max_extrapolation_s=0.2)
    assert h.at(0.0) is None
    h.add(Odometry(0.0, 0.0, math.pi - 0.1, 1.0, 0.0, 0.0))
    h.add(Odometry(1.0, 0.0, -math.pi + 0.1, 1.0, 0.0, 1.0))
    mid = h.at(0.5)
    assert mid is not None and mid.x_m == pytest.approx(0.5)
    assert abs(abs(mid.theta_rad) - math.pi) < 1e-9  # through the +-pi wrap, not through 0
    ahead = h.at(1.1)
    assert ahead is not None and ahead.stamp_s == pytest.approx(1.1)
    assert h.at(1.5) is None
    h.add(Odometry(9.0, 0.0, 0.0, 0.0, 0.0, 0.5))  # out of order: ignored
    assert h.newest is not None and h.newest.stamp_s == 1.0
