"""``bench --only ros2``: the daemon bench's sim without and with ``--ros2``, a listener in another
process (``vipsm-robot ros2-listen``) reading every topic over loopback."""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from app import cmd_daemon, cmd_ros2
from app.ros2.publisher import TOPICS


def test_bench_runs_both_variants_and_the_listener_hears_every_topic(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cmd_daemon, "BENCH_SIM_S", 3.0)  # the bench runs 30 s each; the figures' shape is the test
    figures = cmd_ros2.bench(argparse.Namespace())
    without, with_ros2 = figures["without_ros2"], figures["with_ros2"]
    assert "--ros2" not in without["command"] and "--ros2" in with_ros2["command"]
    for run in (without, with_ros2):
        assert set(cmd_daemon.BENCH_KEYS) <= set(run) and run["estimates"] > 0
    assert with_ros2["ros2"]["state"] == "ok" and with_ros2["ros2"]["errors"] == 0
    heard = with_ros2["listener"]["topics"]
    for name, (ros_type, _) in TOPICS.items():
        pkg, _, typ = ros_type.split("/")
        assert heard[name]["samples"] > 0, name
        assert heard[name]["type"] == f"{pkg}::msg::dds_::{typ}_"
    assert heard["/scan"]["age_ms_median"] > 0


#: a stand-in listener: its SIGTERM handler, then "ready" on stderr (the real one says "listening")
_READY = ("import signal, sys, time; signal.signal(signal.SIGTERM, {handler}); "
          "print('ready', file=sys.stderr, flush=True); ")


@pytest.mark.parametrize(("script", "expect"), [
    # ignores SIGTERM: killed after the wait, reported
    (_READY.format(handler="signal.SIG_IGN") + "time.sleep(60)", "did not exit within 0.5 s"),
    # stops on SIGTERM but prints no JSON
    (_READY.format(handler="lambda *a: sys.exit(0)") + "print('not json', flush=True); time.sleep(60)",
     "printed no JSON"),
    # fails
    (_READY.format(handler="lambda *a: sys.exit(3)") + "time.sleep(60)", "exited with 3"),
])
def test_a_listener_that_will_not_stop_or_talk_is_reported_not_waited_on(monkeypatch, script, expect) -> None:
    monkeypatch.setattr(cmd_ros2, "LISTENER_EXIT_S", 0.5)
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None and proc.stderr.readline().strip() == "ready"  # as the bench waits for it
    try:
        assert expect in cmd_ros2._stopped_listener(proc)["error"]
        assert proc.poll() is not None  # it is gone either way
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
