"""SIGSTOP the daemon of a cruising `sim` for 3 s and measure how far the base drove blind: the
simulated world's true robot pose (``/truth``) at the last estimate before the stop and at the first
after SIGCONT (the fake Pioneer models the firmware watchdog: motion halts 2 s after the last
command, its FLASH default; the wheel odometry cannot show it, the SIPs of those seconds are lost).
The static furnished room, so no obstacle stops the robot. The measurement behind the README's
reliability section (issue 12 row 17).

Run from the repository root: ``python docs/scripts/measure_sigstop_blind_drive.py [RUNS]``."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, ROOT)

from app.fieldlog import LogReadResult, read_log  # noqa: E402

STOP_S = 3.0


def one_run(stop_after_s: float) -> dict[str, float]:
    log = os.path.join(tempfile.mkdtemp(), "stop.mcap")
    cmd = [sys.executable, "-m", "app", "sim", "--scenario", "static_clutter", "--duration", "16",
           "--mission", "cruise", "--no-progress", "--json", "--log", log, "--set", "status.port=0"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT)
    time.sleep(stop_after_s)
    stopped_wall_s = time.time()
    proc.send_signal(signal.SIGSTOP)
    time.sleep(STOP_S)
    proc.send_signal(signal.SIGCONT)
    proc.communicate(timeout=120)
    return {**blind_distance(log, stopped_wall_s), "robot_speed_mps": speed(log, stopped_wall_s)}


def speed(log: str, stopped_wall_s: float) -> float:
    truth = [(m.log_time_ns / 1e9, m.data["robot"]) for m in read_log(log, LogReadResult())
             if m.topic == "/truth" and stopped_wall_s - 1.0 <= m.log_time_ns / 1e9 < stopped_wall_s]
    (ta, a), (tb, b) = truth[0], truth[-1]
    return round(math.hypot(b[0] - a[0], b[1] - a[1]) / (tb - ta), 3)


def blind_distance(log: str, stopped_wall_s: float) -> dict[str, float]:
    truth = [(m.log_time_ns / 1e9, m.data["robot"]) for m in read_log(log, LogReadResult()) if m.topic == "/truth"]
    before = [r for t, r in truth if t < stopped_wall_s]
    after = [(t, r) for t, r in truth if t >= stopped_wall_s]
    (x0, y0, _), (t1, (x1, y1, _)) = before[-1], after[0]
    return {"blind_distance_m": round(math.hypot(x1 - x0, y1 - y0), 3),
            "first_estimate_after_s": round(t1 - stopped_wall_s, 2)}


if __name__ == "__main__":
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    results = [one_run(7.0 + 0.7 * k) for k in range(runs)]
    print(json.dumps(results))
