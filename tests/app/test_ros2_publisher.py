"""The ROS 2 publisher without a network: the loop's side never blocks and its queue is bounded
(the oldest dropped and counted), a DDS failure is a state with one event (never an exception), bad
settings are config errors, and the conversions follow REP 103/105/117 and radar_msgs."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest

from app import logmessages as lm
from app.config import Ros2Config, load_config
from app.daemon import ScanSample
from app.errors import ConfigError
from app.ros2 import convert
from app.ros2 import msgs as m
from app.ros2.publisher import Ros2Publisher, cyclone_config_uri, resolve_domain_id
from app.ros2.qos import normalise_namespace
from vipsm.types import Estimate, MatchQuality, Obstacle, Odometry, Pose2D, Scan

MOUNTS = lm.Mounts(0.1, 0.0, 0.0, 0.05, 0.0, 0.4)


def scan_sample(stamp_s: float) -> ScanSample:
    b = np.linspace(-2.0, 2.0, 9)
    ranges = np.full(9, 2.0)
    rep117 = ranges.copy()
    rep117[0], rep117[1], rep117[2] = math.inf, -math.inf, math.nan
    return ScanSample(Scan(ranges, b, stamp_s, beam_dt_s=1e-4), rep117_ranges_m=rep117, range_limits_m=(0.023, 30.0))


def obstacle(track_id: int, person: bool) -> Obstacle:
    cov = np.diag([0.01, 0.02, 0.03, 0.04])
    cov[0, 1] = cov[1, 0] = 0.005
    return Obstacle(track_id, 1.0, 2.0, 0.3, -0.4, 0.25, 0.1, 0.2, 5, 9, covariance=tuple(cov.ravel()), person=person)


def estimate(obstacles: tuple[Obstacle, ...]) -> Estimate:
    return Estimate(1.0, Pose2D(0.5, 0.25, 0.3), np.diag([0.01, 0.02, 0.003]), obstacles,
                    MatchQuality(100, 5, 0.01, True))


def test_the_loop_side_never_waits_and_the_queue_is_bounded() -> None:
    pub = Ros2Publisher(Ros2Config(enabled=True, queue_size=8), MOUNTS, 0.1)
    pub.scan(scan_sample(-1.0), 999.0)
    assert len(pub._queue) == 0  # DDS not up yet: nobody can listen, nothing stale piles up
    pub.state = "ok"  # as if DDS were up, with the thread not started: nothing drains
    t0 = time.perf_counter()
    for i in range(100):
        pub.scan(scan_sample(float(i)), 1000.0 + i)
    assert time.perf_counter() - t0 < 5.0  # no DDS call, no wait: only references queued
    assert len(pub._queue) == 8 and pub.dropped == 92
    assert [name for name, _ in pub._queue] == ["/scan"] * 8
    msg = pub._queue[-1][1]()  # the newest kept, built only when written
    assert msg.header.stamp.sec == 1099 and msg.scan_time == pytest.approx(1.0)


def test_a_dds_failure_is_a_state_and_one_event(tmp_path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text("<CycloneDDS><Domain><General><NoSuchSetting>1</NoSuchSetting></General></Domain></CycloneDDS>")
    pub = Ros2Publisher(Ros2Config(enabled=True, cyclonedds_config=str(bad), domain_id=201), MOUNTS, 0.1).start()
    pub._thread.join(30.0)
    assert not pub._thread.is_alive()
    assert pub.state == "failed" and pub.error
    events = pub.take_events()
    assert len(events) == 1 and events[0][0] == "error" and "failed" in events[0][1]
    pub.scan(scan_sample(0.0), 1.0)  # ignored, not queued, not raised
    assert len(pub._queue) == 0 and pub.take_events() == []
    pub.close()
    assert pub.summary()["state"] == "failed"


def test_settings_are_checked(tmp_path) -> None:
    assert resolve_domain_id(7, {"ROS_DOMAIN_ID": "3"}) == 7
    assert resolve_domain_id(-1, {"ROS_DOMAIN_ID": "3"}) == 3
    assert resolve_domain_id(-1, {}) == 0
    for bad in ("x", "-2", "233"):
        with pytest.raises(ConfigError, match="ROS_DOMAIN_ID"):
            resolve_domain_id(-1, {"ROS_DOMAIN_ID": bad})
    with pytest.raises(ConfigError, match="ros2.cyclonedds_config"):
        cyclone_config_uri(str(tmp_path / "missing.xml"))
    (tmp_path / "c.xml").write_text("<CycloneDDS/>")
    assert cyclone_config_uri(str(tmp_path / "c.xml")) == (tmp_path / "c.xml").as_uri()
    for key, value in (("namespace", '"a//b"'), ("namespace", '"9robot"'), ("domain_id", "233"),
                       ("queue_size", "1")):
        with pytest.raises(ConfigError, match=f"ros2.{key}"):
            load_config(None, [f"ros2.{key}={value}"])
    assert load_config(None, ['ros2.namespace="robot1"']).ros2.namespace == "robot1"
    assert normalise_namespace("robot1") == "/robot1" and normalise_namespace("/") == ""


def test_scan_keeps_rep117_and_the_sensor_limits() -> None:
    s = scan_sample(0.0)
    msg = convert.laser_scan(s.rep117_ranges_m, s.scan.bearings_rad, 1e-4, 12.5, 0.025, s.range_limits_m)
    assert msg.header.frame_id == "laser" and (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12, 500_000_000)
    assert msg.ranges[0] == math.inf and msg.ranges[1] == -math.inf and math.isnan(msg.ranges[2])
    assert (msg.angle_min, msg.angle_max, msg.angle_increment) == pytest.approx((-2.0, 2.0, 0.5))
    assert (msg.range_min, msg.range_max) == pytest.approx((0.023, 30.0))
    unknown = convert.laser_scan(s.scan.ranges_m, s.scan.bearings_rad, 1e-4, 0.0, 0.0, None)
    assert unknown.range_min == 0.0 and unknown.range_max == math.inf


def test_odometry_carries_the_pose_covariance_in_ros_order() -> None:
    msg = convert.odometry(estimate(()), Odometry(0, 0, 0, 0.2, 0.1, 1.0), 5.0)
    cov = np.asarray(msg.pose.covariance).reshape(6, 6)
    assert cov[0, 0] == 0.01 and cov[1, 1] == 0.02 and cov[5, 5] == 0.003 and cov[2, 2] == 0.0
    assert msg.twist.covariance[0] == -1.0  # the base reports none
    assert (msg.twist.twist.linear.x, msg.twist.twist.angular.z) == (0.2, 0.1)
    assert msg.pose.pose.orientation.z == pytest.approx(math.sin(0.15))
    assert convert.covariance6(np.full((3, 3), np.nan))[0] == -1.0


def test_tracks_and_markers_carry_each_obstacle() -> None:
    run_id = bytes(range(8))
    msg = convert.tracks((obstacle(7, False),), 3.0, run_id)
    (t,) = msg.tracks
    assert msg.header.frame_id == "odom" and bytes(t.uuid.uuid) == run_id + (7).to_bytes(8, "big")
    assert (t.position.x, t.position.y, t.velocity.x, t.velocity.y) == (1.0, 2.0, 0.3, -0.4)
    assert t.position_covariance == [0.01, 0.005, 0.0, 0.02, 0.0, 0.0]
    assert t.velocity_covariance == [0.03, 0.0, 0.0, 0.04, 0.0, 0.0]
    assert t.classification == m.RadarClassification.DYNAMIC and t.size.x == 0.5
    unknown = Obstacle(1, 0, 0, 0, 0, 0.2, 0, 0, 0, 0)  # no covariance: NaN, never a made-up certainty
    assert all(math.isnan(v) for v in convert.tracks((unknown,), 0.0, run_id).tracks[0].position_covariance)
    arr = convert.markers((obstacle(7, False), obstacle(8, True)), 3.0, 0.3, "obstacles", convert.OBSTACLE_COLOR)
    assert arr.markers[0].action == m.MarkerConst.DELETEALL
    kinds = [(mk.ns, mk.id, mk.type) for mk in arr.markers[1:]]
    assert ("obstacles", 7, m.MarkerConst.CYLINDER) in kinds and ("obstacles/velocity", 8, m.MarkerConst.ARROW) in kinds
    assert all(mk.header.frame_id == "odom" and mk.lifetime.nanosec == 300_000_000 for mk in arr.markers[1:])


def test_the_publisher_splits_people_from_obstacles() -> None:
    pub = Ros2Publisher(Ros2Config(enabled=True), MOUNTS, 0.1)
    pub.state = "ok"  # as if DDS were up, with the thread not started
    est = estimate((obstacle(1, False), obstacle(2, True)))
    for wall_s in (10.0, 10.025, 10.05, 10.075, 10.1, 10.125):  # estimates at 40 Hz
        pub.estimate(est, Odometry(0, 0, 0, 0, 0, 1.0), wall_s, (0.1, 0.0), None)
    names = [name for name, _ in pub._queue]
    assert names.count("/vipsm/obstacles/tracks") == 6 and names.count("/odom") == 6
    assert names.count("/vipsm/obstacles") == names.count("/vipsm/people") == 2  # markers at 10 Hz
    pub._queue.clear()
    for wall_s in (20.0, 20.098, 20.201, 20.299):  # a 10 Hz loop with jitter: markers every estimate
        pub.estimate(est, Odometry(0, 0, 0, 0, 0, 1.0), wall_s, (0.1, 0.0), None)
    assert [name for name, _ in pub._queue].count("/vipsm/obstacles") == 4
    built = {name: build() for name, build in pub._queue}
    assert [tr.uuid.uuid[-1] for tr in built["/vipsm/people/tracks"].tracks] == [2]
    assert len(built["/vipsm/obstacles/tracks"].tracks) == 2
    tf = {(t.header.frame_id, t.child_frame_id) for t in built["/tf"].transforms}
    assert tf == {("odom", "base_link"), ("base_link", "camera")}


def test_transforms_follow_the_field_log() -> None:
    tfs = convert.static_transforms(MOUNTS, 1.0).transforms
    static = {(t.header.frame_id, t.child_frame_id): t.transform for t in tfs}
    assert static[("base_link", "laser")].translation.x == 0.1
    q = static[("camera", "camera_optical")].rotation
    # the optical frame's z axis is the camera's x axis (forward), its x axis the camera's -y (right)
    rot = _matrix(q)
    assert rot[:, 2] == pytest.approx([1, 0, 0]) and rot[:, 0] == pytest.approx([0, -1, 0])
    q = convert.pan_tilt(0.4, -0.2)
    assert math.isclose(q.x**2 + q.y**2 + q.z**2 + q.w**2, 1.0)
    assert _matrix(q)[:, 0] == pytest.approx([math.cos(0.4) * math.cos(-0.2), math.sin(0.4) * math.cos(-0.2),
                                              -math.sin(-0.2)])


def _matrix(q: m.Quaternion) -> np.ndarray:
    x, y, z, w = q.x, q.y, q.z, q.w
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_close_stops_the_thread() -> None:
    pub = Ros2Publisher(Ros2Config(enabled=True, domain_id=202), MOUNTS, 0.1).start()
    done = threading.Event()
    threading.Thread(target=lambda: (pub.close(1.0), done.set()), daemon=True).start()
    assert done.wait(30.0)  # close waits at most its timeout
    pub._thread.join(30.0)
    assert not pub._thread.is_alive()


def test_an_unexpected_error_on_the_thread_surfaces_as_a_state() -> None:
    pub = Ros2Publisher(Ros2Config(enabled=True, domain_id=204), MOUNTS, 0.1)

    def broken() -> None:
        raise RuntimeError("boom")

    pub._serve = broken  # type: ignore[method-assign]
    pub.start()
    pub._thread.join(30.0)
    assert pub.state == "failed" and "boom" in (pub.error or "")
    assert [level for level, _ in pub.take_events()] == ["info", "error"]  # up, then down: each said once


@pytest.mark.parametrize("argv, message", [
    (["--duration", "0"], "--duration"),
    (["--domain-id", "233"], "--domain-id"),
    (["--namespace", "9x"], "ros2.namespace"),
    (["--cyclonedds-config", "/no/such/file.xml"], "ros2.cyclonedds_config"),
])
def test_ros2_listen_refuses_bad_arguments(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    from app.cli import main

    assert main(["ros2-listen", *argv]) == 2
    assert message in capsys.readouterr().err
