"""Start-up and exit (issue 31): the simulated world waits for the daemon, the camera is not called
stalled for a frame the start-up itself aged, a failed start leaves no empty log, ``sim`` picks a
free status port, and a bounded run whose device never opened says so in its exit code.

Every check here holds however slow the machine: simulated clocks, or properties of the order of
events, never a count of real-time cycles."""

from __future__ import annotations

import argparse
import dataclasses
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from app.cmd_daemon import EXIT_DEVICE_NEVER_OPENED, _sim_status_port
from app.config import Config, load_config
from app.daemon import ControlLoop, FrameSample
from app.devices import CameraAdapter
from app.simhost import SimHost
from vipsm.estimator import Estimator

# ---------------------------------------------------------------------------------------------
# the world waits for the daemon


def test_the_simulated_world_stands_still_until_the_daemon_says_start(tmp_path: Path) -> None:
    host = SimHost({"name": "scenario1_45deg", "crossing_deg": 45.0, "world": "realistic"}, tmp_path)
    try:
        now = time.monotonic()
        before = host.truth_line(now)
        # however long the daemon takes to get ready (a minute here), no scenario time passes
        assert host.truth_line(now + 60.0)["obstacles"] == before["obstacles"]
        assert host.truth_line(now + 60.0)["robot"] == before["robot"]
        t0 = host.start()
        assert host.truth_line(t0)["obstacles"] == before["obstacles"]  # the world's time 0
        later = host.truth_line(t0 + 10.0)  # the scenario runs from there: its cylinder has moved
        assert [o[:2] for o in later["obstacles"]] != [o[:2] for o in before["obstacles"]]
    finally:
        host.stop()


def test_the_simhost_child_starts_its_clock_on_start_and_ends_on_eof(tmp_path: Path) -> None:
    import json

    params = json.dumps({"name": "scenario2_90deg", "crossing_deg": 90.0, "world": "realistic"})
    child = subprocess.Popen([sys.executable, "-m", "app.simhost", params, str(tmp_path)], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None and child.stdin is not None
        addresses = json.loads(child.stdout.readline())
        assert set(addresses) == {"scanner", "robot", "camera", "camera_http"}
        child.stdin.write("start\n")
        child.stdin.flush()
        started = json.loads(child.stdout.readline())
        first_truth = json.loads(child.stdout.readline())
        assert first_truth["t"] >= started["started"]  # no truth before the world's clock started
        child.stdin.close()
        rest = child.stdout.read().splitlines()
        assert "final" in json.loads(rest[-1])
        assert child.wait(30) == 0
    finally:
        if child.poll() is None:
            child.kill()
            child.wait(5)


# ---------------------------------------------------------------------------------------------
# the camera at start-up, on a simulated clock


class _Camera:
    """A camera port whose frames arrive at the stamps the test says."""

    def __init__(self) -> None:
        self.pending: list[float] = []

    def state(self) -> str:
        return "ok"

    def latest(self) -> FrameSample | None:
        if not self.pending:
            return None
        stamp, self.pending = self.pending[-1], []
        return FrameSample(SimpleNamespace(stamp_s=stamp), b"")  # type: ignore[arg-type]

    def counters(self) -> dict[str, int]:
        return {}

    def close(self) -> None:
        pass


def _camera_loop(camera: _Camera) -> ControlLoop:
    config = dataclasses.replace(Config(), status=dataclasses.replace(Config().status, enabled=False))
    return ControlLoop(config, scanner=None, base=None, camera=camera, estimator=Estimator(config.estimator),
                       clock=lambda: 0.0, wall_clock=lambda: 0.0)


def _camera_events(loop: ControlLoop) -> list[str]:
    return [e for e in loop.stats.state_changes if e.startswith("camera:")]


def test_a_frame_aged_by_the_start_up_is_not_a_stalled_camera_but_a_real_stall_still_is() -> None:
    camera = _Camera()
    loop = _camera_loop(camera)
    max_age = loop.config.loop.max_frame_age_s
    t = 100.0
    camera.pending = [t - 1.0]  # the newest frame is a second old when the first cycle runs
    for _ in range(10):  # frames every 0.1 s from then on
        loop.step(t)
        t += 0.1
        camera.pending = [t - 0.01]
    assert _camera_events(loop) == ["camera: ok"]
    stop_s = t
    while t < stop_s + 2 * max_age:  # no frame any more: stalled after max_frame_age_s of the loop's time
        loop.step(t)
        t += 0.1
    assert _camera_events(loop) == ["camera: ok", "camera: ok -> stalled"]


def test_a_camera_that_never_sends_a_frame_is_stalled_after_the_frame_age_counted_from_the_first_cycle() -> None:
    camera = _Camera()
    loop = _camera_loop(camera)
    max_age = loop.config.loop.max_frame_age_s
    loop.step(50.0)
    assert _camera_events(loop) == ["camera: ok"]
    loop.step(50.0 + max_age + 0.05)
    assert _camera_events(loop) == ["camera: ok", "camera: ok -> stalled"]


def _silent_mjpeg_server() -> tuple[socket.socket, threading.Thread, list[socket.socket]]:
    """Answers any request with an MJPEG stream's header, then sends no frame."""
    srv = socket.create_server(("127.0.0.1", 0))
    conns: list[socket.socket] = []

    def serve() -> None:
        try:
            conn, _ = srv.accept()
        except OSError:
            return
        conns.append(conn)
        conn.recv(4096)
        conn.sendall(b"HTTP/1.0 200 OK\r\nContent-Type: multipart/x-mixed-replace;boundary=--myboundary\r\n\r\n")

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    return srv, t, conns


def test_the_camera_adapter_is_connecting_until_its_first_frame_came() -> None:
    srv, thread, conns = _silent_mjpeg_server()
    cfg = Config()
    url = f"http://127.0.0.1:{srv.getsockname()[1]}"
    adapter = CameraAdapter(dataclasses.replace(cfg, devices=dataclasses.replace(
        cfg.devices, camera_url="", camera_http_url=url)))
    try:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and not adapter.source.connected:
            time.sleep(0.02)
        assert adapter.source.connected  # the HTTP answer came ...
        assert adapter.state() == "connecting"  # ... but no frame yet: not "ok" (and so never "stalled")
    finally:
        adapter.close()
        srv.close()
        for c in conns:
            c.close()
        thread.join(5)


# ---------------------------------------------------------------------------------------------
# ports and logs at start


def test_sim_listens_on_any_free_status_port_unless_one_is_given(tmp_path: Path) -> None:
    def args(*sets: str, config: str | None = None) -> argparse.Namespace:
        return argparse.Namespace(set=list(sets), config=config)

    assert _sim_status_port(load_config(None, []), args()).status.port == 0
    given = _sim_status_port(load_config(None, ["status.port=5999"]), args("status.port=5999"))
    assert given.status.port == 5999
    toml = tmp_path / "c.toml"
    toml.write_text("[status]\nport = 6001\n")
    assert _sim_status_port(load_config(toml, []), args(config=str(toml))).status.port == 6001
    toml.write_text("[status]\nenabled = true\n")
    assert _sim_status_port(load_config(toml, []), args(config=str(toml))).status.port == 0


def _run_cli(*argv: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "app", *argv], capture_output=True, text=True, timeout=300,
                          cwd=cwd)


@pytest.fixture
def busy_port() -> object:
    with socket.create_server(("127.0.0.1", 0)) as s:
        yield s.getsockname()[1]


def test_a_sim_whose_status_port_is_taken_fails_naming_the_fix_and_leaves_no_log(tmp_path: Path,
                                                                                 busy_port: int) -> None:
    proc = _run_cli("sim", "--scenario", "2", "--duration", "2", "--no-progress", "--set",
                    f"status.port={busy_port}", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert f":{busy_port}" in proc.stderr and "another instance" in proc.stderr and "status.port" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not list(tmp_path.glob("*.mcap"))  # the default sim-<time>.mcap was never opened


def test_a_run_whose_live_port_is_taken_fails_naming_the_fix_and_leaves_no_log(tmp_path: Path,
                                                                               busy_port: int) -> None:
    proc = _run_cli("run", "--set", "devices.scanner_url=''", "--set", "devices.robot_url=''", "--set",
                    "devices.camera_url=''", "--set", "devices.camera_http_url=''", "--set", "status.port=0",
                    "--log", "run.mcap", "--live", str(busy_port), "--duration", "1", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert f"live view on 127.0.0.1:{busy_port} failed" in proc.stderr
    assert "another instance" in proc.stderr and "--live" in proc.stderr and "live.listen" in proc.stderr
    assert not list(tmp_path.glob("*.mcap"))


def test_a_bounded_run_whose_device_never_opened_exits_with_its_own_code(tmp_path: Path) -> None:
    proc = _run_cli("run", "--set", "devices.scanner_url='/dev/vipsm-nonexistent'", "--set", "devices.robot_url=''",
                    "--set", "devices.camera_url=''", "--set", "devices.camera_http_url=''", "--set",
                    "status.enabled=false", "--set", "devices.startup_wait_s=0.2", "--log", "", "--duration", "0.5",
                    "--json", cwd=tmp_path)
    assert proc.returncode == EXIT_DEVICE_NEVER_OPENED == 4, proc.stderr
    assert "the scanner never opened during the run (/dev/vipsm-nonexistent" in proc.stderr
    import json

    assert json.loads(proc.stdout)["devices_never_opened"] == ["scanner"]
