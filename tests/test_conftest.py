"""tests/conftest.py's end-of-run note: a fresh clone (no ../shared/data) is told once, at the end,
how many tests skipped for the recorded data and how to point to it (issue 31); and the tests on real
devices kept on one worker when the suite runs on several."""

from __future__ import annotations

import os
import subprocess
import sys

from tests.conftest import REPO_ROOT


def test_the_run_ends_saying_how_many_tests_skipped_for_the_absent_data() -> None:
    env = {**os.environ, "VIPSM_SHARED_DATA": "/nonexistent/vipsm-shared-data"}
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "tests/drivers/hokuyo_scip/test_golden.py"], cwd=REPO_ROOT, env=env, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    skipped = sum(1 for ln in lines if ln.startswith("SKIPPED") and "/nonexistent/vipsm-shared-data" in ln)
    notes = [i for i, ln in enumerate(lines) if "skipped: the real recorded data is not at" in ln]
    assert skipped > 0 and len(notes) == 1  # once
    assert lines[notes[0]].startswith(f"{skipped} test(s) skipped: the real recorded data is not at "
                                      "/nonexistent/vipsm-shared-data")
    assert "VIPSM_SHARED_DATA" in lines[notes[0]]
    assert notes[0] == len(lines) - 2  # at the end: only pytest's count line after it



def _collected(marks: str) -> int:
    files = ["tests/drivers/p2os/test_hardware.py", "tests/drivers/hokuyo_scip/test_hardware.py",
             "tests/drivers/p2os/test_codec.py"]
    cmd = [sys.executable, "-m", "pytest", "-q", "--collect-only", "-p", "no:cacheprovider", "-m", marks, *files]
    proc = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode in (0, 5), proc.stdout + proc.stderr  # 5: none selected
    return sum(1 for ln in proc.stdout.splitlines() if "::" in ln)


def test_the_tests_on_real_devices_run_on_one_worker() -> None:
    """Every test marked ``hardware`` is in the xdist group "hardware" (``--dist loadgroup`` sends a group to one
    worker: two workers never open one serial device at once), and no other test is."""
    assert _collected("hardware") > 0
    assert _collected("hardware and not xdist_group") == 0
    assert _collected("xdist_group and not hardware") == 0
