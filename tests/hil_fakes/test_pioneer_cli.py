"""`vipsm-robot fake robot` in its own process, driven by `vipsm-robot probe` and `vipsm-robot drive`."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.cli import main

REPO = Path(__file__).resolve().parents[2]


def _start_fake(*args: str) -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "app", "fake", "robot", *args],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline().strip()
    if not line:
        proc.kill()
        raise AssertionError(f"fake printed nothing: {proc.stderr.read() if proc.stderr else ''}")
    return proc, line


def _stop(proc: subprocess.Popen[str]) -> None:
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=5)


@pytest.fixture(scope="module", params=["pty", "tcp"])
def fake_url(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    if request.param == "pty":
        link = tmp_path_factory.mktemp("robot") / "pioneer"
        proc, address = _start_fake("--pty", "--link", str(link), "--start-x-counts", "32700")
        assert address == str(link) and os.path.islink(link)
    else:
        proc, address = _start_fake("--tcp", "127.0.0.1:0", "--start-x-counts", "32700")
        assert address.startswith("socket://127.0.0.1:")
    try:
        yield address
    finally:
        _stop(proc)
    assert proc.returncode == 0


def test_probe_prints_identity_config_and_one_sample(fake_url: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["probe", "--robot", fake_url, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)["robot"]
    assert (out["name"], out["class"], out["subclass"]) == ("fakebot", "Pioneer", "p3dx")
    assert out["config"]["watchdog_ms"] == 2000 and out["config"]["sip_cycle_ms"] == 100
    assert out["odometry"]["x_m"] == 0.0 and len(out["odometry"]["sonars"]) == 16
    assert out["odometry"]["motors_enabled"] is False  # probe never enables the motors
    assert out["closed_cleanly"] is True


def test_drive_moves_stops_and_prints_final_odometry(fake_url: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["drive", "--robot", fake_url, "--v", "0.2", "--w", "0.0", "--seconds", "1.0", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["at_rest"] is True and out["closed_cleanly"] is True
    # 1 s at 0.2 m/s with 0.3 m/s^2 ramps at both ends: about 0.2 m, through the 15-bit X wrap
    assert 0.1 < out["final"]["x_m"] < 0.3
    assert abs(out["final"]["y_m"]) < 1e-3


def test_fake_stops_cleanly_on_sigterm(tmp_path: Path) -> None:
    link = tmp_path / "pioneer"
    proc, address = _start_fake("--pty", "--link", str(link))
    assert os.path.islink(link)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=10) == 0
    assert not os.path.lexists(link)  # the stable link is removed with the fake


def test_drive_refuses_unsafe_speeds(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["drive", "--robot", "socket://127.0.0.1:9", "--v", "2.0", "--seconds", "1"]) == 2
    assert "refusing" in capsys.readouterr().err


def test_probe_of_an_absent_robot_is_a_one_line_error(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["probe", "--robot", str(tmp_path / "no-such-tty"), "--json"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot open" in err
