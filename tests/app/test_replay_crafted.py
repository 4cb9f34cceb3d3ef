"""``replay`` on crafted logs (issue 12 row 5): a malformed cycle is skipped, counted and named, the
rest replay, and the exit code says so; never a traceback."""

from __future__ import annotations

import copy
import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from mcap.writer import Writer

from app.logread import LogReadResult
from app.replay import iter_cycles


def good_cycle(n: int) -> dict[str, Any]:
    return {
        "cycle": n,
        "scan": {"seq": n, "stamp_s": 10.0 + 0.1 * n, "beam_dt_s": 2.5e-5, "first_bearing_rad": -1.5,
                 "bearing_step_rad": 3.0 / 180, "ranges_m": [2.0 + 0.01 * (i % 7) for i in range(181)]},
        "odometry": {"x_m": 0.0, "y_m": 0.0, "theta_rad": 0.0, "v_mps": 0.0, "w_radps": 0.0,
                     "stamp_s": 10.0 + 0.1 * n},
        "frame": None,
        "estimate": {},
    }


def crafted() -> list[tuple[str, Any]]:
    """(what is wrong, the /vipsm/cycle payload: a dict, or raw bytes)."""
    out: list[tuple[str, Any]] = []

    def bad(name: str, path: tuple[str, ...], value: Any, delete: bool = False) -> None:
        rec = good_cycle(100 + len(out))
        node = rec
        for key in path[:-1]:
            node = node[key]
        if delete:
            del node[path[-1]]
        else:
            node[path[-1]] = value
        out.append((name, rec))

    bad("no scan", ("scan",), None, delete=True)
    bad("ranges not a list", ("scan", "ranges_m"), "abc")
    bad("empty ranges", ("scan", "ranges_m"), [])
    bad("zero bearing step", ("scan", "bearing_step_rad"), 0.0)
    bad("NaN bearing step", ("scan", "bearing_step_rad"), math.nan)
    bad("a string range", ("scan", "ranges_m"), [1.0, "x", 2.0])
    bad("odometry as text", ("odometry", "x_m"), "1")
    bad("no odometry stamp", ("odometry", "stamp_s"), None, delete=True)
    bad("frame not an object", ("frame",), 7)
    bad("3 M ranges", ("scan", "ranges_m"), [1.0] * 3_000_000)
    out.append(("nested 100,000 deep", b"[" * 100_000 + b"]" * 100_000))
    out.append(("not JSON", b"\xff\xfe not json"))
    return out


def write_log(path: Path, payloads: list[Any]) -> None:
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("vipsm.Cycle", "jsonschema", b"{}")
        cid = w.register_channel("/vipsm/cycle", "json", sid)
        for i, p in enumerate(payloads):
            data = p if isinstance(p, bytes) else json.dumps(p).encode()
            w.add_message(cid, log_time=i, publish_time=i, data=data)
        w.finish()


def test_each_malformed_cycle_is_skipped_named_and_counted(tmp_path: Path) -> None:
    cases = crafted()
    goods = [good_cycle(n) for n in range(4)]
    log = tmp_path / "crafted.mcap"
    write_log(log, [goods[0], goods[1], *[p for _, p in cases], goods[2], goods[3]])
    read = LogReadResult()
    cycles = list(iter_cycles(log, read))
    assert [c.cycle for c in cycles] == [0, 1, 2, 3]
    assert read.bad_messages == len(cases) and not read.truncated
    assert any("ranges_m" in r for r in read.bad) and any("bearing_step_rad" in r for r in read.bad)


@pytest.mark.parametrize("index", range(len(crafted())))
def test_one_crafted_cycle_among_good_ones(tmp_path: Path, index: int) -> None:
    name, payload = crafted()[index]
    log = tmp_path / "one.mcap"
    write_log(log, [good_cycle(0), copy.deepcopy(payload), good_cycle(1)])
    read = LogReadResult()
    assert [c.cycle for c in iter_cycles(log, read)] == [0, 1], name
    assert read.bad_messages == 1, name


def test_replay_cli_reports_the_skipped_messages_with_exit_3(tmp_path: Path) -> None:
    log = tmp_path / "crafted.mcap"
    write_log(log, [good_cycle(0), good_cycle(1), crafted()[1][1], good_cycle(2)])
    proc = subprocess.run([sys.executable, "-m", "app", "replay", str(log), "--json"], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 3, proc.stderr
    assert "Traceback" not in proc.stderr and "malformed message" in proc.stderr
    out = json.loads(proc.stdout)
    assert out["cycles"] == 3 and out["bad_messages"] == 1 and "ranges_m" in out["bad_message_reasons"][0]


def test_a_log_with_only_malformed_cycles_says_why_in_one_line(tmp_path: Path) -> None:
    log = tmp_path / "bad.mcap"
    write_log(log, [crafted()[1][1], crafted()[2][1]])
    proc = subprocess.run([sys.executable, "-m", "app", "replay", str(log)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "2 malformed" in proc.stderr and "ranges_m" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_a_log_recorded_with_a_removed_config_key_is_refused_with_the_way_out(tmp_path) -> None:
    """A field log whose recorded configuration sets a key this version removed is not silently replayed
    with another configuration: the error names the key, its replacement and the replay options to use."""
    from app.replay import LogFormatError, recorded_estimator_config

    path = tmp_path / "old.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        cid = w.register_channel("/vipsm/config", "json", w.register_schema("vipsm.Config", "jsonschema", b"{}"))
        payload = {"estimator": {"bodies": {"leg_radius_m": 0.06}}, "log_version": 3}
        w.add_message(cid, log_time=0, publish_time=0, data=json.dumps(payload).encode())
        w.finish()
    with pytest.raises(LogFormatError) as exc:
        recorded_estimator_config(path)
    msg = str(exc.value)
    assert "estimator.bodies.leg_radius_m" in msg and "people.leg_radius_m" in msg and "--config" in msg
