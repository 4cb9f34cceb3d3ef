"""``bench --only ros2``: the daemon bench's sim without and with ``--ros2``, a listener in another
process (``vipsm-robot ros2-listen``) reading every topic over loopback."""

from __future__ import annotations

import argparse

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
