"""The MCAP field log: channels and schemas, drops counted, rotation, truncated files readable."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from app.errors import LogFormatError
from app.fieldlog import SCHEMAS, FieldLog, LogReadResult, read_log, schema_for


def test_messages_round_trip_with_foxglove_schemas(tmp_path: Path) -> None:
    log = FieldLog(str(tmp_path / "run.mcap"), flush_s=0.05).start()
    t0 = time.time()
    for i in range(20):
        log.log("/scan", t0 + i * 0.025, {"ranges": [1.0, None, 2.5], "seq": i})
    log.log("/log", t0, lambda: {"level": 2, "message": "built on the writer thread"})
    log.close()
    assert log.stats.written == 21 and log.stats.dropped == 0
    result = LogReadResult()
    msgs = list(read_log(log.path, result))
    assert not result.truncated
    assert [m.data["seq"] for m in msgs if m.topic == "/scan"] == list(range(20))
    assert msgs[-1].data["message"] == "built on the writer thread"
    # a closed log is indexed: the seeking reader finds the summary and the foxglove schema names
    with open(log.path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    names = {s.name for s in summary.schemas.values()}
    assert names == {"foxglove.LaserScan", "foxglove.Log"}
    assert {c.message_encoding for c in summary.channels.values()} == {"json"}


def test_every_topic_has_a_schema() -> None:
    for topic in ["/scan", "/odom", "/pose", "/camera/image", "/obstacles", "/diagnostics", "/log", "/truth",
                  "/vipsm/cycle", "/vipsm/config"]:
        assert schema_for(topic) in SCHEMAS
    with pytest.raises(LogFormatError):
        schema_for("/nope")


def test_full_queue_drops_and_counts_without_blocking(tmp_path: Path) -> None:
    log = FieldLog(str(tmp_path / "q.mcap"), queue_size=8)  # not started: nothing drains the queue
    log._open_file()  # noqa: SLF001 - so close() has a file to finish
    accepted = sum(log.log("/log", 0.0, {"i": i}) for i in range(20))
    assert accepted == 8 and log.stats.dropped == 12


def test_rotation_by_time_makes_several_readable_files(tmp_path: Path) -> None:
    log = FieldLog(str(tmp_path / "rot.mcap"), rotate_s=1.0, flush_s=0.05).start()
    deadline = time.monotonic() + 30
    i = 0
    while len(log.stats.files) < 2 and time.monotonic() < deadline:
        log.log("/log", time.time(), {"i": i})
        i += 1
        time.sleep(0.01)
    log.close()
    assert len(log.stats.files) >= 2
    seen = [m.data["i"] for path in log.stats.files for m in read_log(path)]
    assert seen == list(range(i))


def test_not_mcap_is_a_typed_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"hello world, not a log")
    with pytest.raises(LogFormatError):
        list(read_log(bad))
    with pytest.raises(LogFormatError):
        list(read_log(tmp_path / "missing.mcap"))


def test_truncated_file_yields_what_was_complete(tmp_path: Path) -> None:
    log = FieldLog(str(tmp_path / "cut.mcap"), flush_s=0.05).start()
    for i in range(50):
        log.log("/log", time.time(), {"i": i})
    log.close()
    data = Path(log.path).read_bytes()
    cut = tmp_path / "cut2.mcap"
    cut.write_bytes(data[: len(data) // 2])
    result = LogReadResult()
    msgs = list(read_log(cut, result))
    assert result.truncated and result.reason
    assert [m.data["i"] for m in msgs] == list(range(len(msgs)))


def test_sigkill_loses_at_most_the_last_flush_interval(tmp_path: Path) -> None:
    script = textwrap.dedent(
        f"""
        import sys, time
        from app.fieldlog import FieldLog
        log = FieldLog({str(tmp_path / "kill.mcap")!r}, flush_s=0.5).start()
        i = 0
        while True:
            log.log("/log", time.time(), {{"i": i, "t": time.monotonic()}})
            i += 1
            if i == 1:
                print("started", flush=True)
            time.sleep(0.01)
        """
    )
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, cwd=os.getcwd())
    assert proc.stdout is not None and proc.stdout.readline().strip() == b"started"
    time.sleep(2.0)
    killed_at = time.monotonic()
    proc.send_signal(signal.SIGKILL)
    proc.wait(10)
    result = LogReadResult()
    msgs = list(read_log(tmp_path / "kill.mcap", result))
    assert msgs, "nothing survived SIGKILL"
    assert [m.data["i"] for m in msgs] == list(range(len(msgs)))
    lost_s = killed_at - msgs[-1].data["t"]
    # flush every 0.5 s: the last second survives (slack for a loaded machine's scheduling)
    assert lost_s <= 1.0 + 0.5


def test_numpy_values_nan_and_bad_messages_do_not_stop_the_writer(tmp_path: Path) -> None:
    import numpy as np

    log = FieldLog(str(tmp_path / "np.mcap"), flush_s=0.05).start()
    log.log("/diagnostics", 0.0, {"n": np.int64(3), "x": np.float32(0.5), "cov": np.eye(2), "r": float("nan")})
    log.log("/diagnostics", 0.0, {"bad": object()})
    log.log("/diagnostics", 0.0, lambda: 1 / 0)
    log.log("/diagnostics", 0.0, {"after": True})
    log.close()
    msgs = [m.data for m in read_log(log.path)]
    assert msgs == [{"n": 3, "x": 0.5, "cov": [[1.0, 0.0], [0.0, 1.0]], "r": None}, {"after": True}]
    assert log.stats.bad_messages == 2 and log.stats.error is None


def test_empty_or_header_cut_file_is_truncated_not_foreign(tmp_path: Path) -> None:
    for n in (0, 5):
        p = tmp_path / f"cut{n}.mcap"
        p.write_bytes(b"\x89MCAP0\r\n"[:n])
        result = LogReadResult()
        assert list(read_log(p, result)) == [] and result.truncated
