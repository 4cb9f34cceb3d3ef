"""``sim --ros2`` seen from another process as a ROS 2 node would see it: plain ``cyclonedds`` on
loopback only (multicast off, unicast discovery on 127.0.0.1, both processes with the same Cyclone
config), a domain of its own (so parallel runs do not mix) and a namespace. Each topic arrives with
its ROS 2 type name, the frames of REP 105 / 117, stamps of the run's wall-clock time and ROS 2's QoS;
``/tf_static`` reaches a reader created late (transient local)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from app.cmd_ros2 import LOOPBACK_XML
from app.ros2.publisher import TOPICS
from tests.machine_lock import MachineLock

ROOT = Path(__file__).resolve().parents[2]
CYCLONE_XML = LOOPBACK_XML  # loopback only, no multicast: the machine's network stays out
NAMESPACE = "/e2e"


def header_ok(h: dict, frame: str, t0: float, t1: float) -> None:
    assert h["frame_id"] == frame
    t = h["stamp"]["sec"] + h["stamp"]["nanosec"] * 1e-9
    assert t0 - 1.0 <= t <= t1, (t0, t, t1)


@pytest.fixture(scope="module")
def ros2_run(tmp_path_factory: pytest.TempPathFactory, machine_lock: MachineLock) -> dict:
    tmp = tmp_path_factory.mktemp("ros2")
    xml = tmp / "cyclonedds.xml"
    xml.write_text(CYCLONE_XML)
    domain = 100 + os.getpid() % 100
    env = {**os.environ, "PYTHONPATH": str(ROOT), "ROS_DOMAIN_ID": str(domain), "CYCLONEDDS_URI": xml.as_uri()}
    subscriber = [sys.executable, str(ROOT / "tests/app/ros2_subscriber.py"), NAMESPACE, str(tmp / "seen.json")]
    sub = subprocess.Popen(subscriber, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=tmp)
    try:
        assert sub.stdout is not None and sub.stdout.readline().strip() == "ready"
        # the daemon: the domain from ROS_DOMAIN_ID, its Cyclone config from ros2.cyclonedds_config
        sim_env = {k: v for k, v in env.items() if k != "CYCLONEDDS_URI"}
        t0 = time.time()
        with machine_lock.exclusive():  # a real-time run: the simulated robot must keep its pace
            proc = subprocess.run(
                [sys.executable, "-m", "app", "sim", "--scenario", "1", "--duration", "3", "--ros2", "--json",
                 "--no-progress", "--log", str(tmp / "sim.mcap"), "--set", f'ros2.namespace="{NAMESPACE}"',
                 "--set", f'ros2.cyclonedds_config="{xml}"', "--set", "status.port=0"],
                env=sim_env, cwd=tmp, capture_output=True, text=True, timeout=150)
        t1 = time.time()
        assert proc.returncode == 0, proc.stderr[-2000:]
        time.sleep(0.5)  # the last samples in flight
    finally:
        sub.communicate(timeout=30)
    return {"seen": json.loads((tmp / "seen.json").read_text()), "summary": json.loads(proc.stdout), "t0": t0,
            "t1": t1, "stderr": proc.stderr}


def test_every_topic_arrives_with_its_ros2_type_and_qos(ros2_run: dict) -> None:
    seen, summary = ros2_run["seen"], ros2_run["summary"]
    assert summary["ros2"]["state"] == "ok" and summary["ros2"]["errors"] == 0, summary["ros2"]
    assert summary["ros2"]["namespace"] == NAMESPACE
    for name, (ros_type, profile) in TOPICS.items():
        entry = seen[name]
        assert entry["count"] >= 1, name
        pkg, _, typ = ros_type.split("/")
        assert entry["writer"]["type_name"] == f"{pkg}::msg::dds_::{typ}_", name
        assert entry["writer"]["topic_name"] == f"rt{NAMESPACE}{name}"
        w = entry["writer"]
        assert w["reliability"].startswith("Policy.Reliability.Reliable" if profile.reliable
                                           else "Policy.Reliability.BestEffort"), (name, w)
        assert w["durability"] == ("Policy.Durability.TransientLocal" if profile.transient_local
                                   else "Policy.Durability.Volatile"), (name, w)
        assert w["history"] == f"Policy.History.KeepLast(depth={profile.depth})", (name, w)
    assert seen["/scan"]["count"] >= seen["/odom"]["count"]  # at most one estimate per scan


def test_frames_stamps_and_content(ros2_run: dict) -> None:
    seen, t0, t1 = ros2_run["seen"], ros2_run["t0"], ros2_run["t1"]
    scan = seen["/scan"]["samples"][0]
    header_ok(scan["header"], "laser", t0, t1)
    assert scan["angle_increment"] > 0 and scan["time_increment"] > 0
    assert scan["angle_min"] < 0 < scan["angle_max"] and len(scan["ranges"]) > 100
    assert 0 < scan["range_min"] < 0.1 and scan["range_max"] >= 30.0  # the sensor's own DMIN/DMAX (PP)
    # scan_time: the interval since the previous scan (equal to the stamps' difference when no scan
    # was lost between two received ones)
    scans = seen["/scan"]["samples"]
    stamps = [s["header"]["stamp"]["sec"] + s["header"]["stamp"]["nanosec"] * 1e-9 for s in scans]
    for prev, scan_s, this in zip(stamps, stamps[1:], scans[1:], strict=False):
        assert 0.0 < this["scan_time"] <= scan_s - prev + 1e-6
    odom = seen["/odom"]["last"]
    header_ok(odom["header"], "odom", t0, t1)
    assert odom["child_frame_id"] == "base_link"
    assert odom["pose"]["covariance"][0] >= 0.0  # the estimator's covariance, known
    assert odom["twist"]["twist"]["linear"]["x"] == pytest.approx(0.2, abs=0.05)  # cruise at 0.2 m/s
    tf = {(t["header"]["frame_id"], t["child_frame_id"]) for t in seen["/tf"]["last"]["transforms"]}
    assert {("odom", "base_link"), ("base_link", "camera"), ("world", "odom")} <= tf
    for t in seen["/tf"]["last"]["transforms"]:
        header_ok(t["header"], t["header"]["frame_id"], t0, t1)
    static = {(t["header"]["frame_id"], t["child_frame_id"]) for t in seen["/tf_static"]["samples"][0]["transforms"]}
    assert static == {("base_link", "laser"), ("camera", "camera_optical")}
    image = seen["/camera/image/compressed"]["samples"][0]
    header_ok(image["header"], "camera_optical", t0, t1)
    assert image["format"] == "jpeg" and image["data"][:2] == [0xFF, 0xD8]
    for name in ("/vipsm/obstacles", "/vipsm/people"):
        first = seen[name]["samples"][0]["markers"][0]
        assert first["action"] == 3  # DELETEALL, then this cycle's markers
        header_ok(first["header"], "odom", t0, t1)
    for name in ("/vipsm/obstacles/tracks", "/vipsm/people/tracks"):
        header_ok(seen[name]["samples"][0]["header"], "odom", t0, t1)
    diag = seen["/diagnostics"]["samples"][-1]  # (at 1 Hz: the first few)
    names = {s["name"]: s for s in diag["status"]}
    assert {"vipsm-robot: scanner", "vipsm-robot: base", "vipsm-robot: camera", "vipsm-robot: loop",
            "vipsm-robot: field log", "vipsm-robot: ros2 publisher"} == set(names)
    assert names["vipsm-robot: scanner"]["level"] == 0 and names["vipsm-robot: scanner"]["message"] == "ok"


def test_a_dds_failure_leaves_the_run_going(tmp_path: Path) -> None:
    """An unusable Cyclone config: the participant cannot be made; the run goes on without ROS 2,
    says so once and reports the state in its summary."""
    bad = tmp_path / "bad.xml"
    bad.write_text("<CycloneDDS><Domain><General><NoSuchSetting/></General></Domain></CycloneDDS>")
    proc = subprocess.run(
        [sys.executable, "-m", "app", "sim", "--scenario", "1", "--duration", "2", "--ros2", "--json", "--no-progress",
         "--log", str(tmp_path / "sim.mcap"), "--set", f'ros2.cyclonedds_config="{bad}"', "--set", "status.port=0"],
        env={**os.environ, "PYTHONPATH": str(ROOT)}, cwd=tmp_path, capture_output=True, text=True, timeout=150)
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = json.loads(proc.stdout)
    assert summary["ros2"]["state"] == "failed" and "DDS" in summary["ros2"]["error"]
    assert summary["estimates"] > 0
    assert sum("ros2: starting -> failed" in e for e in summary["events"]) == 1
