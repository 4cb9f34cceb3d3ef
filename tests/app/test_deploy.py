"""The systemd unit matches the README's Debian 12 deployment (issue 12, row 16): the daemon runs
from the venv under /opt, and its group can read the 0640 root:vipsm config."""

from __future__ import annotations

import configparser
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

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


# ---------------------------------------------------------------------------------------------
# the sandbox (issue 31): `systemd-analyze security` rated the unit 9.2-9.6 UNSAFE before


def _directives() -> dict[str, list[str]]:
    """Every ``[Service]`` directive with all its values (DeviceAllow= and SystemCallFilter= repeat)."""
    out: dict[str, list[str]] = {}
    section = ""
    for line in (ROOT / "app/deploy/vipsm-robot.service").read_text(encoding="utf-8").splitlines():
        line = line.strip()
        if line.startswith("[") and line.endswith("]"):
            section = line[1:-1]
        elif section == "Service" and line and not line.startswith("#"):
            key, _, value = line.partition("=")
            out.setdefault(key.strip(), []).append(value.strip())
    return out


def test_the_unit_keeps_its_sandbox() -> None:
    d = _directives()
    for key, value in {"NoNewPrivileges": "yes", "ProtectSystem": "strict", "ProtectHome": "yes", "PrivateTmp": "yes",
                       "DevicePolicy": "closed", "UMask": "0027", "CapabilityBoundingSet": "", "LockPersonality": "yes",
                       "RestrictRealtime": "yes", "RestrictSUIDSGID": "yes", "RestrictNamespaces": "yes",
                       "ProtectKernelTunables": "yes", "ProtectKernelModules": "yes", "ProtectKernelLogs": "yes",
                       "ProtectControlGroups": "yes", "ProtectClock": "yes", "SystemCallArchitectures": "native",
                       "IPAddressDeny": "any"}.items():
        assert d.get(key) == [value], key
    assert "@system-service" in d["SystemCallFilter"]
    assert set(d["RestrictAddressFamilies"][0].split()) == {"AF_UNIX", "AF_INET", "AF_INET6"}
    assert int(d["LimitNOFILE"][0]) >= 1024
    # numba's JIT maps its kernels writable, then executable (see the next test); PrivateUsers would
    # hide the dialout group the serial devices belong to
    assert "MemoryDenyWriteExecute" not in d and "PrivateUsers" not in d


def test_the_sandbox_leaves_the_log_folder_the_kernel_cache_and_the_three_devices_usable() -> None:
    d = _directives()
    example = (ROOT / "app/deploy/config.example.toml").read_text(encoding="utf-8")
    log_dir = re.search(r'^path = "(/var/log/[^/"]+)/', example, re.M)
    assert log_dir is not None and log_dir.group(1) == "/var/log/" + d["LogsDirectory"][0]
    assert d["WorkingDirectory"] == [log_dir.group(1)]
    assert d["Environment"] == ["NUMBA_CACHE_DIR=/var/cache/" + d["CacheDirectory"][0]]
    rules = (ROOT / "app/deploy/99-vipsm-robot.rules").read_text(encoding="utf-8")
    names = re.findall(r'SYMLINK\+="([^"]+)"', rules)
    assert sorted(names) == ["hokuyo", "pioneer", "ptzcam"]
    allowed = {v.split()[0]: v.split()[1] for v in d["DeviceAllow"]}
    assert all(allowed.get(f"/dev/{n}") == "rw" for n in names)
    # a replugged device gets a new minor number: its class is allowed (CDC-ACM scanner, USB-serial adapters)
    assert allowed.get("char-ttyACM") == "rw" and allowed.get("char-ttyUSB") == "rw"
    groups = set(d["SupplementaryGroups"][0].split())
    assert set(re.findall(r'GROUP="([^"]+)"', rules)) <= groups | {d["Group"][0]}


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="systemd-analyze is not installed")
def test_systemd_analyze_rates_the_unit_ok(tmp_path: Path) -> None:
    unit = tmp_path / "vipsm-robot.service"
    unit.write_text((ROOT / "app/deploy/vipsm-robot.service").read_text(encoding="utf-8"), encoding="utf-8")
    proc = subprocess.run(["systemd-analyze", "security", "--offline=true", str(unit)], capture_output=True,
                          text=True, timeout=60)
    found = re.search(r"Overall exposure level for vipsm-robot\.service: ([0-9.]+) (\w+)", proc.stdout + proc.stderr)
    if found is None:
        pytest.skip(f"systemd-analyze here cannot rate a unit offline: {proc.stderr.strip()[:200]}")
    assert float(found.group(1)) <= 2.0 and found.group(2) == "OK", proc.stdout
    checked = tmp_path / "check.service"  # the same unit, with a command that exists here
    checked.write_text(re.sub(r"^ExecStart=.*$", "ExecStart=/bin/true", unit.read_text(), flags=re.M))
    verify = subprocess.run(["systemd-analyze", "verify", str(checked)], capture_output=True, text=True, timeout=60)
    assert verify.returncode == 0 and not verify.stderr.strip(), verify.stderr


def test_numba_needs_writable_then_executable_memory_so_the_unit_cannot_deny_it() -> None:
    """Why MemoryDenyWriteExecute stays off: under the kernel's equivalent (prctl PR_SET_MDWE, Linux
    6.3+) the scan matcher's kernels cannot be loaded, even from a warm cache."""
    code = (
        "import ctypes, sys\n"
        "libc = ctypes.CDLL(None, use_errno=True)\n"
        "if libc.prctl(65, 1, 0, 0, 0) != 0: sys.exit(77)  # PR_SET_MDWE, PR_MDWE_REFUSE_EXEC_GAIN\n"
        "from vipsm.estimator import warm_up\n"
        "warm_up()\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, cwd=ROOT)
    if proc.returncode == 77:
        pytest.skip("this kernel has no PR_SET_MDWE (Linux < 6.3)")
    assert proc.returncode != 0 and "cannot allocate executable memory" in proc.stderr
