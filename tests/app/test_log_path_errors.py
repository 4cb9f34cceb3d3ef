"""issue 12 row 4: an unwritable or over-long log.path is the usual one-line error with exit 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.cli import main

NO_DEVICES = ["--set", "devices.scanner_url=''", "--set", "devices.robot_url=''", "--set", "devices.camera_url=''",
              "--set", "devices.camera_http_url=''", "--set", "status.enabled=false"]


@pytest.mark.parametrize("kind", ["unwritable", "too-long", "not-a-folder"])
def test_a_log_path_that_cannot_be_opened_is_a_one_line_error(kind: str, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    # (a missing folder is created; /proc refuses new folders even to root)
    path = {"unwritable": Path("/proc/vipsm-robot-test/x.mcap"), "too-long": tmp_path / ("x" * 300 + ".mcap"),
            "not-a-folder": blocker / "x.mcap"}[kind]
    code = main(["run", *NO_DEVICES, "--log", str(path), "--duration", "0.2"])
    err = capsys.readouterr().err
    assert code == 2 and "log.path" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_run_names_each_device_its_url_and_why_it_is_not_there(capsys: pytest.CaptureFixture[str]) -> None:
    """issue 12 row 13: a wrong device path is named on stderr, with the reason, from the start."""
    args = ["--set", "devices.scanner_url='/dev/vipsm-nosuch'", "--set", "devices.robot_url=''",
            "--set", "devices.camera_url=''", "--set", "devices.camera_http_url=''", "--set", "status.enabled=false",
            "--set", "log.path=''", "--set", "devices.startup_wait_s=0.5"]
    code = main(["run", *args, "--duration", "1.0"])
    err = capsys.readouterr().err
    assert code == 4  # a bounded run in which a configured device never opened (issue 31)
    assert "vipsm-robot run: error: the scanner never opened during the run (/dev/vipsm-nosuch" in err
    lines = [ln for ln in err.splitlines() if ln.startswith("vipsm-robot: ") and "scanner:" in ln]
    assert lines and "/dev/vipsm-nosuch" in lines[0]
    assert any("last error" in ln for ln in lines) or "connecting" in lines[0]
    assert "waiting up to 0.5 s for the devices to open (devices.startup_wait_s)" in err
