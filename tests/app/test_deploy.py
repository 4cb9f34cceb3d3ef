"""The systemd unit matches the README's Debian 12 deployment (issue 12, row 16): the daemon runs
from the venv under /opt, and its group can read the 0640 root:vipsm config."""

from __future__ import annotations

import configparser
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _service() -> configparser.SectionProxy:
    unit = configparser.ConfigParser(strict=False, interpolation=None)
    unit.read_string((ROOT / "app/deploy/vipsm-robot.service").read_text(encoding="utf-8"))
    return unit["Service"]


def test_exec_start_points_into_the_venv_the_readme_creates() -> None:
    exec_start = _service()["ExecStart"].split()
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert exec_start[0] == "/opt/vipsm-robot/bin/vipsm-robot"
    assert "python3 -m venv /opt/vipsm-robot" in readme
    assert "sudo pip install ." not in readme.replace("`sudo pip install .`", "")


def test_the_config_is_installed_private_and_readable_by_the_service_group() -> None:
    service = _service()
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "-m 640 -o root -g vipsm app/deploy/config.example.toml /etc/vipsm-robot/config.toml" in readme
    assert service["User"] == "vipsm" and service["Group"] == "vipsm"
    assert {"dialout", "plugdev"} <= set(service["SupplementaryGroups"].split())
