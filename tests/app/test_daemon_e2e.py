"""The daemon end to end: `sim` through the real bytes, signals, replay, unplug/replug, Modbus.

These run the real loop against the byte-level fakes on the wall clock, so every assertion is a
property that holds however slow or busy the machine is (issue 31): the loop's own accounting, the log
against the daemon's counters; never a count of cycles or messages a real-time run "should" reach,
never a latency bound (speed belongs in ``bench``). The accuracy targets are judged only when the
simulated world, itself a process on this machine, kept real time (it says how many scans it sent late).
Waits are bounded generously: they end a hung run, they do not measure one.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import pytest
from mcap.reader import make_reader
from pymodbus.client import ModbusTcpClient

from app.config import Config
from app.devices import build_loop
from app.fieldlog import LogReadResult, read_log
from hil_fakes.pioneer import FakePioneer
from hil_fakes.transport import DeviceServer, PtyEndpoint
from hil_fakes.utm30lx import Utm30lxModel
from tests.machine_lock import MachineLock

SIM_S = 12.0


def run_cli(*args: str, timeout_s: float = 240, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "app", *args], capture_output=True, text=True, timeout=timeout_s,
                          cwd=cwd)


@pytest.fixture(scope="module")
def sim_run(tmp_path_factory: pytest.TempPathFactory, machine_lock: MachineLock) -> tuple[dict, Path]:
    log = tmp_path_factory.mktemp("sim") / "run.mcap"
    # no status.port given: sim listens on any free port (a second run at once does not clash); the
    # machine to itself: the simulated world must keep real time for the targets to mean anything
    with machine_lock.exclusive():
        proc = run_cli("sim", "--scenario", "2", "--duration", str(SIM_S), "--json", "--no-progress",
                       "--log", str(log))
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout), log


def test_sim_summary_has_the_interface_fields(sim_run: tuple[dict, Path]) -> None:
    summary, log = sim_run
    for key in ("cycles", "deadline_misses", "loop_jitter_p99_ms", "obstacle_err_mean_m", "pose_err_final_m",
                "log_path"):
        assert key in summary
    assert summary["log_path"] == str(log)
    # every period of the run was either a cycle or counted as skipped (a busy machine skips some)
    assert summary["cycles"] > 0
    assert summary["cycles"] + summary["skipped_periods"] >= SIM_S / 0.1 - 1
    assert 0 < summary["status_server"]["port"] != 5020
    assert summary["log_dropped"] == 0 and summary["log_error"] is None
    # bytes and frames per device, from both sides
    assert summary["devices"]["scanner"]["frames"] > 0 and summary["devices"]["camera"]["frames"] > 0
    assert summary["fakes"]["scanner"]["bytes_out"] > 0 and summary["fakes"]["robot"]["bytes_in"] > 0
    scanner = summary["fakes"]["scanner"]
    assert scanner["scans_sent"] > 0 and scanner["scans_late"] >= 0


def test_sim_meets_the_targets_when_the_simulated_devices_kept_real_time(sim_run: tuple[dict, Path]) -> None:
    """The evaluation's targets (issue 6), here through the bytes and the real-time loop. The simulated
    world is a process on this machine: on a shared machine it can be starved of CPU, and then its
    scanner sends scans late or skips them, which no real UTM-30LX does. The targets are judged when
    it kept real time; the estimator's accuracy on a simulated clock is judged in ``eval`` always."""
    summary, _ = sim_run
    scanner = summary["fakes"]["scanner"]
    late, sent = scanner["scans_late"], scanner["scans_sent"]
    if late > 0.2 * (late + sent):  # alone on an idle machine 0-5 %, starved 37-68 % (docs/simulation.md)
        pytest.skip(f"the simulated world fell behind real time: {late} of {late + sent} scans late or skipped")
    assert summary["obstacle_err_mean_m"] <= 0.10
    assert summary["obstacle_err_std_m"] <= 0.08
    assert summary["pose_err_final_m"] <= 0.05
    assert summary["heading_err_final_deg"] <= 1.0
    assert summary["obstacle_detected_fraction"] >= 0.85
    assert summary["velocity_err_mean_mps"] <= 0.05


def test_sim_log_has_every_channel_at_its_rate(sim_run: tuple[dict, Path]) -> None:
    summary, log = sim_run
    result = LogReadResult()
    counts = Counter(m.topic for m in read_log(log, result))
    assert not result.truncated
    cycles = summary["cycles"]
    estimates = summary["estimates"]
    # every sample the daemon received is in the log (however many a busy machine let through)
    assert counts["/scan"] == summary["scans"] > 0
    assert counts["/odom"] == summary["odometry_samples"] > 0
    assert counts["/camera/image"] == summary["frames"] > 0
    assert counts["/diagnostics"] == cycles
    for topic in ("/pose", "/obstacles", "/vipsm/cycle", "/truth"):
        assert counts[topic] >= estimates - 1, topic
    assert counts["/vipsm/config"] == 1 and counts["/log"] >= 1
    with open(log, "rb") as f:
        summary_rec = make_reader(f).get_summary()
    assert summary_rec is not None  # closed cleanly: indexed


def test_replay_of_the_sim_log_equals_live(sim_run: tuple[dict, Path]) -> None:
    summary, log = sim_run
    proc = run_cli("replay", str(log), "--json")
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout)
    assert rep["cycles"] == summary["estimates"]
    assert rep["identical_to_recorded"] == rep["cycles"]
    assert rep["obstacle_err_mean_m"] == pytest.approx(summary["obstacle_err_mean_m"], abs=1e-4)


def _start_sim(log: Path) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "app", "sim", "--scenario", "1", "--duration", "120", "--json", "--no-progress",
         "--log", str(log), "--set", "status.port=0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )


def _wait_for_cycles(log: Path, proc: subprocess.Popen[str], n: int, timeout_s: float = 600) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
        if log.exists():
            got = sum(1 for m in read_log(log, LogReadResult()) if m.topic == "/diagnostics")
            if got >= n:
                return
        time.sleep(0.5)
    raise AssertionError("the daemon did not start cycling")


def test_sigterm_stops_cleanly_with_a_complete_log(tmp_path: Path) -> None:
    log = tmp_path / "term.mcap"
    proc = _start_sim(log)
    _wait_for_cycles(log, proc, 20)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    summary = json.loads(out)
    assert summary["cycles"] >= 20
    result = LogReadResult()
    msgs = list(read_log(log, result))
    assert not result.truncated
    assert any(m.topic == "/vipsm/cycle" for m in msgs)
    with open(log, "rb") as f:
        assert make_reader(f).get_summary() is not None


def test_sigkill_leaves_a_readable_log_that_keeps_everything_flushed_before(tmp_path: Path) -> None:
    """The log is flushed every log.flush_s (on a simulated clock in test_fieldlog.py); here: SIGKILL
    loses nothing that was flushed, and what is left reads back. (How much a kill loses depends on how
    far the writer got, which a busy machine slows: no bound on seconds here.)"""
    log = tmp_path / "kill.mcap"
    proc = _start_sim(log)
    _wait_for_cycles(log, proc, 20)
    flushed = [m.log_time_ns for m in read_log(log, LogReadResult()) if m.topic == "/diagnostics"]
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    result = LogReadResult()
    msgs = list(read_log(log, result))
    diag = [m.log_time_ns for m in msgs if m.topic == "/diagnostics"]
    assert len(flushed) >= 20 and diag[: len(flushed)] == flushed


# ---------------------------------------------------------------------------------------------
# in-process rig: fakes on ptys, the loop in a thread


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclasses.dataclass
class Rig:
    scanner: DeviceServer
    robot: DeviceServer
    robot_model: FakePioneer
    config: Config


@pytest.fixture
def rig(tmp_path: Path) -> Rig:
    scanner = DeviceServer(Utm30lxModel(), PtyEndpoint(str(tmp_path / "hokuyo"))).start()
    robot_model = FakePioneer()
    robot = DeviceServer(robot_model, PtyEndpoint(str(tmp_path / "pioneer"))).start()
    cfg = Config()
    cfg = dataclasses.replace(
        cfg,
        devices=dataclasses.replace(cfg.devices, scanner_url=scanner.address, robot_url=robot.address, camera_url="",
                                    camera_http_url=""),
        status=dataclasses.replace(cfg.status, port=free_port(), allow_stop_coil=True),
        mission=dataclasses.replace(cfg.mission, mode="cruise", cruise_speed_mps=0.1),
        log=dataclasses.replace(cfg.log, path=str(tmp_path / "rig.mcap")),
    )
    yield Rig(scanner, robot, robot_model, cfg)
    for srv in (scanner, robot):
        srv.stop()


def run_loop_in_thread(loop, seconds: float) -> tuple[threading.Thread, threading.Event]:  # type: ignore[no-untyped-def]
    stop = threading.Event()
    t = threading.Thread(target=loop.run, args=(stop,), kwargs={"duration_s": seconds}, daemon=True)
    t.start()
    return t, stop


def wait_until(pred, timeout_s: float = 120.0) -> bool:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(0.05)
    return False


def test_unplugged_scanner_stops_the_base_and_is_used_again_after_replug(rig: Rig) -> None:
    loop = build_loop(rig.config)
    t, stop = run_loop_in_thread(loop, 60)
    try:
        assert wait_until(lambda: loop.mission_state == "moving")
        rig.scanner.faults.disconnect()  # the pty vanishes and comes back behind the same link
        assert wait_until(lambda: loop.mission_state == "device_stop")
        assert wait_until(lambda: rig.robot_model.setpoint[0] == 0.0)
        before = loop.stats.estimates
        assert wait_until(lambda: loop.mission_state == "moving" and loop.stats.estimates > before + 10)
        events = " | ".join(loop.stats.state_changes)
        assert "scanner: ok ->" in events and "-> ok" in events.split("scanner: ok ->", 1)[1]
        # no camera configured: plain PSM, flagged on every estimate
        assert loop.stats.plain_psm_cycles == loop.stats.estimates > 0
    finally:
        stop.set()
        t.join(10)
        loop.shutdown()


def test_modbus_registers_and_stop_coil_on_a_running_daemon(rig: Rig) -> None:
    loop = build_loop(rig.config)
    t, stop = run_loop_in_thread(loop, 60)
    client = ModbusTcpClient("127.0.0.1", port=rig.config.status.port, timeout=5)
    try:
        assert wait_until(lambda: loop.mission_state == "moving")
        assert client.connect()
        assert wait_until(lambda: client.read_input_registers(0, count=52, device_id=1).registers[1] == 1)
        regs = client.read_input_registers(0, count=52, device_id=1).registers
        assert regs[0] & 1 and regs[0] & 2  # scanner ok, base ok
        assert regs[48] == 2 and regs[49] == 2 and regs[50] == 0  # ok, ok, absent
        assert not client.write_coil(0, True, device_id=1).isError()
        assert wait_until(lambda: loop.mission_state == "coil_stop")
        assert wait_until(lambda: rig.robot_model.setpoint[0] == 0.0)
        assert wait_until(lambda: client.read_input_registers(0, count=2, device_id=1).registers[1] == 4)
        client.write_coil(0, False, device_id=1)
        assert wait_until(lambda: loop.mission_state == "moving")
    finally:
        client.close()
        stop.set()
        t.join(10)
        loop.shutdown()


def test_run_command_with_a_bad_config_value_names_the_key() -> None:
    proc = run_cli("run", "--set", "mission.mode=sprint", "--duration", "1")
    assert proc.returncode == 2
    assert "mission.mode" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_dump_config_is_loadable_toml(tmp_path: Path) -> None:
    proc = run_cli("dump-config")
    assert proc.returncode == 0
    path = tmp_path / "c.toml"
    path.write_text(proc.stdout)
    assert run_cli("dump-config", "--config", str(path)).stdout == proc.stdout


def test_replay_of_a_missing_or_corrupt_log_is_a_clean_error(tmp_path: Path) -> None:
    proc = run_cli("replay", str(tmp_path / "nope.mcap"))
    assert proc.returncode == 2 and "no such log" in proc.stderr
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(os.urandom(100))
    proc = run_cli("replay", str(bad))
    assert proc.returncode == 2 and "not an MCAP file" in proc.stderr


# ---------------------------------------------------------------------------------------------
# the log's conformance: official schemas, complete custom schemas, transforms, old logs


def test_sim_log_conforms_to_the_official_and_its_own_schemas(sim_run: tuple[dict, Path]) -> None:
    import foxglove
    import jsonschema
    from mcap.records import Schema

    from app.logread import _protobuf_class, proto_to_dict

    _, log = sim_run
    checked: Counter[str] = Counter()
    with open(log, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        assert reader.get_summary() is not None
        for schema, channel, message in reader.iter_messages():
            if schema.encoding == "protobuf":
                official = getattr(foxglove.messages, schema.name.removeprefix("foxglove.")).get_schema()
                assert schema.data == official.data, schema.name
                cls = _protobuf_class(Schema(id=0, name=official.name, encoding="protobuf", data=official.data))
                assert proto_to_dict(cls.FromString(message.data)), channel.topic
            else:
                assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
                jsonschema.validate(json.loads(message.data), json.loads(schema.data))
            checked[schema.name] += 1
    assert {"foxglove.LaserScan", "foxglove.PoseInFrame", "foxglove.FrameTransforms", "foxglove.CompressedImage",
            "foxglove.SceneUpdate", "vipsm.Cycle", "vipsm.LoopDiagnostics", "vipsm.GroundTruth",
            "vipsm.Config", "vipsm.ScannerInfo"} <= set(checked)


def test_sim_transforms_chain_odom_to_the_sensors_and_the_world(sim_run: tuple[dict, Path]) -> None:
    _, log = sim_run
    tfs = [m.data for m in read_log(log) if m.topic == "/tf"]
    assert tfs
    edges = {(t["parent_frame_id"], t["child_frame_id"]) for t in tfs[-1]["transforms"]}
    assert edges == {("odom", "base_link"), ("base_link", "laser"), ("base_link", "camera"), ("world", "odom"),
                     ("world", "truth/base_link")}
    scans = [m.data for m in read_log(log) if m.topic == "/scan"]
    assert scans[0]["frame_id"] == "laser"
    poses = [m.data for m in read_log(log) if m.topic == "/pose"]
    last_pose = poses[-1]["pose"]["position"]
    odom_base = next(t for t in tfs[-1]["transforms"] if t["child_frame_id"] == "base_link")
    assert odom_base["translation"]["x"] == pytest.approx(last_pose["x"])
    assert odom_base["translation"]["y"] == pytest.approx(last_pose["y"])


def _as_version_1(src: Path, dst: Path) -> None:
    """The same run as the field log's first layout wrote it: JSON everywhere, frames matched by seq."""
    import base64

    from mcap.writer import Writer

    msgs = list(read_log(src))
    seq_by_image_time = {m.data["frame"]["image_log_time_ns"]: m.data["frame"]["seq"] for m in msgs
                         if m.topic == "/vipsm/cycle" and m.data["frame"] is not None}
    with open(dst, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("vipsm.Any", "jsonschema", b"{}")
        channels: dict[str, int] = {}
        for m in msgs:
            data = dict(m.data)
            if m.topic == "/camera/image":
                if m.log_time_ns not in seq_by_image_time:
                    continue
                data = {"seq": seq_by_image_time[m.log_time_ns], "format": "jpeg",
                        "data": base64.b64encode(m.data["data"]).decode()}
            elif m.topic == "/vipsm/cycle":
                if data["frame"] is not None:
                    data["frame"] = {k: v for k, v in data["frame"].items()
                                     if k not in ("image_log_time_ns", "distortion")}
            elif m.topic == "/vipsm/config":
                data.pop("log_version")
            elif m.topic not in ("/truth",):
                continue
            if m.topic not in channels:
                channels[m.topic] = w.register_channel(m.topic, "json", sid)
            w.add_message(channels[m.topic], log_time=m.log_time_ns, publish_time=m.log_time_ns,
                          data=json.dumps(data).encode())
        w.finish()


def test_a_log_in_the_first_layout_still_replays_identically(sim_run: tuple[dict, Path], tmp_path: Path) -> None:
    _, log = sim_run
    old = tmp_path / "v1.mcap"
    _as_version_1(log, old)
    proc = run_cli("replay", str(old), "--json")
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["log_version"] == 1 and out["bad_messages"] == 0
    assert out["cycles"] > 0 and out["identical_to_recorded"] == out["cycles"]


def test_rosbag2_export_reads_back_with_types_counts_stamps_and_frames(sim_run: tuple[dict, Path],
                                                                       tmp_path: Path) -> None:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    summary, log = sim_run
    out = tmp_path / "bag"
    proc = run_cli("export", str(log), "--rosbag2", str(out), "--json")
    assert proc.returncode == 0, proc.stderr
    counts = json.loads(proc.stdout)["messages"]
    src = Counter(m.topic for m in read_log(log))
    assert counts["/scan"] == src["/scan"] and counts["/odom"] == src["/odom"]
    assert counts["/camera/image/compressed"] == src["/camera/image"] and counts["/tf"] == src["/tf"]
    assert counts["/vipsm/pose"] == counts["/vipsm/obstacles"] == src["/vipsm/cycle"]
    assert counts["/tf_static"] == 1
    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Reader(out) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types == {"/scan": "sensor_msgs/msg/LaserScan", "/odom": "nav_msgs/msg/Odometry",
                         "/vipsm/pose": "nav_msgs/msg/Odometry",
                         "/camera/image/compressed": "sensor_msgs/msg/CompressedImage",
                         "/vipsm/obstacles": "visualization_msgs/msg/MarkerArray",
                         "/tf": "tf2_msgs/msg/TFMessage", "/tf_static": "tf2_msgs/msg/TFMessage"}
        seen: Counter[str] = Counter()
        for conn, bag_ns, raw in reader.messages():
            msg = ts.deserialize_cdr(raw, conn.msgtype)
            seen[conn.topic] += 1
            if conn.topic == "/scan":
                assert msg.header.frame_id == "laser" and len(msg.ranges) == 1081
                stamp_ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
                assert abs(stamp_ns - bag_ns) < 1000
            elif conn.topic == "/vipsm/pose":
                assert msg.header.frame_id == "odom" and msg.child_frame_id == "base_link"
                assert msg.pose.covariance[0] >= 0.0
            elif conn.topic == "/tf_static":
                assert [(t.header.frame_id, t.child_frame_id) for t in msg.transforms] == [("base_link", "laser")]
            elif conn.topic == "/tf":
                assert ("odom", "base_link") in {(t.header.frame_id, t.child_frame_id) for t in msg.transforms}
        assert dict(seen) == counts
        tf_static = next(c for c in reader.connections if c.topic == "/tf_static")
        assert "transient_local" in str(tf_static.ext.offered_qos_profiles).lower()


def test_rosbag2_export_refuses_an_existing_folder(sim_run: tuple[dict, Path], tmp_path: Path) -> None:
    _, log = sim_run
    proc = run_cli("export", str(log), "--rosbag2", str(tmp_path))
    assert proc.returncode == 2 and "exists" in proc.stderr and "Traceback" not in proc.stderr


def test_a_killed_sims_folder_is_removed_by_the_next_sim(tmp_path: Path) -> None:
    from app.sim import OWNER_FILE, SIM_DIR_PREFIX, remove_stale_sim_dirs

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f"{SIM_DIR_PREFIX}old"
    stale.mkdir()
    (stale / OWNER_FILE).write_text(str(dead.pid))
    alive = tmp_path / f"{SIM_DIR_PREFIX}running"
    alive.mkdir()
    (alive / OWNER_FILE).write_text(str(os.getpid()))
    foreign = tmp_path / f"{SIM_DIR_PREFIX}no-owner-file"
    foreign.mkdir()
    assert remove_stale_sim_dirs(str(tmp_path)) == [str(stale)]
    assert not stale.exists() and alive.exists() and foreign.exists()


def test_replay_plots_write_every_figure_for_both_methods(sim_run: tuple[dict, Path], tmp_path: Path) -> None:
    import cv2

    _, log = sim_run
    out = tmp_path / "plots"
    proc = run_cli("replay", str(log), "--json", "--plots", str(out), "--svg")
    assert proc.returncode == 0, proc.stderr
    written = sorted(Path(p).name for p in json.loads(proc.stdout)["plots"])
    stems = ["errors_run", "fig8_map_run", "fig9_paths_run"]
    assert written == sorted([f"{s}.png" for s in stems] + [f"{s}.svg" for s in stems])
    sizes = {p.stem: cv2.imread(str(p)).shape[:2] for p in out.glob("*.png")}
    assert sizes == {"fig8_map_run": (1080, 2520), "fig9_paths_run": (750, 1950), "errors_run": (1125, 1200)}
    assert all(p.stat().st_size > 20_000 for p in out.iterdir())


def test_sim_summary_starts_with_the_headline_figures_and_their_targets(sim_run: tuple[dict, Path]) -> None:
    summary, _ = sim_run
    assert list(summary)[0] == "headline"
    head = summary["headline"]
    assert list(head) == ["obstacle_err_mean_m", "obstacle_detected_fraction", "false_tracks_per_min",
                          "pose_err_final_m", "deadline_misses"]
    assert head["deadline_misses"] == {"value": summary["deadline_misses"], "target": "<= 0",
                                       "met": summary["deadline_misses"] == 0}
    assert head["pose_err_final_m"]["value"] == summary["pose_err_final_m"]
    assert head["pose_err_final_m"]["met"] == (summary["pose_err_final_m"] <= 0.05)


def test_sim_prints_a_short_summary_with_the_headline_last(tmp_path: Path) -> None:
    proc = run_cli("sim", "--scenario", "2", "--duration", "3", "--no-progress", "--log", str(tmp_path / "h.mcap"))
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) <= 15  # it fits on a screen; every figure with --verbose, or --json
    assert lines[0].startswith("devices: ")
    assert lines[1] == f"log:     {tmp_path / 'h.mcap'}   (vipsm-robot replay {tmp_path / 'h.mcap'})"
    assert lines[2].startswith("status:  Modbus TCP on 127.0.0.1:") and not lines[2].endswith(":5020")
    head = lines[-6:]  # the headline is what stays on the screen
    assert head[0].startswith("sim: scenario2_90deg") and "obstacle error, mean" in head[1]
    assert "final pose error" in head[4] and "deadline misses" in head[5]
    assert all(w in " ".join(head[1:]) for w in ("target", "met"))
    # the camera's first frame is waited for at start-up: it is never "stalled" before it came
    assert "camera: stalled" not in proc.stderr and "camera: connecting" not in proc.stderr


def test_sim_verbose_prints_every_figure_before_the_short_summary(tmp_path: Path) -> None:
    proc = run_cli("sim", "--scenario", "2", "--duration", "2", "--no-progress", "--verbose",
                   "--log", str(tmp_path / "v.mcap"))
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert out.index("fakes:") < out.index("devices: ") < out.index("sim: scenario2_90deg")
    assert out.splitlines()[-1].lstrip().startswith("deadline misses")


def test_the_first_run_on_a_slow_machine_still_locates_the_scenarios_obstacle(tmp_path: Path) -> None:
    """Issue 31: with an empty kernel cache (numba compiles every kernel) and the daemon's start
    delayed further (the test hook VIPSM_TEST_SLOW_START_S, a slow or busy machine simulated), the
    scenario waits for the daemon: its obstacle crosses while the daemon runs, not while it compiled.
    (Before the fix the world's clock ran from the child's start: with the run's length more than the compile,
    the cylinder had crossed before the first cycle and both obstacle figures were n/a.)"""
    # the cylinder enters the camera's view about 5 s into the scenario: 9 s leave it in view for 4 s; a start
    # delayed by the run's length more than the compile has the whole scenario over before the first cycle
    # when the world's clock runs from the child's start
    duration_s = 9
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "empty-kernel-cache"),
           "VIPSM_TEST_SLOW_START_S": str(duration_s)}
    log = tmp_path / "first.mcap"
    proc = subprocess.run([sys.executable, "-m", "app", "sim", "--scenario", "1", "--duration", str(duration_s),
                           "--json", "--no-progress", "--log", str(log)], capture_output=True, text=True, timeout=1800,
                          env=env)
    assert proc.returncode == 0, proc.stderr
    assert any((tmp_path / "empty-kernel-cache").rglob("*.nbi"))  # the kernels were compiled, not loaded
    s = json.loads(proc.stdout)
    in_view = [m.data for m in read_log(log) if m.topic == "/truth" and any(o[6] for o in m.data["obstacles"])]
    assert in_view  # the obstacle crossed the camera's view while the daemon ran its cycles
    assert s["headline"]["obstacle_err_mean_m"]["value"] is not None
    assert s["obstacle_detected_fraction"] > 0.0  # located (the targets are checked on sim_run)


def test_sim_runs_triggered_by_scans_and_reports_its_latencies(tmp_path: Path) -> None:
    proc = run_cli("sim", "--scenario", "2", "--duration", "4", "--json", "--no-progress", "--log",
                   str(tmp_path / "s40.mcap"), "--set", "status.port=0", "--set", 'loop.trigger="scan"',
                   "--set", "loop.period_s=0.025")
    assert proc.returncode == 0, proc.stderr
    s = json.loads(proc.stdout)
    # every scan gets its estimate on a machine that keeps up: checked on a simulated clock in
    # test_loop_trigger.py (on the wall clock a busy machine makes the loop skip scans)
    assert 0 < s["estimates"] <= s["scans"]
    assert 0.0 < s["scan_to_obstacles_ms_median"] <= s["scan_to_obstacles_ms_p99"]
    # the host's part (last byte read -> published) is part of the whole (last beam -> published)
    assert 0.0 < s["scan_received_to_obstacles_ms_median"] <= s["scan_received_to_obstacles_ms_p99"]
    assert s["scan_received_to_obstacles_ms_median"] < s["scan_to_obstacles_ms_median"]
    assert "scan matcher ready in" in proc.stderr


def test_the_lens_distortion_from_the_config_reaches_the_estimator_and_replays(tmp_path: Path) -> None:
    log = tmp_path / "dist.mcap"
    proc = run_cli("sim", "--scenario", "2", "--duration", "4", "--json", "--no-progress", "--log", str(log),
                   "--set", "status.port=0", "--set", "devices.camera_k1=-0.15", "--set", "devices.camera_k2=0.02")
    assert proc.returncode == 0, proc.stderr
    frames = [m.data["frame"] for m in read_log(log) if m.topic == "/vipsm/cycle" and m.data["frame"]]
    assert frames and all(f["distortion"] == [-0.15, 0.02, 0.0, 0.0] for f in frames)
    replay = run_cli("replay", str(log), "--json")
    assert replay.returncode == 0, replay.stderr
    out = json.loads(replay.stdout)
    assert out["identical_to_recorded"] == out["cycles"] > 0


def test_sim_without_a_field_log(tmp_path: Path) -> None:
    """``--log ""`` (log.path empty: no log) runs with the status server on; it used to crash at start."""
    proc = run_cli("sim", "--scenario", "2", "--duration", "2", "--json", "--no-progress", "--log", "",
                   "--set", "status.port=0", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    s = json.loads(proc.stdout)
    assert s["log_path"] in (None, "") and s["estimates"] > 0
    assert not list(tmp_path.glob("*.mcap"))
