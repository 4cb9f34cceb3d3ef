"""ROS bags as the estimator's input (app.bagread) and ``vipsm-robot replay BAG``: ROS 1 and ROS 2 bags
written here with ``rosbags``, the typed errors with their exit codes, the field log of a bag's replay,
the round trip through ``export --rosbag2``, and the shared real recordings."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.bagread import (
    BagOpenError,
    BagReadResult,
    BagTopicError,
    BagTopics,
    BagTypeError,
    read_bag,
)
from app.cli import main

REPO = Path(__file__).resolve().parents[2]
N_BEAMS = 181  # a 180-degree, 1-degree scanner
T0 = 1_700_000_000


def _scan_msg(ts, i: int, ranges: np.ndarray, ros1: bool, inc: float = math.radians(1.0)):
    t = ts.types
    prefix = "std_msgs/msg/"
    stamp = t["builtin_interfaces/msg/Time"](sec=T0 + i // 10, nanosec=(i % 10) * 100_000_000)
    header = t[prefix + "Header"](seq=i, stamp=stamp, frame_id="laser") if ros1 else \
        t[prefix + "Header"](stamp=stamp, frame_id="laser")
    first = -math.pi / 2 if inc > 0 else math.pi / 2
    return t["sensor_msgs/msg/LaserScan"](
        header=header, angle_min=first, angle_max=first + inc * (N_BEAMS - 1), angle_increment=inc,
        time_increment=0.1 / 360, scan_time=0.1, range_min=0.05, range_max=5.0,
        ranges=ranges.astype(np.float32), intensities=np.zeros(0, np.float32))


def _odom_msg(ts, i: int, ros1: bool):
    t = ts.types
    stamp = t["builtin_interfaces/msg/Time"](sec=T0 + i // 10, nanosec=(i % 10) * 100_000_000)
    header = t["std_msgs/msg/Header"](seq=i, stamp=stamp, frame_id="odom") if ros1 else \
        t["std_msgs/msg/Header"](stamp=stamp, frame_id="odom")
    v3 = t["geometry_msgs/msg/Vector3"]
    pose = t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](x=0.01 * i, y=0.0, z=0.0),
                                       orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))
    return t["nav_msgs/msg/Odometry"](
        header=header, child_frame_id="base_link",
        pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
        twist=t["geometry_msgs/msg/TwistWithCovariance"](
            twist=t["geometry_msgs/msg/Twist"](linear=v3(x=0.1, y=0.0, z=0.0), angular=v3(x=0.0, y=0.0, z=0.0)),
            covariance=np.zeros(36)))


def _room_ranges(i: int) -> np.ndarray:
    """A room's walls seen from the middle; beam 10 beyond range_max, beam 11 below range_min."""
    b = np.radians(np.arange(N_BEAMS) - 90.0)
    r = np.minimum(3.0 / np.maximum(np.abs(np.cos(b)), 1e-3), 2.0 / np.maximum(np.abs(np.sin(b)), 1e-3))
    r = np.minimum(r, 4.5)
    r[10], r[11] = 7.0, 0.01
    return r


def write_bag(path: Path, ros1: bool, n: int = 20, odom: bool = True, inc: float = math.radians(1.0)) -> Path:
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:
        from rosbags.rosbag1 import Writer

        writer, ser = Writer(path), ts.serialize_ros1
    else:
        from rosbags.rosbag2 import Writer

        writer, ser = Writer(path, version=8), ts.serialize_cdr
    with writer:
        kw = {"typestore": ts}
        scan_c = writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", **kw)
        odom_c = writer.add_connection("/odom", "nav_msgs/msg/Odometry", **kw) if odom else None
        for i in range(n):
            t_ns = (T0 + i // 10) * 1_000_000_000 + (i % 10) * 100_000_000
            if odom_c is not None:
                writer.write(odom_c, t_ns, ser(_odom_msg(ts, i, ros1), "nav_msgs/msg/Odometry"))
            scan = _scan_msg(ts, i, _room_ranges(i), ros1, inc)
            writer.write(scan_c, t_ns + 1, ser(scan, "sensor_msgs/msg/LaserScan"))
    return path


@pytest.mark.parametrize("ros1", [True, False], ids=["ros1", "ros2"])
def test_bag_reads_scans_and_odometry(tmp_path: Path, ros1: bool) -> None:
    path = write_bag(tmp_path / ("r.bag" if ros1 else "r2"), ros1)
    read = BagReadResult()
    cycles = list(read_bag(path, BagTopics("/scan", "/odom"), read=read))
    assert len(cycles) == 20 and read.scans == 20 and read.odometry == 20
    s = cycles[3].scan
    assert s.ranges_m.size == N_BEAMS
    assert s.bearings_rad[0] == pytest.approx(-math.pi / 2) and np.all(np.diff(s.bearings_rad) > 0)
    assert math.isnan(s.ranges_m[10]) and math.isnan(s.ranges_m[11])  # beyond range_max, below range_min
    assert s.ranges_m[90] == pytest.approx(3.0, abs=1e-5)
    assert s.stamp_s == pytest.approx(T0 + 0.3) and s.beam_dt_s == pytest.approx(0.1 / 360)
    assert cycles[3].odometry_given and cycles[3].odometry.x_m == pytest.approx(0.03)
    assert cycles[3].odometry.v_mps == pytest.approx(0.1)
    assert read.sensor is not None and read.sensor.scan_period_s == pytest.approx(0.1)
    assert math.degrees(read.sensor.fov_rad) == pytest.approx(180.0, abs=1e-3)


def test_bag_without_odometry_holds_the_identity(tmp_path: Path) -> None:
    path = write_bag(tmp_path / "n.bag", True, n=3, odom=False)
    cycles = list(read_bag(path, BagTopics("scan")))  # the leading / is forgiven
    assert [c.odometry_given for c in cycles] == [False] * 3
    assert all((c.odometry.x_m, c.odometry.y_m, c.odometry.theta_rad) == (0.0, 0.0, 0.0) for c in cycles)


def test_clockwise_scanner_is_reversed(tmp_path: Path) -> None:
    path = write_bag(tmp_path / "cw.bag", True, n=1, odom=False, inc=-math.radians(1.0))
    (c,) = list(read_bag(path, BagTopics("/scan")))
    assert np.all(np.diff(c.scan.bearings_rad) > 0) and c.scan.bearings_rad[0] == pytest.approx(-math.pi / 2)
    # beam 10 of the message (beyond range) is now beam N-1-10
    assert math.isnan(c.scan.ranges_m[N_BEAMS - 11]) and c.scan.beam_dt_s < 0


def test_missing_topic_lists_the_topics(tmp_path: Path) -> None:
    path = write_bag(tmp_path / "m.bag", True, n=2)
    with pytest.raises(BagTopicError, match=r"'/laser' is not in the bag; its topics: /odom \(Odometry\), "
                                            r"/scan \(LaserScan\)"):
        list(read_bag(path, BagTopics("/laser")))
    with pytest.raises(BagTypeError, match="carries nav_msgs/msg/Odometry"):
        list(read_bag(path, BagTopics("/odom")))
    with pytest.raises(BagTypeError, match="--odom topic '/scan'"):
        list(read_bag(path, BagTopics("/scan", "/scan")))


def test_truncated_and_foreign_bags_are_typed_errors(tmp_path: Path) -> None:
    path = write_bag(tmp_path / "t.bag", True, n=20)
    cut = tmp_path / "cut.bag"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(BagOpenError, match="cut.bag: cannot read the bag.*index"):
        list(read_bag(cut, BagTopics("/scan")))
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"not a bag at all")
    with pytest.raises(BagOpenError, match="junk.bag"):
        list(read_bag(junk, BagTopics("/scan")))
    r2 = write_bag(tmp_path / "r2", False, n=20)
    (db,) = r2.glob("*.db3")
    db.write_bytes(db.read_bytes()[: db.stat().st_size // 2])
    with pytest.raises(BagOpenError, match="r2"):
        list(read_bag(r2, BagTopics("/scan")))


def test_cli_errors_are_one_line_with_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_bag(tmp_path / "c.bag", True, n=2)
    cut = tmp_path / "cut.bag"
    cut.write_bytes(path.read_bytes()[:300])
    for argv, msg in ((["replay", str(path), "--scan", "/nope"], "is not in the bag; its topics"),
                      (["replay", str(path)], "needs --scan TOPIC"),
                      (["replay", str(cut), "--scan", "/scan"], "cannot read the bag"),
                      (["replay", str(tmp_path / "absent.bag"), "--scan", "/scan"], "no such bag"),
                      (["replay", str(path), "--scan", "/scan", "--image", "/scan"],
                       "carries sensor_msgs/msg/LaserScan"),
                      (["replay", str(path), "--scan", "/scan", "--fx", "500"], "--fx, --fy, --cx and --cy")):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert msg in err and err.count("\n") == 1 and "Traceback" not in err


def test_replay_bag_writes_a_field_log_that_replays_identically(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "w.bag", True, n=20)
    out = tmp_path / "out.mcap"
    env = {"PYTHONPATH": str(REPO)}
    run = subprocess.run([sys.executable, "-m", "app", "replay", str(bag), "--scan", "/scan", "--odom", "/odom",
                          "--laser-x", "0.1", "--laser-yaw-deg", "5", "--json", "--log", str(out)],
                         capture_output=True, text=True, timeout=120, env=env, cwd=REPO)
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["cycles"] == 20 and summary["bag"]["sensor"]["beams"] == N_BEAMS
    assert summary["field_log"]["path"] == str(out) and summary["field_log"]["bad_messages"] == 0
    back = subprocess.run([sys.executable, "-m", "app", "replay", str(out), "--json"], capture_output=True, text=True,
                          timeout=120, env=env, cwd=REPO)
    assert back.returncode == 0, back.stderr
    again = json.loads(back.stdout)
    assert again["cycles"] == 20 and again["identical_to_recorded"] == 20
    from app.logread import read_log
    from app.replay import recorded_estimator_config

    topics = {m.topic for m in read_log(out)}
    assert {"/scan", "/odom", "/pose", "/obstacles", "/tf", "/vipsm/cycle", "/vipsm/config"} <= topics
    cfg = recorded_estimator_config(out)
    assert cfg is not None and cfg.laser_x_m == 0.1 and cfg.laser_theta_rad == pytest.approx(math.radians(5))


def test_round_trip_sim_export_rosbag2_replay(tmp_path: Path) -> None:
    """A short simulated run's field log, exported as a ROS 2 bag, replays from the bag."""
    env = {"PYTHONPATH": str(REPO)}
    log, bag = tmp_path / "sim.mcap", tmp_path / "sim_bag"

    def vipsm(*argv: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "app", *argv], capture_output=True, text=True, timeout=180,
                              env=env, cwd=REPO)

    sim = vipsm("sim", "--scenario", "1", "--duration", "1.5", "--log", str(log), "--no-progress", "--json",
                "--set", "status.enabled=false")  # no Modbus port: other runs on the machine may hold it
    assert sim.returncode == 0, sim.stderr
    exp = vipsm("export", str(log), "--rosbag2", str(bag))
    assert exp.returncode == 0, exp.stderr
    run = vipsm("replay", str(bag), "--scan", "/scan", "--odom", "/odom", "--json")
    assert run.returncode == 0, run.stderr
    s = json.loads(run.stdout)
    assert s["cycles"] > 10 and s["bag"]["odometry_messages"] > 0
    assert s["bag"]["sensor"]["beams"] == 1081 and s["bag"]["sensor"]["scan_period_s"] == pytest.approx(0.025)
    # the fake UTM-30LX's PP reply (DMIN 23 mm, DMAX 60000 mm), carried by the log's /vipsm/scanner
    assert (s["bag"]["sensor"]["range_min_m"], s["bag"]["sensor"]["range_max_m"]) == pytest.approx((0.023, 60.0))


def test_compressed_image_with_camera_info(tmp_path: Path) -> None:
    import cv2
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    t = ts.types
    img = (np.indices((48, 64)).sum(axis=0) % 256).astype(np.uint8)
    ok, jpeg = cv2.imencode(".jpg", img)
    assert ok
    path = tmp_path / "img"
    with Writer(path, version=8) as w:
        cs = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=ts)
        ci = w.add_connection("/cam/info", "sensor_msgs/msg/CameraInfo", typestore=ts)
        cim = w.add_connection("/cam/image", "sensor_msgs/msg/CompressedImage", typestore=ts)
        hdr = t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=T0, nanosec=0), frame_id="camera")
        roi = t["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
        info = t["sensor_msgs/msg/CameraInfo"](
            header=hdr, height=48, width=64, distortion_model="plumb_bob", d=np.array([0.1, 0.0, 0.0, 0.0, 0.0]),
            k=np.array([50.0, 0, 32, 0, 51.0, 24, 0, 0, 1]), r=np.eye(3).ravel(), p=np.zeros(12), binning_x=0,
            binning_y=0, roi=roi)
        w.write(ci, T0 * 10**9, ts.serialize_cdr(info, "sensor_msgs/msg/CameraInfo"))
        im = t["sensor_msgs/msg/CompressedImage"](header=hdr, format="jpeg", data=jpeg.ravel())
        w.write(cim, T0 * 10**9 + 1, ts.serialize_cdr(im, "sensor_msgs/msg/CompressedImage"))
        w.write(cs, T0 * 10**9 + 2, ts.serialize_cdr(_scan_msg(ts, 0, _room_ranges(0), False),
                                                     "sensor_msgs/msg/LaserScan"))
    (c,) = list(read_bag(path, BagTopics("/scan", None, "/cam/image", "/cam/info")))
    assert c.frame is not None and c.jpeg == jpeg.tobytes() and c.frame.image.shape == (48, 64)
    assert (c.frame.intrinsics.fx_px, c.frame.intrinsics.fy_px, c.frame.intrinsics.k1) == (50.0, 51.0, 0.1)
    with pytest.raises(Exception, match="needs --camera-info"):
        list(read_bag(path, BagTopics("/scan", None, "/cam/image")))


def test_replay_runs_on_a_shared_recording(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = shared_data / "real_people_laser" / "positive_2.bag"
    if not bag.exists():
        pytest.skip(f"{bag} not found")
    assert main(["replay", str(bag), "--scan", "right_scan", "--max-scans", "25", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["cycles"] == 25
    assert s["bag"]["sensor"] == {"frame_id": "right_laser", "beams": 768, "fov_deg": pytest.approx(269.648, abs=0.01),
                                  "step_deg": pytest.approx(0.35156, abs=1e-4), "range_min_m": 0.03,
                                  "range_max_m": 11.0, "scan_period_s": pytest.approx(0.13333, abs=1e-4)}


def test_replay_bag_plots_and_max_scans(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_bag(tmp_path / "p.bag", True, n=20)
    assert main(["replay", str(bag), "--scan", "/scan", "--odom", "/odom", "--max-scans", "8", "--plots",
                 str(tmp_path / "figs"), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["cycles"] == 8 and len(s["plots"]) == 3
    assert all(Path(p).stat().st_size > 1000 and Path(p).parent == tmp_path / "figs" for p in s["plots"])


def test_bag_with_images_replays_from_its_field_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """JPEG frames go into the field log, so its replay matches the bag's cycle for cycle."""
    import cv2
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    t = ts.types
    rng = np.random.default_rng(0)
    path = tmp_path / "cam"
    with Writer(path, version=8) as w:
        cs = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=ts)
        cim = w.add_connection("/image", "sensor_msgs/msg/CompressedImage", typestore=ts)
        for i in range(6):
            t_ns = (T0 + i // 10) * 10**9 + (i % 10) * 100_000_000
            img = cv2.GaussianBlur(rng.integers(0, 255, (60, 80), dtype=np.uint8), (5, 5), 0)
            ok, jpeg = cv2.imencode(".jpg", img)
            stamp = t["builtin_interfaces/msg/Time"](sec=t_ns // 10**9, nanosec=t_ns % 10**9)
            im = t["sensor_msgs/msg/CompressedImage"](header=t["std_msgs/msg/Header"](stamp=stamp, frame_id="camera"),
                                                      format="jpeg", data=jpeg.ravel())
            w.write(cim, t_ns, ts.serialize_cdr(im, "sensor_msgs/msg/CompressedImage"))
            w.write(cs, t_ns + 1, ts.serialize_cdr(_scan_msg(ts, i, _room_ranges(i), False),
                                                   "sensor_msgs/msg/LaserScan"))
    out = tmp_path / "cam.mcap"
    assert main(["replay", str(path), "--scan", "/scan", "--image", "/image", "--fx", "60", "--fy", "60", "--cx", "40",
                 "--cy", "30", "--json", "--log", str(out)]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["bag"]["frames"] == 6 and s["cycles"] == 6
    assert main(["replay", str(out), "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["identical_to_recorded"] == 6


def test_malformed_scan_is_skipped_and_counted_exit_3(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    path = tmp_path / "bad.bag"
    with Writer(path) as w:
        c = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=ts)
        for i in range(5):
            msg = _scan_msg(ts, i, _room_ranges(i), True, inc=0.0 if i == 2 else math.radians(1.0))
            w.write(c, T0 * 10**9 + i * 100_000_000, ts.serialize_ros1(msg, "sensor_msgs/msg/LaserScan"))
    assert main(["replay", str(path), "--scan", "/scan", "--json"]) == 3
    captured = capsys.readouterr()
    s = json.loads(captured.out)
    assert s["cycles"] == 4 and s["bad_messages"] == 1 and "angle_increment 0.0" in s["bad_message_reasons"][0]
    assert "1 malformed message(s) skipped" in captured.err


def test_damage_part_way_keeps_what_came_before(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """A chunk that cannot be read (rosbags raises while iterating) ends the bag there: the scans before
    it are replayed and reported, the cut named, exit 3."""
    import struct

    from rosbags.highlevel import AnyReader

    path = write_bag(tmp_path / "d.bag", True, n=10, odom=False)
    real = AnyReader.messages

    def damaged(self, *a, **kw):  # type: ignore[no-untyped-def]
        for k, item in enumerate(real(self, *a, **kw)):
            if k == 6:
                raise struct.error("unpack requires a buffer of 4 bytes")
            yield item

    monkeypatch.setattr(AnyReader, "messages", damaged)
    assert main(["replay", str(path), "--scan", "/scan", "--json"]) == 3
    captured = capsys.readouterr()
    s = json.loads(captured.out)
    assert s["cycles"] == 6 and s["truncated"] and "damaged after 6 scans: error: unpack" in s["truncation"]
    assert "the bag is damaged after 6 scans" in captured.err
