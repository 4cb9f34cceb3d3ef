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
