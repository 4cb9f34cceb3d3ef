"""``bench --only daemon``: the 40 Hz loop against the simulated devices, its latency and load."""

from __future__ import annotations

import argparse

import pytest

from app import cmd_daemon


def test_daemon_bench_runs_the_sim_at_40_hz_and_reports_the_latency(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cmd_daemon, "BENCH_SIM_S", 4.0)  # the bench runs 30 s; the figures' shape is the test
    figures = cmd_daemon.bench(argparse.Namespace())
    assert set(cmd_daemon.BENCH_KEYS) <= set(figures)
    assert figures["duration_s"] == 4.0 and 'loop.trigger="scan"' in figures["command"]
    # How many scans get an estimate depends on the machine's speed (that is the bench's figure,
    # not this test's): here only that the loop ran on scans and counted what it did.
    assert figures["scans"] > 0 and 0 < figures["estimates"] <= figures["scans"]
    assert figures["cycles"] >= figures["estimates"] and figures["deadline_misses"] >= 0
    whole, host = figures["scan_to_obstacles_ms_median"], figures["scan_received_to_obstacles_ms_median"]
    assert 0.0 < host < whole  # the host's part is inside the whole (the USB transfer is the rest)
    assert figures["scan_to_obstacles_ms_p99"] >= whole
    assert figures["daemon_cpu_percent"] > 0.0 and figures["load_average_1min"] >= 0.0
