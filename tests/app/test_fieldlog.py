"""The MCAP field log: channels and schemas, drops counted, rotation, truncated files readable."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import foxglove
import numpy as np
import pytest
from foxglove.messages import LaserScan
from mcap.reader import make_reader

from app import fieldlog
from app import logmessages as lm
from app.errors import LogFormatError
from app.fieldlog import TOPICS, FieldLog, LogReadResult, read_log, schema_for


def _scan(i: int, t: float) -> LaserScan:
    return lm.laser_scan([1.0, math.inf, -math.inf, math.nan, 2.5], -1.0, 1.0, None, t + i * 0.025)


def test_messages_round_trip_with_the_official_foxglove_schemas(tmp_path: Path) -> None:
    log = FieldLog(str(tmp_path / "run.mcap"), flush_s=0.05).start()
    t0 = time.time()
    for i in range(20):
        log.log("/scan", t0 + i * 0.025, _scan(i, t0))
    log.log("/log", t0, lambda: lm.log_line("info", "built on the writer thread", t0))
    log.log("/diagnostics", t0, {"cycle": 1})
    log.close()
    assert log.stats.written == 22 and log.stats.dropped == 0 and log.stats.bad_messages == 0
    result = LogReadResult()
    msgs = list(read_log(log.path, result))
    assert not result.truncated and result.bad_messages == 0
    scans = [m for m in msgs if m.topic == "/scan"]
    assert len(scans) == 20 and scans[0].schema == "foxglove.LaserScan"
    r = scans[0].data["ranges"]
    # REP 117: +inf no return, -inf too close, NaN erroneous, carried exactly by protobuf doubles
    assert r[:3] == [1.0, math.inf, -math.inf] and math.isnan(r[3]) and r[4] == 2.5
    assert scans[3].data["timestamp"] == {"sec": int(t0 + 0.075), "nsec": lm.stamp_ns(t0 + 0.075) % 10**9}
    logline = next(m.data for m in msgs if m.topic == "/log")
    assert logline["message"] == "built on the writer thread" and logline["level"] == 2  # foxglove INFO
    # a closed log is indexed; its foxglove schemas are byte for byte the SDK's official ones
    with open(log.path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    by_name = {s.name: s for s in summary.schemas.values()}
    assert by_name["foxglove.LaserScan"].encoding == "protobuf"
    assert by_name["foxglove.LaserScan"].data == foxglove.messages.LaserScan.get_schema().data
    assert by_name["foxglove.Log"].data == foxglove.messages.Log.get_schema().data
    assert by_name["vipsm.LoopDiagnostics"].encoding == "jsonschema"
    encodings = {c.topic: c.message_encoding for c in summary.channels.values()}
    assert encodings == {"/scan": "protobuf", "/log": "protobuf", "/diagnostics": "json"}


def test_every_topic_has_a_schema_and_the_foxglove_ones_are_the_sdks() -> None:
    for topic in TOPICS:
        name = schema_for(topic)
        if name.startswith("foxglove."):
            cls = getattr(foxglove.messages, name.removeprefix("foxglove."))
            assert cls.get_schema().name == name
    assert set(TOPICS) >= {"/scan", "/odom", "/pose", "/tf", "/camera/image", "/obstacles", "/diagnostics", "/log",
                           "/truth", "/vipsm/cycle", "/vipsm/config"}
    with pytest.raises(LogFormatError):
        schema_for("/nope")


def test_a_message_of_the_wrong_type_is_counted_not_written(tmp_path: Path) -> None:
    log = FieldLog(str(tmp_path / "bad.mcap"), flush_s=0.05).start()
    log.log("/scan", 0.0, {"ranges": [1.0]})  # a dict where the SDK's LaserScan is required
    log.log("/scan", 0.0, _scan(0, 0.0))
    log.close()
    assert log.stats.bad_messages == 1 and "LaserScan" in (log.stats.last_bad_message or "")
    assert [m.topic for m in read_log(log.path)] == ["/scan"]


def test_full_queue_drops_and_counts_without_blocking(tmp_path: Path) -> None:
    log = FieldLog(str(tmp_path / "q.mcap"), queue_size=8)  # not started: nothing drains the queue
    log._open_file()  # noqa: SLF001 - so close() has a file to finish
    accepted = sum(log.log("/diagnostics", 0.0, {"i": i}) for i in range(20))
    assert accepted == 8 and log.stats.dropped == 12


def test_rotation_by_time_makes_several_readable_files(tmp_path: Path) -> None:
    log = FieldLog(str(tmp_path / "rot.mcap"), rotate_s=1.0, flush_s=0.05).start()
    deadline = time.monotonic() + 30
    i = 0
    while len(log.stats.files) < 2 and time.monotonic() < deadline:
        log.log("/diagnostics", time.time(), {"i": i})
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
        log.log("/diagnostics", time.time(), {"i": i})
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
            log.log("/diagnostics", time.time(), {{"i": i, "t": time.monotonic()}})
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
    # flush_s = 0.5 promises at most 0.5 s lost (slack for a loaded machine's scheduling)
    assert lost_s <= 0.5 + 0.5


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


class _Disk:
    """A disk that fills up: writes past ``free`` bytes fail with ENOSPC until space is freed."""

    def __init__(self, free: int) -> None:
        self.free = free

    def patch(self, monkeypatch: pytest.MonkeyPatch) -> None:
        import errno

        real_write = fieldlog._GuardedFile.write
        disk = self

        def write(f: fieldlog._GuardedFile, data: bytes) -> int:
            if f.failure is None and len(data) > disk.free:
                f.failure = OSError(errno.ENOSPC, "No space left on device")
            elif f.failure is None:
                disk.free -= len(data)
            return real_write(f, data)

        monkeypatch.setattr(fieldlog._GuardedFile, "write", write)


def test_disk_full_is_reported_logging_resumes_when_space_returns(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    disk = _Disk(free=6000)
    disk.patch(monkeypatch)
    events: list[tuple[str, str]] = []
    log = FieldLog(str(tmp_path / "full.mcap"), flush_s=0.05, retry_s=0.2,
                   on_event=lambda level, msg: events.append((level, msg))).start()
    i = 0
    deadline = time.monotonic() + 20
    while log.stats.state != "disk_error" and time.monotonic() < deadline:
        log.log("/diagnostics", time.time(), {"i": i, "pad": "x" * 200})
        i += 1
        time.sleep(0.002)
    assert log.stats.state == "disk_error" and log.stats.disk_errors >= 1
    assert events[0][0] == "error" and "No space left" in events[0][1]
    for _ in range(20):  # while full: not written, counted, the caller never blocks nor sees an error
        assert log.log("/diagnostics", time.time(), {"i": i})
        i += 1
    time.sleep(0.3)
    disk.free = 10**9  # space returns
    while log.stats.state != "ok" and time.monotonic() < deadline:
        log.log("/diagnostics", time.time(), {"i": i})
        i += 1
        time.sleep(0.01)
    log.log("/diagnostics", time.time(), {"i": "last"})
    log.close()  # never raises for the disk
    assert log.stats.state == "ok" and len(log.stats.files) == 2 and log.stats.lost_to_disk > 0
    assert any(level == "info" and "writing again" in msg for level, msg in events)
    first, second = (list(read_log(p, LogReadResult())) for p in log.stats.files)
    assert first and [m.data["i"] for m in first] == list(range(len(first)))  # readable up to the failure
    assert second[-1].data["i"] == "last"


def test_close_on_a_full_disk_does_not_raise(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    disk = _Disk(free=10**9)
    disk.patch(monkeypatch)
    log = FieldLog(str(tmp_path / "c.mcap"), flush_s=10.0).start()
    for i in range(50):
        log.log("/diagnostics", time.time(), {"i": i})
    time.sleep(0.2)
    disk.free = 0  # the summary and index cannot be written
    log.close()
    assert log.stats.state == "disk_error" and log.stats.last_disk_error
    result = LogReadResult()
    list(read_log(log.path, result))
    assert result.truncated  # the file ends where the disk filled up, and says so when read


def test_scanner_info_is_the_scans_own_and_written_only_on_a_change() -> None:
    """/vipsm/scanner: the scan's beams, bearings and beam timing (one turn of the mirror from them), the
    given limits; written before the first scan, not again for microsecond jitter, again for a new scanner,
    and tried again when the log refused it."""
    from vipsm.types import Scan

    step = 2 * math.pi / 1024
    scan = Scan(np.ones(682), -math.radians(120) + step * np.arange(682), 0.0, 0, 0.1 / 1024)
    info = lm.scanner_info(scan, (0.02, 5.6))
    assert info["beams"] == 682 and info["angle_increment_rad"] == pytest.approx(step)
    assert info["scan_time_s"] == pytest.approx(0.1) and info["time_increment_s"] == pytest.approx(0.1 / 1024)
    assert (info["range_min_m"], info["range_max_m"]) == (0.02, 5.6)
    unknown = lm.scanner_info(Scan(np.ones(3), np.array([0.0, 0.1, 0.2]), 0.0), (0.0, math.inf))
    assert unknown["scan_time_s"] == 0.0 and unknown["range_max_m"] is None  # JSON has no +inf
    written: list[dict] = []
    accept = [False, True, True, True]

    def log(topic: str, wall_s: float, payload: dict) -> bool:
        assert topic == "/vipsm/scanner"
        ok = accept.pop(0)
        if ok:
            written.append(payload)
        return ok

    w = lm.ScannerInfoLog()
    w.before_scan(log, 0.0, info)  # refused (queue full): tried again with the next scan
    w.before_scan(log, 0.1, info)
    w.before_scan(log, 0.2, {**info, "scan_time_s": 0.1 * (1 + 1e-5)})  # jitter: not a new scanner
    w.before_scan(log, 0.3, {**info, "range_max_m": 30.0})
    assert written == [info, {**info, "range_max_m": 30.0}] and accept == [True]


def test_every_rotated_file_begins_with_the_newest_config_and_scanner(tmp_path: Path) -> None:
    """A file after rotation can be read alone: it holds the run's /vipsm/config and the /vipsm/scanner in
    force (the newest, not the first), before its first scan. Driven step by step (no writer thread), so
    where each file ends does not depend on timing."""
    log = FieldLog(str(tmp_path / "rot.mcap"), rotate_bytes=1, fsync=False)
    log._open_file()  # noqa: SLF001 - the writer thread's steps, one by one
    log._write("/vipsm/config", 1.0, {"log_version": 3})  # noqa: SLF001
    for k in range(3):
        log._write("/vipsm/scanner", 1.0 + k, {"beams": 5, "scan_time_s": 0.1 * (k + 1)})  # noqa: SLF001
        log._write("/scan", 1.0 + k, lm.laser_scan([1.0] * 5, -1.0, 1.0, None, 1.0 + k))  # noqa: SLF001
        log._flush()  # noqa: SLF001
        log._rotate_if_due()  # noqa: SLF001 - rotate_bytes=1: a new file after every step
    log._finish_file()  # noqa: SLF001
    assert len(log.stats.files) == 4 and log.stats.written == 7 and log.stats.rewritten == 6
    for k, path in enumerate(log.stats.files):
        msgs = list(read_log(path))
        assert [m.topic for m in msgs] == (["/vipsm/config"] if k == 0 else ["/vipsm/config", "/vipsm/scanner"]) + \
            (["/vipsm/scanner", "/scan"] if k < 3 else []), path
        if k:  # the newest scanner record, at the time of the last message before the file
            assert msgs[1].data["scan_time_s"] == pytest.approx(0.1 * k)
            assert msgs[0].log_time_ns == msgs[1].log_time_ns == lm.stamp_ns(float(k))
