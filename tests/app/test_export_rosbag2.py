"""``export --rosbag2`` (issue 32 row 4, issue 31 ROS 2 export): exit codes and counts as ``replay``,
no bag that looks complete unless it is, the partial folder of a killed export cleaned up, the QoS
profiles ``ros2 bag record`` writes, and covariances by nav_msgs conventions."""

from __future__ import annotations

import dataclasses
import fcntl
import json
import math
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from foxglove import messages as fm
from mcap.writer import Writer
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from ruamel.yaml import YAML

from app import logmessages as lm
from app.config import Config
from app.export_rosbag2 import UNOBSERVED_VARIANCE, export_rosbag2, partial_folder

T0 = 1_700_000_000.0
N = 20
MOUNTS = lm.Mounts(0.1, 0.0, 0.0, 0.05, 0.0, 0.3)


def cycle(k: int, x: float) -> dict[str, Any]:
    cov = [0.0004, 0.0, 0.0, 0.0, 0.0009, 0.0, 0.0, 0.0, 0.0001]
    return {"cycle": k, "scan": {}, "odometry": {"x_m": x, "y_m": 0.0, "theta_rad": 0.0, "v_mps": 0.2,
                                                 "w_radps": 0.01, "stamp_s": T0 + 0.1 * k},
            "frame": None, "estimate": {"pose": [x, 0.0, 0.0], "covariance": cov, "obstacles": [
                {"track_id": 3, "x_m": 2.0, "y_m": 1.0, "vx_mps": 0.1, "vy_mps": 0.0, "radius_m": 0.4}]}}


class LogWriter:
    """A field log written record by record, so that tests can put anything on any channel."""

    def __init__(self, path: Path) -> None:
        self.f = open(path, "wb")  # noqa: SIM115 - closed by finish()
        self.w = Writer(self.f)
        self.w.start()
        self.channels: dict[str, int] = {}  # 'topic schema' -> channel id

    def channel(self, topic: str, schema: Any) -> int:
        """One channel per topic and schema (a second schema on a topic is a second channel)."""
        key = f"{topic} {schema if isinstance(schema, str) else schema.get_schema().name}"
        if key not in self.channels:
            if isinstance(schema, str):
                sid = self.w.register_schema(schema, "jsonschema", b"{}")
                self.channels[key] = self.w.register_channel(topic, "json", sid)
            else:
                s = schema.get_schema()
                sid = self.w.register_schema(s.name, s.encoding, s.data)
                self.channels[key] = self.w.register_channel(topic, "protobuf", sid)
        return self.channels[key]

    def add(self, topic: str, t_s: float, payload: Any, schema: Any = None) -> None:
        if isinstance(payload, dict):
            cid, data = self.channel(topic, schema or "vipsm.Cycle"), json.dumps(payload).encode()
        elif isinstance(payload, bytes):
            cid, data = self.channel(topic, schema), payload
        else:
            cid, data = self.channel(topic, schema or type(payload)), payload.encode()
        ns = lm.stamp_ns(t_s)
        self.w.add_message(cid, log_time=ns, publish_time=ns, data=data)

    def finish(self) -> None:
        self.w.finish()
        self.f.close()


def good_log(path: Path, extra: Any = None) -> None:
    w = LogWriter(path)
    w.add("/vipsm/config", T0, {"log_version": 2, **dataclasses.asdict(Config())}, "vipsm.Config")
    for k in range(N):
        t, x = T0 + 0.1 * k, 0.02 * k
        w.add("/scan", t, lm.laser_scan([1.0, math.inf, -math.inf, math.nan, 2.0], -1.0, 1.0, None, t))
        w.add("/odom", t, lm.pose_in_frame(x, 0.0, 0.0, t))
        w.add("/tf", t, lm.robot_transforms((x, 0.0, 0.0), MOUNTS, (0.0, 0.0), t))
        w.add("/vipsm/cycle", t, cycle(k, x))
        w.add("/diagnostics", t, {"cycle": k}, "vipsm.LoopDiagnostics")
        if extra is not None:
            extra(w, k, t)
    w.finish()


def bag_messages(bag: Path) -> tuple[dict[str, Any], dict[str, list[Any]]]:
    ts = get_typestore(Stores.ROS2_HUMBLE)
    out: dict[str, list[Any]] = {}
    with Reader(bag) as r:
        conns = {c.topic: c for c in r.connections}
        for c, _t, raw in r.messages():
            out.setdefault(c.topic, []).append(ts.deserialize_cdr(raw, c.msgtype))
    return conns, out


def run_export(log: Path, out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "app", "export", str(log), "--rosbag2", str(out), "--json"],
                          capture_output=True, text=True, timeout=300)


def test_every_topic_offers_the_qos_ros2_bag_record_writes(tmp_path: Path) -> None:
    log, out = tmp_path / "log.mcap", tmp_path / "bag"
    good_log(log)
    export_rosbag2(log, out)
    conns, _ = bag_messages(out)
    assert set(conns) == {"/scan", "/odom", "/tf", "/tf_static", "/vipsm/pose", "/vipsm/obstacles"}
    for topic, c in conns.items():
        (qos,) = c.ext.offered_qos_profiles
        assert qos.reliability == QosReliability.RELIABLE, topic
        want = QosDurability.TRANSIENT_LOCAL if topic == "/tf_static" else QosDurability.VOLATILE
        assert qos.durability == want, topic
        assert (qos.deadline.sec, qos.deadline.nsec) == (9223372036, 854775807)  # RMW_DURATION_INFINITE
    # bag format 8 (Humble on): each topic's profiles are a YAML string holding a list, enums as integers
    meta = YAML(typ="safe").load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    for entry in meta["topics_with_message_count"]:
        (profile,) = YAML(typ="safe").load(entry["topic_metadata"]["offered_qos_profiles"])
        assert profile["reliability"] == 1 and profile["history"] == 3 and profile["liveliness"] == 1
        assert profile["durability"] == (1 if entry["topic_metadata"]["name"] == "/tf_static" else 2)


def test_odometry_covariances_follow_nav_msgs_conventions(tmp_path: Path) -> None:
    log, out = tmp_path / "log.mcap", tmp_path / "bag"
    good_log(log)
    export_rosbag2(log, out)
    _, msgs = bag_messages(out)
    odom = msgs["/odom"]
    covs = [np.asarray(m.pose.covariance).reshape(6, 6) for m in odom]
    assert all(np.all(np.diag(c) > 0) for c in covs), "a variance <= 0 (-1 is no nav_msgs convention)"
    assert all(np.allclose(np.diag(c)[2:5], UNOBSERVED_VARIANCE) for c in covs)
    # the estimator's dead-reckoning model: sigma = odom_sigma_per_m x metres driven (0.38 m here)
    driven = 0.02 * (N - 1)
    assert math.isclose(math.sqrt(covs[-1][0, 0]), Config().estimator.odom_sigma_per_m * driven, rel_tol=1e-6)
    assert covs[-1][0, 0] > covs[1][0, 0]
    assert odom[-1].twist.twist.linear.x == pytest.approx(0.2) and odom[-1].twist.covariance[0] > 0
    pose = np.asarray(msgs["/vipsm/pose"][-1].pose.covariance).reshape(6, 6)
    assert pose[0, 0] == pytest.approx(0.0004) and pose[1, 1] == pytest.approx(0.0009)
    assert pose[5, 5] == pytest.approx(0.0001) and pose[2, 2] == UNOBSERVED_VARIANCE


def test_a_clean_log_exits_0_and_moves_the_bag_into_place(tmp_path: Path) -> None:
    log, out = tmp_path / "log.mcap", tmp_path / "bag"
    good_log(log)
    proc = run_export(log, out)
    assert proc.returncode == 0, proc.stderr
    res = json.loads(proc.stdout)
    assert res["messages"]["/scan"] == N and res["bad_messages"] == 0 and res["bad_chunks"] == 0
    assert res["not_exported"] == {"/diagnostics": N, "/vipsm/config": 1}
    assert (out / "metadata.yaml").exists() and not list(tmp_path.glob(".bag.partial-*"))


def test_an_empty_input_exits_2_and_leaves_no_bag(tmp_path: Path) -> None:
    log, out = tmp_path / "empty.mcap", tmp_path / "bag"
    log.write_bytes(b"")
    proc = run_export(log, out)
    assert proc.returncode == 2 and "no message to export" in proc.stderr and "Traceback" not in proc.stderr
    assert not out.exists() and not list(tmp_path.glob(".bag.partial-*"))


@pytest.mark.parametrize("fault", ["undecodable", "swapped", "undeclared"])
def test_skipped_messages_are_counted_and_exit_3(tmp_path: Path, fault: str) -> None:
    """940 undecodable scans, a swapped schema, a message on an undeclared channel: each one skipped and
    counted, everything else exported, exit 3 with a stderr line."""
    def extra(w: LogWriter, k: int, t: float) -> None:
        if fault == "undecodable":
            w.add("/scan", t, b"\xff\xff\xff\xff", fm.LaserScan)
        elif fault == "swapped" and k % 2 == 0:
            w.add("/odom", t, lm.laser_scan([1.0], 0.0, 0.0, None, t), fm.LaserScan)  # /odom's channel is PoseInFrame
        elif fault == "undeclared" and k == 5:
            w.w.add_message(999, log_time=lm.stamp_ns(t), publish_time=0, data=b"{}")

    log, out = tmp_path / "log.mcap", tmp_path / "bag"
    good_log(log, extra)
    proc = run_export(log, out)
    assert proc.returncode == 3, proc.stderr
    res = json.loads(proc.stdout)
    expected = {"undecodable": N, "swapped": N // 2, "undeclared": 1}[fault]
    assert res["bad_messages"] == expected and res["messages"]["/scan"] == N and res["messages"]["/odom"] == N
    assert "malformed message" in proc.stderr and "Traceback" not in proc.stderr
    _, msgs = bag_messages(out)
    assert len(msgs["/scan"]) == N


def test_a_killed_export_leaves_no_bag_and_the_next_export_cleans_up(tmp_path: Path) -> None:
    log, out = tmp_path / "log.mcap", tmp_path / "bag"
    good_log(log)
    script = textwrap.dedent(f"""
        import os, signal
        from app import export_rosbag2 as e
        real, n = e._export_checked, [0]
        def dying(bag, msg, result):
            real(bag, msg, result)
            n[0] += 1
            if n[0] == 30:
                os.kill(os.getpid(), signal.SIGKILL)
        e._export_checked = dying
        e.export_rosbag2({str(log)!r}, {str(out)!r})
        """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert proc.returncode == -9
    assert not out.exists(), "a killed export must not leave a bag that looks complete"
    assert len(list(tmp_path.glob(".bag.partial-*"))) == 1
    again = run_export(log, out)
    assert again.returncode == 0, again.stderr
    assert (out / "metadata.yaml").exists() and not list(tmp_path.glob(".bag.partial-*"))


def test_a_running_exports_partial_folder_is_not_removed(tmp_path: Path) -> None:
    out = tmp_path / "bag"
    with partial_folder(out) as mine:
        mine.mkdir()
        with open(mine.parent / "lock") as f:
            with pytest.raises(BlockingIOError):
                fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)  # held by the export writing it
        with partial_folder(out):
            assert mine.exists()
    assert not mine.parent.exists()


# ---------------------------------------------------------------------------------------------
# the scanner's own limits and timing (/vipsm/scanner), never the UTM-30LX's

#: a URG-04LX-class scanner: 682 beams of 360/1024 deg from -120 deg, 10 Hz, 0.02-5.6 m
URG = {"beams": 682, "angle_min_rad": -math.radians(120.0), "angle_increment_rad": 2 * math.pi / 1024,
       "time_increment_s": 0.1 / 1024, "scan_time_s": 0.1, "range_min_m": 0.02, "range_max_m": 5.6}
URG["angle_max_rad"] = URG["angle_min_rad"] + URG["angle_increment_rad"] * (URG["beams"] - 1)


def scanner_log(path: Path, records: list[tuple[int, dict[str, Any]]]) -> None:
    """N scans of 5 beams from -1 to +1 rad; ``records`` [(before scan k, /vipsm/scanner record)]."""
    w = LogWriter(path)
    for k in range(N):
        t = T0 + 0.1 * k
        for at, rec in records:
            if at == k:
                w.add("/vipsm/scanner", t, rec, "vipsm.ScannerInfo")
        w.add("/scan", t, lm.laser_scan([1.0, math.inf, -math.inf, math.nan, 2.0], -1.0, 1.0, None, t))
    w.finish()


def five_beams(**changes: Any) -> dict[str, Any]:
    rec = {"beams": 5, "angle_min_rad": -1.0, "angle_max_rad": 1.0, "angle_increment_rad": 0.5,
           "time_increment_s": 0.1 / 1024, "scan_time_s": 0.1, "range_min_m": 0.02, "range_max_m": 5.6}
    return {**rec, **changes}


def test_scan_limits_and_timing_are_the_scanners_and_follow_a_change(tmp_path: Path) -> None:
    """A 5.6 m, 10 Hz scanner's scans carry its values (not the UTM-30LX's 60 m and 25 ms); after a new
    record (another scanner on reconnect) the scans carry the new ones; unknown limits export as 0 / +inf."""
    log, out = tmp_path / "log.mcap", tmp_path / "bag"
    later = five_beams(time_increment_s=0.025 / 1440, scan_time_s=0.025, range_min_m=None, range_max_m=None)
    scanner_log(log, [(0, five_beams()), (12, later)])
    result = export_rosbag2(log, out)
    assert result.scan_info == {"recorded": N} and result.warnings == []
    assert result.not_exported["/vipsm/scanner"] == 2
    _, msgs = bag_messages(out)
    scans = msgs["/scan"]
    for k, m in enumerate(scans):
        assert (m.angle_min, m.angle_max, m.angle_increment) == pytest.approx((-1.0, 1.0, 0.5))
        if k < 12:
            assert (m.range_min, m.range_max) == pytest.approx((0.02, 5.6))
            assert (m.time_increment, m.scan_time) == pytest.approx((0.1 / 1024, 0.1))
        else:
            assert m.range_min == 0.0 and m.range_max == math.inf
            assert (m.time_increment, m.scan_time) == pytest.approx((0.025 / 1440, 0.025))


def test_an_old_log_exports_with_the_stated_assumption_and_one_warning(tmp_path: Path) -> None:
    """A log without /vipsm/scanner (version 2): range 0 to +inf, the beam time of its first cycle with as
    many beams, the scan time measured from the scans' stamps (0.1 s apart; the beam timing alone would
    say 0.05 s: a scanner whose bearing step is not its mirror's); said once on stderr and in the
    summary, exit 0."""
    def with_beam_timing(w: LogWriter, k: int, t: float) -> None:
        if k == 0:
            rec = cycle(0, 0.0)
            rec["scan"] = {"seq": 0, "stamp_s": t, "beam_dt_s": 0.05 / 1024, "first_bearing_rad": -1.0,
                           "bearing_step_rad": 2 * math.pi / 1024, "ranges_m": [1.0, None, None, None, 2.0]}
            w.add("/vipsm/cycle", t + 0.05, rec)

    log, out = tmp_path / "log.mcap", tmp_path / "bag"
    good_log(log, with_beam_timing)
    proc = run_export(log, out)
    assert proc.returncode == 0, proc.stderr
    res = json.loads(proc.stdout)
    assert res["scan_info"] == {"recorded": 0, "assumed": N} and len(res["warnings"]) == 1
    w = res["warnings"][0]
    assert "range_min 0 and range_max +inf" in w and "/vipsm/cycle" in w and f"median spacing of {N}" in w
    assert proc.stderr.count("warning") == 1
    _, msgs = bag_messages(out)
    for m in msgs["/scan"]:
        assert m.range_min == 0.0 and m.range_max == math.inf
        assert m.time_increment == pytest.approx(0.05 / 1024) and m.scan_time == pytest.approx(0.1, rel=1e-6)


def test_a_scan_that_does_not_fit_the_record_is_assumed_not_mislabelled(tmp_path: Path) -> None:
    log, out = tmp_path / "log.mcap", tmp_path / "bag"
    scanner_log(log, [(0, five_beams(beams=682))])
    result = export_rosbag2(log, out)
    assert result.scan_info == {"assumed": N} and len(result.warnings) == 1
    assert "does not fit" in result.warnings[0]
    _, msgs = bag_messages(out)
    # no cycle in this log: no beam time (0, unknown); the scan time measured from the stamps
    assert all(m.range_max == math.inf and m.time_increment == 0.0 for m in msgs["/scan"])
    assert all(m.scan_time == pytest.approx(0.1, rel=1e-6) for m in msgs["/scan"])


def test_a_malformed_scanner_record_is_counted(tmp_path: Path) -> None:
    log, out = tmp_path / "log.mcap", tmp_path / "bag"
    scanner_log(log, [(0, five_beams()), (10, five_beams(scan_time_s="fast"))])
    result = export_rosbag2(log, out)
    assert result.read.bad_messages == 1 and "scan_time_s" in result.read.bad[0]
    # after the bad record the older one no longer holds: those scans are assumed (and said so)
    assert result.scan_info == {"recorded": 10, "assumed": N - 10} and len(result.warnings) == 1
    assert "is malformed" in result.warnings[0]


def write_urg_bag(path: Path, n: int = 12) -> None:
    """A ROS 2 bag of a URG-04LX-class scanner (``URG``) standing in a 4 m x 3 m room."""
    from rosbags.rosbag2 import Writer

    ts = get_typestore(Stores.ROS2_HUMBLE)
    t = ts.types
    b = URG["angle_min_rad"] + URG["angle_increment_rad"] * np.arange(URG["beams"])
    room = np.minimum(2.0 / np.maximum(np.abs(np.cos(b)), 1e-3), 1.5 / np.maximum(np.abs(np.sin(b)), 1e-3))
    with Writer(path, version=8) as w:
        c = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=ts)
        for i in range(n):
            t_ns = int(T0 * 1e9) + i * 100_000_000
            hdr = t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](
                sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id="laser")
            msg = t["sensor_msgs/msg/LaserScan"](
                header=hdr, angle_min=URG["angle_min_rad"], angle_max=URG["angle_max_rad"],
                angle_increment=URG["angle_increment_rad"], time_increment=URG["time_increment_s"],
                scan_time=URG["scan_time_s"], range_min=URG["range_min_m"], range_max=URG["range_max_m"],
                ranges=room.astype(np.float32), intensities=np.zeros(0, np.float32))
            w.write(c, t_ns, ts.serialize_cdr(msg, "sensor_msgs/msg/LaserScan"))


def assert_laser_fields(msgs: list[Any], want: dict[str, Any]) -> None:
    assert msgs
    for m in msgs:
        assert len(m.ranges) == want["beams"]
        got = (m.angle_min, m.angle_max, m.angle_increment, m.time_increment, m.scan_time, m.range_min, m.range_max)
        keys = ("angle_min_rad", "angle_max_rad", "angle_increment_rad", "time_increment_s", "scan_time_s",
                "range_min_m", "range_max_m")
        assert got == pytest.approx(tuple(want[k] for k in keys), rel=1e-6, abs=1e-6)


def test_round_trip_of_a_urg04lx_bag_through_replay_log_export_and_replay(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``replay BAG --log`` -> ``export --rosbag2`` -> ``replay``: the exported scans have the source's 5.6 m,
    10 Hz, 682-beam values, and so does what the second replay reads."""
    from app.cli import main

    src, log, out = tmp_path / "urg", tmp_path / "urg.mcap", tmp_path / "urg_out"
    write_urg_bag(src)
    assert main(["replay", str(src), "--scan", "/scan", "--log", str(log), "--json"]) == 0
    capsys.readouterr()
    infos = [m.data for m in lm_read(log) if m.topic == "/vipsm/scanner"]
    assert len(infos) == 1 and infos[0]["range_max_m"] == pytest.approx(5.6)
    result = export_rosbag2(log, out)
    assert result.scan_info == {"recorded": 12} and not result.warnings
    assert_laser_fields(bag_messages(out)[1]["/scan"], URG)
    assert main(["replay", str(out), "--scan", "/scan", "--json"]) == 0
    sensor = json.loads(capsys.readouterr().out)["bag"]["sensor"]
    assert sensor["beams"] == 682 and sensor["range_max_m"] == pytest.approx(5.6)
    assert sensor["scan_period_s"] == pytest.approx(0.1) and sensor["range_min_m"] == pytest.approx(0.02)


def test_round_trip_of_a_real_768_beam_hokuyo_bag(shared_data: Path, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """A real 7.5 Hz, 768-beam, 0.03-11 m Hokuyo recording (leg_tracker's positive_1.bag): every exported
    scan carries the bag's own LaserScan fields."""
    from rosbags.highlevel import AnyReader

    from app.cli import main

    bag = shared_data / "real_people_laser" / "positive_1.bag"
    log, out = tmp_path / "real.mcap", tmp_path / "real_out"
    assert main(["replay", str(bag), "--scan", "right_scan", "--max-scans", "10", "--log", str(log), "--json"]) == 0
    capsys.readouterr()
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS1_NOETIC)) as r:
        conn = [c for c in r.connections if c.topic == "right_scan"]
        first = r.deserialize(next(r.messages(connections=conn))[2], conn[0].msgtype)
    want = {"beams": len(first.ranges), "angle_min_rad": first.angle_min,
            "angle_increment_rad": first.angle_increment, "time_increment_s": first.time_increment,
            "scan_time_s": first.scan_time, "range_min_m": first.range_min, "range_max_m": first.range_max}
    want["angle_max_rad"] = first.angle_min + first.angle_increment * (want["beams"] - 1)
    assert want["beams"] == 768 and want["scan_time_s"] == pytest.approx(1 / 7.5) and want["range_max_m"] == 11.0
    result = export_rosbag2(log, out)
    assert result.scan_info == {"recorded": 10}
    assert_laser_fields(bag_messages(out)[1]["/scan"], want)


def lm_read(path: Path) -> list[Any]:
    from app.logread import read_log

    return list(read_log(path))


class _SwitchingScanner:
    """A scanner port on the simulated clock: a URG-04LX-class scanner (``URG``, its PP limits on every
    sample, as :class:`app.devices.ScannerAdapter` gives them) for the first ``switch_at`` scans, then,
    as after a reconnect to another device, a UTM-30LX (1081 beams, 25 ms, 0.023-60 m)."""

    def __init__(self, clock: Any, switch_at: int) -> None:
        self.clock, self.switch_at, self.seq = clock, switch_at, 0
        self.next_s = clock.now_s + URG["scan_time_s"]

    def _geometry(self) -> tuple[np.ndarray, float, tuple[float, float], float]:
        if self.seq < self.switch_at:
            b = URG["angle_min_rad"] + URG["angle_increment_rad"] * np.arange(URG["beams"])
            return b, URG["time_increment_s"], (URG["range_min_m"], URG["range_max_m"]), URG["scan_time_s"]
        return -0.75 * math.pi + 2 * math.pi / 1440 * np.arange(1081), 0.025 / 1440, (0.023, 60.0), 0.025

    def state(self) -> str:
        return "ok"

    def wait_scan(self, timeout_s: float) -> bool:
        self.clock.now_s = max(self.clock.now_s, min(self.next_s, self.clock.now_s + timeout_s))
        return self.next_s <= self.clock.now_s

    def poll(self) -> list[Any]:
        from app.daemon import ScanSample
        from vipsm.types import Scan

        out = []
        while self.next_s <= self.clock.now_s:
            b, dt, limits, period = self._geometry()
            ranges = np.minimum(2.0 / np.maximum(np.abs(np.cos(b)), 1e-3), 1.5 / np.maximum(np.abs(np.sin(b)), 1e-3))
            out.append(ScanSample(Scan(ranges, b, self.next_s, self.seq, dt), range_limits_m=limits))
            self.seq += 1
            self.next_s += period
        return out

    def counters(self) -> dict[str, int]:
        return {}

    def close(self) -> None:
        pass


class _LiveViewStub:
    """What the control loop uses of :class:`app.liveview.LiveView`: its latched messages are kept."""

    state = "ok"

    def __init__(self) -> None:
        self.latched: dict[str, Any] = {}
        self.on_event: Any = None

    def latch(self, topic: str, t_wall_s: float, payload: Any) -> None:
        self.latched[topic] = payload

    def stop(self, timeout_s: float = 1.5) -> None:
        pass


def test_the_daemon_logs_its_scanners_own_values_and_a_changed_scanner(tmp_path: Path) -> None:
    """The control loop writes /vipsm/scanner from the driver's samples (PP limits, beam timing) before the
    first scan and again when another scanner answers; the export gives each scan its own scanner's values."""
    import threading

    from app.daemon import ControlLoop
    from app.fieldlog import FieldLog
    from tests.app.loop_fakes import FakeBase, SimClock
    from vipsm.estimator import Estimator

    clock = SimClock()
    base = Config()
    config = dataclasses.replace(base, loop=dataclasses.replace(base.loop, trigger="scan", period_s=0.1),
                                 status=dataclasses.replace(base.status, enabled=False))
    log = FieldLog(str(tmp_path / "run.mcap"), fsync=False).start()
    scanner, live = _SwitchingScanner(clock, switch_at=8), _LiveViewStub()
    loop = ControlLoop(config, scanner=scanner, base=FakeBase(clock), camera=None, live_view=live,
                       estimator=Estimator(plain_psm=True), field_log=log, clock=clock, wall_clock=lambda: 1.7e9)
    loop.run(threading.Event(), duration_s=1.2)
    log.close()
    assert log.stats.dropped == 0 and log.stats.bad_messages == 0
    infos = [m.data for m in lm_read(Path(log.path)) if m.topic == "/vipsm/scanner"]
    assert [i["beams"] for i in infos] == [682, 1081]
    assert live.latched["/vipsm/scanner"] == infos[-1]  # a viewer connecting later gets the scanner in force
    result = export_rosbag2(log.path, tmp_path / "bag")
    assert result.scan_info["assumed"] == 0 and not result.warnings
    scans = bag_messages(tmp_path / "bag")[1]["/scan"]
    urg = [m for m in scans if len(m.ranges) == 682]
    utm = [m for m in scans if len(m.ranges) == 1081]
    assert len(urg) == 8 and len(utm) >= 4 and len(urg) + len(utm) == len(scans)
    assert_laser_fields(urg, URG)
    for m in utm:
        assert (m.range_min, m.range_max, m.scan_time) == pytest.approx((0.023, 60.0, 0.025))
        assert m.time_increment == pytest.approx(0.025 / 1440)
