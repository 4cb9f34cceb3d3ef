"""The field log: MCAP files written with the Foxglove SDK by their own thread, and the same channels
served live (``app.liveview``).

Channels (topic: schema, encoding):

===================  ============================  ==========================================================
``/scan``            ``foxglove.LaserScan`` pb     every scan the driver delivered (REP 117: +inf no return)
``/odom``            ``foxglove.PoseInFrame`` pb   wheel odometry, every sample (frame ``odom``)
``/pose``            ``foxglove.PoseInFrame`` pb   the estimator's matched pose, every cycle (frame ``odom``)
``/tf``              ``foxglove.FrameTransforms``  odom -> base_link -> laser, camera (+ world, truth in sim)
``/camera/image``    ``foxglove.CompressedImage``  every frame used, JPEG as the camera sent it
``/obstacles``       ``foxglove.SceneUpdate`` pb   tracked obstacles: cylinder, velocity arrow, speed text
``/people``          ``foxglove.SceneUpdate`` pb   every person: moving (obstacle colour, arrow) or standing (blue)
``/log``             ``foxglove.Log`` pb           daemon log lines (state changes, degraded modes, faults)
``/diagnostics``     ``vipsm.LoopDiagnostics``     loop health and device states, every cycle (JSON)
``/truth``           ``vipsm.GroundTruth``         simulated runs only: the world's true robot/obstacles (JSON)
``/vipsm/cycle``     ``vipsm.Cycle``               the estimator's exact inputs and outputs, for replay (JSON)
``/vipsm/config``    ``vipsm.Config``              the whole configuration and ``log_version``, once (JSON)
``/vipsm/scanner``   ``vipsm.ScannerInfo``         the scanner's geometry, timing, range limits: before the
                                                   first ``/scan`` and on every change (JSON; from log 3 on)
===================  ============================  ==========================================================

The ``foxglove.*`` channels are the SDK's typed channels (official protobuf schemas by
construction); the project's channels carry complete JSON schemas (:mod:`app.logschemas`).

The control loop only enqueues (``log``); a bounded queue drops and counts what the writer cannot
take, so the loop never blocks on the disk. A chunk is closed and the file flushed and fsynced once
its oldest message is ``0.6 * flush_s`` old, so a process killed with SIGKILL (or a power cut) loses
at most ``flush_s`` (the rest is the flush's own time). A log closed normally gets its summary and
index. Files rotate by size or age and are created mode 0640 whatever the umask; each later file
begins with the newest ``/vipsm/config`` and ``/vipsm/scanner`` (:data:`LATCHED_TOPICS`, at the log
time of the last message before it), so it replays and exports on its own. A failed write
(disk full, I/O error) ends that file where it stands (readable up to its last complete chunk), is
reported once through ``on_event``, and a new file is tried every ``retry_s``; messages in between
still reach the live view and are counted as ``lost_to_disk``.
"""

from __future__ import annotations

import json
import math
import os
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import LogFormatError
from .logread import LogMessage, LogReadResult, read_log  # noqa: F401 - the log's reader lives beside it
from .logschemas import CYCLE, DIAGNOSTICS, GROUND_TRUTH, SCANNER_INFO, config_schema

#: the project's JSON channels: topic -> (schema name, schema factory)
JSON_TOPICS: dict[str, tuple[str, Callable[[], dict[str, Any]]]] = {
    "/diagnostics": ("vipsm.LoopDiagnostics", lambda: DIAGNOSTICS),
    "/truth": ("vipsm.GroundTruth", lambda: GROUND_TRUTH),
    "/vipsm/cycle": ("vipsm.Cycle", lambda: CYCLE),
    "/vipsm/config": ("vipsm.Config", config_schema),
    "/vipsm/scanner": ("vipsm.ScannerInfo", lambda: SCANNER_INFO),
}

#: the Foxglove channels: topic -> name of the SDK's typed channel class in ``foxglove.channels``
FOXGLOVE_TOPICS: dict[str, str] = {
    "/scan": "LaserScanChannel",
    "/odom": "PoseInFrameChannel",
    "/pose": "PoseInFrameChannel",
    "/tf": "FrameTransformsChannel",
    "/camera/image": "CompressedImageChannel",
    "/obstacles": "SceneUpdateChannel",
    "/people": "SceneUpdateChannel",
    "/log": "LogChannel",
}

TOPICS = (*FOXGLOVE_TOPICS, *JSON_TOPICS)

#: channels written once or on a change that every file must hold to be read alone: the newest message
#: of each is written again at the start of every later file (rotation, a new file after a disk error)
LATCHED_TOPICS = ("/vipsm/config", "/vipsm/scanner")

#: log files are readable by their owner and group only (they hold camera images and the robot's
#: whereabouts; the configuration in them is redacted, see :func:`app.config.redacted_config`)
LOG_FILE_MODE = 0o640


def schema_for(topic: str) -> str:
    """The schema name a topic carries (``foxglove.LaserScan``, ``vipsm.Cycle``, ...)."""
    if topic in JSON_TOPICS:
        return JSON_TOPICS[topic][0]
    if topic in FOXGLOVE_TOPICS:
        return "foxglove." + FOXGLOVE_TOPICS[topic].removesuffix("Channel")
    raise LogFormatError(f"no schema for topic {topic!r}")


@dataclass
class FieldLogStats:
    enqueued: int = 0
    written: int = 0
    dropped: int = 0
    files: list[str] = field(default_factory=list)
    bytes_written: int = 0
    #: messages that could not be encoded (counted and skipped; the writer carries on)
    bad_messages: int = 0
    last_bad_message: str | None = None
    #: "ok", "off" (live view only), or "disk_error" (a write failed; retrying)
    state: str = "ok"
    #: messages not written to a file because the disk had failed (they still went to the live view)
    lost_to_disk: int = 0
    disk_errors: int = 0
    last_disk_error: str | None = None
    #: an unexpected failure of the writer thread (it stopped); None while it runs
    error: str | None = None
    #: latched messages written again at the start of a later file (not in ``written``)
    rewritten: int = 0


def _json_default(obj: Any) -> Any:
    """numpy scalars and arrays as plain JSON values."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def _finite(obj: Any) -> Any:
    """NaN and infinities become null (JSON has neither)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _finite(obj.tolist())
    if isinstance(obj, np.floating):
        return _finite(float(obj))
    return obj


def encode_json(payload: Any) -> bytes:
    try:
        text = json.dumps(payload, separators=(",", ":"), allow_nan=False, default=_json_default)
    except ValueError:
        text = json.dumps(_finite(payload), separators=(",", ":"), allow_nan=False, default=_json_default)
    return text.encode()


class _GuardedFile:
    """The file the SDK's MCAP writer writes to. A failed write (ENOSPC, EIO) is recorded and the
    rest of the file's bytes are discarded, so the writer never sees an error (it would print one per
    message) and the file ends at the failure, readable up to its last complete chunk. After a
    failure, positions are kept as if the writes had happened (the writer seeks back to patch chunk
    headers and checks where it is)."""

    def __init__(self, path: str) -> None:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, LOG_FILE_MODE)
        try:
            os.fchmod(fd, LOG_FILE_MODE)  # whatever the umask (or a file that was there) made of it
        except OSError:
            os.close(fd)
            raise
        self.file = os.fdopen(fd, "wb")
        self.bytes = 0  # bytes actually written
        self._pos = 0  # the writer's position, real or (after a failure) virtual
        self._size = 0
        self.failure: OSError | None = None

    def write(self, data: bytes) -> int:
        if self.failure is None:
            try:
                self.file.write(data)
                self.bytes = max(self.bytes, self._pos + len(data))
            except OSError as exc:
                self.failure = exc
        self._pos += len(data)
        self._size = max(self._size, self._pos)
        return len(data)

    def seek(self, offset: int, whence: int = 0) -> int:
        base = {0: 0, 1: self._pos, 2: self._size}[whence]
        self._pos = base + offset
        if self.failure is None:
            try:
                self.file.seek(self._pos)
            except OSError as exc:
                self.failure = exc
        return self._pos

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        self.sync(fsync=False)

    def sync(self, fsync: bool) -> None:
        if self.failure is not None:
            return
        try:
            self.file.flush()
            if fsync:
                os.fsync(self.file.fileno())
        except OSError as exc:
            self.failure = exc

    def close(self) -> None:
        try:
            self.file.close()
        except OSError as exc:  # the buffered tail could not be written: the file ends before it
            self.failure = self.failure or exc


_STOP = object()


class FieldLog:
    """Writes messages to MCAP (and the live view) on a background thread; ``log`` never blocks.

    ``log(topic, t_wall_s, payload)``: ``payload`` is a Foxglove SDK message for a ``foxglove.*``
    topic or a JSON-able dict for a project topic, or a callable returning one (evaluated on the
    writer thread, so building large messages costs the loop nothing). ``path_pattern`` None: no
    file, the channels only feed a live view started on :attr:`context`.
    """

    def __init__(
        self,
        path_pattern: str | None,
        *,
        compression: str = "zstd",
        rotate_bytes: int = 512 * 1024 * 1024,
        rotate_s: float = 3600.0,
        flush_s: float = 0.5,
        queue_size: int = 512,
        fsync: bool = True,
        retry_s: float = 5.0,
        wall_clock: Callable[[], float] = time.time,
        on_event: Callable[[str, str], None] | None = None,
    ) -> None:
        import foxglove

        if compression not in ("zstd", "lz4", "none"):
            raise LogFormatError(f"unknown compression {compression!r}")
        self._pattern = path_pattern
        self._compression = compression
        self._rotate_bytes = rotate_bytes
        self._rotate_s = rotate_s
        self._flush_s = flush_s
        self._fsync = fsync
        self._retry_s = retry_s
        self._wall = wall_clock
        self.on_event = on_event
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=queue_size)
        self.stats = FieldLogStats(state="ok" if path_pattern else "off")
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        #: the SDK context binding the channels to their sinks (the MCAP file, a live view)
        self.context = foxglove.Context()
        self._channels: dict[str, Any] = {}
        self._file: _GuardedFile | None = None
        self._writer: Any = None
        self._opened_at = 0.0
        self._retry_at = math.inf
        #: the newest message of each latched topic (encoded) and the newest log time written
        self._latched: dict[str, Any] = {}
        self._last_log_ns = 0

    @property
    def path(self) -> str | None:
        """The file being written now (the newest one after rotation)."""
        return self.stats.files[-1] if self.stats.files else None

    def start(self) -> FieldLog:
        """Opens the first file (``OSError`` if it cannot be created) and starts the writer."""
        if self._pattern:
            self._open_file()
        self._thread = threading.Thread(target=self._run, name="field-log", daemon=True)
        self._thread.start()
        return self

    def log(self, topic: str, t_wall_s: float, payload: Any) -> bool:
        """Queue one message; False (and counted) when the queue is full or the writer stopped."""
        if self.stats.error is not None:
            with self._lock:
                self.stats.dropped += 1
            return False
        try:
            self._queue.put_nowait((topic, t_wall_s, payload, time.monotonic()))
        except queue.Full:
            with self._lock:
                self.stats.dropped += 1
            return False
        with self._lock:
            self.stats.enqueued += 1
        return True

    def close(self, timeout_s: float = 10.0) -> None:
        """Write what is queued, the summary and the index; idempotent; never raises for the disk
        (a failure is in ``stats``)."""
        if self._thread is None:
            return
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                self._queue.put(_STOP, timeout=0.1)
                break
            except queue.Full:
                if time.monotonic() > deadline:
                    break
        self._thread.join(max(0.0, deadline - time.monotonic()))
        self._thread = None
        self._finish_file()

    # -- files ---------------------------------------------------------------------------------

    def _new_path(self) -> str:
        assert self._pattern
        path = Path(time.strftime(self._pattern, time.localtime(self._wall())))
        if path.parent and not path.parent.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
        n = 1
        candidate = path
        while str(candidate) in self.stats.files or candidate.exists():
            candidate = path.with_name(f"{path.stem}-{n}{path.suffix}")
            n += 1
        return str(candidate)

    def _open_file(self) -> None:
        import foxglove
        from foxglove.mcap import MCAPCompression, MCAPWriteOptions

        path = self._new_path()
        self._file = _GuardedFile(path)
        compression = {"zstd": MCAPCompression.Zstd, "lz4": MCAPCompression.Lz4, "none": None}[self._compression]
        options = MCAPWriteOptions(compression=compression, compression_threads=0, profile="",
                                   chunk_size=1024 * 1024)
        self._writer = foxglove.open_mcap(self._file, context=self.context, writer_options=options)  # type: ignore[arg-type]
        self._opened_at = time.monotonic()
        self.stats.files.append(path)
        self._write_latched()

    def _write_latched(self) -> None:
        """A new file begins with the newest message of every latched topic (none before the first)."""
        for topic, data in self._latched.items():
            self._channel(topic).log(data, log_time=self._last_log_ns)
            self.stats.rewritten += 1

    def _finish_file(self) -> None:
        """Summary and index written, the file synced and closed (a failure is recorded, not raised)."""
        if self._writer is None or self._file is None:
            return
        writer, f = self._writer, self._file
        self._writer = self._file = None
        try:
            writer.close()
        except RuntimeError as exc:  # the SDK's error for a failed write the guard let through
            f.failure = f.failure or OSError(str(exc))
        f.sync(fsync=self._fsync)
        f.close()
        if f.failure is not None:
            self._note_failure(f.failure)

    def _note_failure(self, exc: OSError) -> None:
        self.stats.disk_errors += 1
        self.stats.last_disk_error = str(exc.strerror or exc)
        self.stats.state = "disk_error"
        self._retry_at = time.monotonic() + self._retry_s
        if self.on_event is not None:
            self.on_event("error", f"field log: writing failed: {exc.strerror or exc}; messages are lost until "
                                    f"a new file can be written (retry every {self._retry_s:g} s)")

    def _check_disk(self) -> None:
        """A failed file is ended; after ``retry_s`` a new file is tried."""
        f = self._file
        if f is not None and f.failure is not None:
            path = self.path
            self._finish_file()
            if self.on_event is not None:
                self.on_event("warning", f"field log: {path} ends at the failure (readable up to it)")
        if self._file is None and self._pattern and time.monotonic() >= self._retry_at:
            try:
                self._open_file()
            except OSError as exc:
                self._note_failure(exc)
                return
            self.stats.state = "ok"
            self._retry_at = math.inf
            if self.on_event is not None:
                self.on_event("info", f"field log: writing again, to {self.path}")

    # -- writer thread ------------------------------------------------------------------------

    def _channel(self, topic: str) -> Any:
        ch = self._channels.get(topic)
        if ch is not None:
            return ch
        import foxglove
        import foxglove.channels

        if topic in JSON_TOPICS:
            name, schema = JSON_TOPICS[topic]
            sch = foxglove.Schema(name=name, encoding="jsonschema", data=json.dumps(schema()).encode())
            ch = foxglove.Channel(topic, schema=sch, message_encoding="json", context=self.context)
        elif topic in FOXGLOVE_TOPICS:
            ch = getattr(foxglove.channels, FOXGLOVE_TOPICS[topic])(topic, context=self.context)
        else:
            raise TypeError(f"no channel for topic {topic!r}")
        self._channels[topic] = ch
        return ch

    def _write(self, topic: str, t_wall_s: float, payload: Any) -> None:
        try:
            if callable(payload):
                payload = payload()
            channel = self._channel(topic)
            ns = int(round(t_wall_s * 1e9))
            data = encode_json(payload) if topic in JSON_TOPICS else payload
            channel.log(data, log_time=ns)
            if topic in LATCHED_TOPICS:
                self._latched[topic] = data
            self._last_log_ns = max(self._last_log_ns, ns)
        except (TypeError, ValueError, ArithmeticError, OverflowError) as exc:
            self.stats.bad_messages += 1
            self.stats.last_bad_message = f"{topic}: {type(exc).__name__}: {exc}"
            return
        if self._file is None:
            if self._pattern:
                self.stats.lost_to_disk += 1
            return
        self.stats.written += 1
        self.stats.bytes_written = self._file.bytes

    def _flush(self) -> None:
        if self._writer is None or self._file is None:
            return
        try:
            self._writer.flush()
        except RuntimeError as exc:
            self._file.failure = self._file.failure or OSError(str(exc))
        self._file.sync(fsync=self._fsync)

    def _run(self) -> None:
        oldest: float | None = None  # enqueue time of the oldest message not yet flushed
        flush_after = 0.6 * self._flush_s
        try:
            while True:
                wait = self._retry_s if oldest is None else max(0.0, oldest + flush_after - time.monotonic())
                try:
                    item = self._queue.get(timeout=min(wait, self._retry_s))
                except queue.Empty:
                    item = None
                if item is _STOP:
                    self._flush()
                    return
                if item is not None:
                    self._write(*item[:3])
                    oldest = item[3] if oldest is None else oldest
                if oldest is not None and time.monotonic() - oldest >= flush_after:
                    self._flush()
                    oldest = None
                    self._rotate_if_due()
                self._check_disk()
        except BaseException as exc:  # noqa: BLE001 - surfaced through stats.error and the daemon's status
            self.stats.error = f"{type(exc).__name__}: {exc}"

    def _rotate_if_due(self) -> None:
        f = self._file
        if f is None or f.failure is not None:
            return
        if f.bytes >= self._rotate_bytes or time.monotonic() - self._opened_at >= self._rotate_s:
            self._finish_file()
            if self.stats.state == "ok":
                try:
                    self._open_file()
                except OSError as exc:
                    self._note_failure(exc)
