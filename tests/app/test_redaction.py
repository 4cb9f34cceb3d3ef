"""Secrets stay out of logs and printed lines (issue 32 row 3): the camera password is redacted in the
field log's ``/vipsm/config`` (and so in the live view, which serves the same channels), in every
state-change line (stderr, ``/log``, the summary's events) and in CLI error lines; field logs are
created 0640 whatever the umask. ``dump-config`` prints the configuration the user gave, in full."""

from __future__ import annotations

import dataclasses
import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from app.config import REDACTED, load_config, redact_text, redacted, redacted_config
from app.fieldlog import FieldLog, read_log

PASSWORD = "Sup3r-s3cret"
CAMERA = f"http://admin:{PASSWORD}@192.168.0.100"


@pytest.mark.parametrize("text, expected", [
    (CAMERA, "http://admin:***@192.168.0.100"),
    (f"http://admin:{PASSWORD}@cam:8080/path?q=1", "http://admin:***@cam:8080/path?q=1"),
    ("http://admin:p@ss@cam/", "http://admin:***@cam/"),  # an @ in the password: the host follows the last @
    (f"error at {CAMERA}/oneshotimage.jpg: refused", "error at http://admin:***@192.168.0.100/oneshotimage.jpg: "
                                                      "refused"),
    ("http://cam/cgi?user=a&password=zz&x=1", "http://cam/cgi?user=a&password=***&x=1"),
    ("https://host/api?access_token=abc", "https://host/api?access_token=***"),
    ("http://user@host/", "http://user@host/"),
    ("socket://127.0.0.1:10940", "socket://127.0.0.1:10940"),
    ("/dev/hokuyo", "/dev/hokuyo"),
])
def test_redact_text(text: str, expected: str) -> None:
    assert redact_text(text) == expected


def test_redacted_tree_hides_secret_keys_and_url_passwords() -> None:
    tree = {"devices": {"camera_http_url": CAMERA, "n": 3}, "ros2": {"api_token": "abc", "password": ""},
            "list": [CAMERA, 1.5]}
    out = redacted(tree)
    assert out["ros2"]["api_token"] == REDACTED and out["ros2"]["password"] == ""  # unset stays unset
    assert PASSWORD not in json.dumps(out) and out["devices"]["n"] == 3 and out["list"][1] == 1.5
    assert tree["devices"]["camera_http_url"] == CAMERA  # a copy: the running config keeps its password


def test_the_field_log_records_the_config_without_the_password(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    from app.daemon import ControlLoop
    from app.runtime import loop_summary
    from vipsm.estimator import Estimator

    class _Live:  # what the live view is handed to latch for viewers that connect later
        url, on_event = None, None

        def __init__(self) -> None:
            self.latched: list[tuple[str, dict]] = []

        def latch(self, topic: str, t_wall_s: float, payload: dict) -> None:
            self.latched.append((topic, payload))

        def summary(self) -> dict:
            return {}

    config = load_config(None, [f'devices.camera_http_url="{CAMERA}"', f'devices.camera_url="{CAMERA}"'])
    log = FieldLog(str(tmp_path / "run.mcap"), flush_s=0.05).start()
    live = _Live()
    loop = ControlLoop(config, scanner=None, base=None, camera=None, estimator=Estimator(), field_log=log,
                       live_view=live)
    loop.say("warning", f"camera: cannot open {CAMERA}/image: timed out", 0.0)
    summary = loop_summary(loop)
    log.close()
    raw = Path(log.path).read_bytes()
    assert PASSWORD.encode() not in raw
    recorded = next(m.data for m in read_log(log.path) if m.topic == "/vipsm/config")
    assert recorded["devices"]["camera_http_url"] == "http://admin:***@192.168.0.100"
    assert recorded["devices"]["scanner_url"] == config.devices.scanner_url
    assert PASSWORD not in capsys.readouterr().err and PASSWORD not in json.dumps(summary["events"])
    assert config.devices.camera_http_url == CAMERA
    assert [t for t, _ in live.latched] == ["/vipsm/config"] and PASSWORD not in json.dumps(live.latched)


def test_log_files_are_not_world_readable_whatever_the_umask(tmp_path: Path) -> None:
    old = os.umask(0)
    try:
        log = FieldLog(str(tmp_path / "run.mcap"), flush_s=0.05).start()
        log.log("/diagnostics", 0.0, {"i": 1})
        log.close()
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(log.path).st_mode) == 0o640


def test_a_cli_error_line_redacts_the_password() -> None:
    proc = subprocess.run([sys.executable, "-m", "app", "dump-config", "--set", f'devices.camera_fps="{CAMERA}"'],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "camera_fps" in proc.stderr
    assert PASSWORD not in proc.stderr and "admin:***@" in proc.stderr


def test_dump_config_prints_the_configuration_the_user_gave() -> None:
    """The user's own file to edit: a redacted copy could not be loaded back."""
    proc = subprocess.run([sys.executable, "-m", "app", "dump-config", "--set", f'devices.camera_http_url="{CAMERA}"'],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and f'camera_http_url = "{CAMERA}"' in proc.stdout


def test_redacted_config_matches_the_config_schema() -> None:
    """What the log records still validates against /vipsm/config's JSON schema shape (same keys)."""
    from app.config import Config

    plain, red = json.loads(json.dumps(dataclasses.asdict(Config()))), redacted_config(Config())
    assert red == plain
