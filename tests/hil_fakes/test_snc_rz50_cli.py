"""`vipsm-robot fake camera` as a real process, driven by `vipsm-robot probe --camera` and `ptz`."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.cli import main

ROOT = Path(__file__).resolve().parents[2]


def _start_fake(*args: str) -> tuple[subprocess.Popen[str], dict[str, str]]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "app", "fake", "camera", *args],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    wanted = sum(a in ("--visca-pty", "--visca-tcp", "--http") for a in args)
    addresses: dict[str, str] = {}
    deadline = time.monotonic() + 30
    assert proc.stdout is not None
    while len(addresses) < wanted and time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        kind, _, addr = line.strip().partition(" ")
        addresses[kind] = addr
    if len(addresses) < wanted:
        proc.kill()
        raise AssertionError(f"fake camera did not start: {proc.stderr.read() if proc.stderr else ''}")
    return proc, addresses


@pytest.fixture
def fake(tmp_path: Path) -> Iterator[dict[str, str]]:
    proc, addrs = _start_fake("--visca-pty", "--link", str(tmp_path / "ptzcam"), "--visca-tcp", "127.0.0.1:0",
                              "--http", "127.0.0.1:0", "--user", "op", "--password", "pw")
    try:
        yield addrs
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0


def test_fake_prints_its_addresses(fake: dict[str, str], tmp_path: Path) -> None:
    assert fake["visca-pty"] == str(tmp_path / "ptzcam")
    assert fake["visca-tcp"].startswith("socket://127.0.0.1:")
    assert fake["http"].startswith("http://127.0.0.1:")


def test_probe_and_ptz_through_the_cli(fake: dict[str, str], capsys: pytest.CaptureFixture[str]) -> None:
    http = fake["http"].replace("http://", "http://op:pw@")
    assert main(["probe", "--camera", fake["visca-pty"], "--camera-http", http, "--json"]) == 0
    cam = json.loads(capsys.readouterr().out)["camera"]
    assert cam["version"]["vendor"] == "0x0020" and cam["camera_count"] == 1
    assert (cam["pan_deg"], cam["tilt_deg"], cam["zoom_position"]) == (0, 0, 0)
    assert cam["frame"]["width_px"] == 320 and cam["frame"]["height_px"] == 240 and cam["model"] == "SNC-RZ50N"

    assert main(["ptz", "--camera", fake["visca-tcp"], "--pan-deg", "30", "--tilt-deg", "-5", "--zoom", "0",
                 "--json"]) == 0
    moved = json.loads(capsys.readouterr().out)["camera"]
    assert moved["pan_deg"] == pytest.approx(30) and moved["tilt_deg"] == pytest.approx(-5)
    assert moved["pan_counts"] == -432 and moved["zoom_position"] == 0

    assert main(["ptz", "--camera", fake["visca-pty"], "--zoom-x", "2", "--json"]) == 0
    zoomed = json.loads(capsys.readouterr().out)["camera"]
    assert zoomed["pan_deg"] == pytest.approx(30) and zoomed["magnification"] == pytest.approx(2, rel=1e-3)


def test_ptz_refuses_out_of_range(fake: dict[str, str], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ptz", "--camera", fake["visca-tcp"], "--pan-deg", "200", "--json"]) == 2
    assert "outside" in capsys.readouterr().err


def test_to_vipsm_frame_decodes_and_adds_intrinsics(fake: dict[str, str]) -> None:
    from app.cmd_camera import to_vipsm_frame
    from drivers.ptz_cam import HttpConfig
    from drivers.ptz_cam.frames import fetch_oneshot

    frame = to_vipsm_frame(fetch_oneshot(HttpConfig(base_url=fake["http"], username="op", password="pw")))
    assert frame.image.shape == (240, 320, 3)
    assert frame.intrinsics.width_px == 320 and frame.intrinsics.cx_px == 160
    assert frame.intrinsics.fx_px == pytest.approx(160 / 0.5095254494944288)  # tan(27 deg)


def test_bench_reports_figures_without_judging_them() -> None:
    import argparse

    from app.cmd_camera import bench

    figures = bench(argparse.Namespace())
    assert figures["frames"] == 115
    for key in ("receive_ms_median", "receive_ms_p99", "decode_ms_median", "decode_ms_p99",
                "receive_decode_ms_median", "receive_decode_ms_p99"):
        assert figures[key] >= 0
    assert figures["receive_decode_ms_p99"] >= figures["receive_decode_ms_median"]
