"""SIGKILL a `sim` six times mid-run and print how much of the field log was lost (kill time minus
the last /diagnostics message): the measurement behind the README's log.flush_s figure.

Run from the repository root: ``python docs/scripts/measure_sigkill_loss.py``."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, ROOT)

from app.fieldlog import LogReadResult, read_log  # noqa: E402


def one_kill(after_s: float) -> float:
    log = os.path.join(tempfile.mkdtemp(), "kill.mcap")
    cmd = [sys.executable, "-m", "app", "sim", "--scenario", "2", "--no-progress", "--log", log,
           "--set", "status.port=0"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT)
    time.sleep(after_s)
    killed_wall_s = time.time()
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    diag = [m for m in read_log(log, LogReadResult()) if m.topic == "/diagnostics"]
    return killed_wall_s - diag[-1].log_time_ns / 1e9


if __name__ == "__main__":
    losses = [one_kill(6.0 + 0.37 * k) for k in range(6)]
    print("lost_s", sorted(round(x, 3) for x in losses), "max", round(max(losses), 3))
