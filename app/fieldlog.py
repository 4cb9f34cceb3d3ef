"""The field log: MCAP files with Foxglove schemas in JSON encoding, written by their own thread.

Channels (topic: schema):

===========================  =========================  =====================================================
``/scan``                    ``foxglove.LaserScan``     every scan the driver delivered (invalid ranges: null)
``/odom``                    ``foxglove.PoseInFrame``   wheel odometry, every sample
``/pose``                    ``foxglove.PoseInFrame``   the estimator's matched pose, every cycle
``/camera/image``            ``foxglove.CompressedImage``  every frame used, JPEG as the camera sent it
``/obstacles``               ``foxglove.SceneUpdate``   tracked obstacles (cylinders + velocity text)
``/diagnostics``             ``vipsm.LoopDiagnostics``  loop health and device states, every cycle
``/log``                     ``foxglove.Log``           daemon log lines (degraded modes, reconnects, faults)
``/truth``                   ``vipsm.GroundTruth``      simulated runs only: the world's true robot/obstacles
``/vipsm/cycle``             ``vipsm.Cycle``            the estimator's exact inputs and outputs (for replay)
``/vipsm/config``            ``vipsm.Config``           the whole configuration, once at start (for replay)
===========================  =========================  =====================================================

The control loop only enqueues (``log``); a bounded queue drops and counts what the writer cannot
take, so the loop never blocks on the disk. Chunks are closed and the file flushed and fsynced at
least every ``flush_s`` seconds, so a process killed with SIGKILL (or a power cut) loses at most that
much; a log closed normally (SIGTERM) gets its summary and index. Files rotate by size or age.
"""

from __future__ import annotations

import base64
import json
import math
import os
import queue
import struct
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from mcap.exceptions import McapError
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from .errors import LogFormatError

_TIME = {
    "type": "object",
    "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0}},
}
_VEC3 = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
_QUAT = {"type": "object", "properties": {k: {"type": "number"} for k in "xyzw"}}
_POSE = {"type": "object", "properties": {"position": _VEC3, "orientation": _QUAT}}
_COLOR = {"type": "object", "properties": {k: {"type": "number"} for k in "rgba"}}

SCHEMAS: dict[str, dict[str, Any]] = {
    "foxglove.LaserScan": {
        "type": "object",
        "properties": {
            "timestamp": _TIME,
            "frame_id": {"type": "string"},
            "pose": _POSE,
            "start_angle": {"type": "number"},
            "end_angle": {"type": "number"},
            "ranges": {"type": "array", "items": {"type": ["number", "null"]}},
            "intensities": {"type": "array", "items": {"type": "number"}},
        },
    },
    "foxglove.PoseInFrame": {
        "type": "object",
        "properties": {"timestamp": _TIME, "frame_id": {"type": "string"}, "pose": _POSE},
    },
    "foxglove.CompressedImage": {
        "type": "object",
        "properties": {
            "timestamp": _TIME,
            "frame_id": {"type": "string"},
            "data": {"type": "string", "contentEncoding": "base64"},
            "format": {"type": "string"},
        },
    },
    "foxglove.SceneUpdate": {
        "type": "object",
        "properties": {
            "deletions": {"type": "array", "items": {"type": "object"}},
            "entities": {
                "type": "array",
                "items": {
                    "type": "object",
                    "properties": {
                        "timestamp": _TIME,
                        "frame_id": {"type": "string"},
                        "id": {"type": "string"},
                        "lifetime": _TIME,
                        "frame_locked": {"type": "boolean"},
                        "metadata": {"type": "array", "items": {"type": "object"}},
                        "cylinders": {
                            "type": "array",
                            "items": {
                                "type": "object",
                                "properties": {
                                    "pose": _POSE,
                                    "size": _VEC3,
                                    "bottom_scale": {"type": "number"},
                                    "top_scale": {"type": "number"},
                                    "color": _COLOR,
                                },
                            },
                        },
                        "arrows": {"type": "array", "items": {"type": "object"}},
                        "texts": {"type": "array", "items": {"type": "object"}},
                    },
                },
            },
        },
    },
    "foxglove.Log": {
        "type": "object",
        "properties": {
            "timestamp": _TIME,
            "level": {"type": "integer", "description": "1 debug, 2 info, 3 warning, 4 error, 5 fatal"},
            "message": {"type": "string"},
            "name": {"type": "string"},
            "file": {"type": "string"},
            "line": {"type": "integer"},
        },
    },
    "vipsm.LoopDiagnostics": {"type": "object", "description": "loop health and device states per cycle"},
    "vipsm.GroundTruth": {"type": "object", "description": "the simulated world's truth at the cycle's time"},
    "vipsm.Cycle": {"type": "object", "description": "the estimator's exact inputs and outputs for one cycle"},
    "vipsm.Config": {"type": "object", "description": "the daemon's whole configuration at start"},
}

TOPIC_SCHEMAS: dict[str, str] = {
    "/scan": "foxglove.LaserScan",
    "/odom": "foxglove.PoseInFrame",
    "/pose": "foxglove.PoseInFrame",
    "/camera/image": "foxglove.CompressedImage",
    "/obstacles": "foxglove.SceneUpdate",
    "/diagnostics": "vipsm.LoopDiagnostics",
    "/log": "foxglove.Log",
    "/truth": "vipsm.GroundTruth",
    "/vipsm/cycle": "vipsm.Cycle",
    "/vipsm/config": "vipsm.Config",
}

LOG_LEVELS = {"debug": 1, "info": 2, "warning": 3, "error": 4, "fatal": 5}


def schema_for(topic: str) -> str:
    if topic in TOPIC_SCHEMAS:
        return TOPIC_SCHEMAS[topic]
    raise LogFormatError(f"no schema for topic {topic!r}")


def stamp(t_wall_s: float) -> dict[str, int]:
    """A foxglove Time from seconds since the epoch."""
    ns = int(round(t_wall_s * 1e9))
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def yaw_quaternion(theta_rad: float) -> dict[str, float]:
    return {"x": 0.0, "y": 0.0, "z": math.sin(theta_rad / 2.0), "w": math.cos(theta_rad / 2.0)}


def b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


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
    error: str | None = None


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


_COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
_STOP = object()


class FieldLog:
    """Writes messages to MCAP on a background thread; ``log`` never blocks.

    ``log(topic, t_wall_s, payload)``: ``payload`` is a JSON-able dict, or a callable returning one
    (evaluated on the writer thread, so building large messages costs the loop nothing).
    """

    def __init__(
        self,
        path_pattern: str,
        *,
        compression: str = "zstd",
        rotate_bytes: int = 512 * 1024 * 1024,
        rotate_s: float = 3600.0,
        flush_s: float = 0.5,
        queue_size: int = 512,
        fsync: bool = True,
        wall_clock: Callable[[], float] = time.time,
    ) -> None:
        if compression not in _COMPRESSION:
            raise LogFormatError(f"unknown compression {compression!r}")
        self._pattern = path_pattern
        self._compression = _COMPRESSION[compression]
        self._rotate_bytes = rotate_bytes
        self._rotate_s = rotate_s
        self._flush_s = flush_s
        self._fsync = fsync
        self._wall = wall_clock
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=queue_size)
        self.stats = FieldLogStats()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._file: Any = None
        self._writer: Writer | None = None
        self._channels: dict[str, int] = {}
        self._schemas: dict[str, int] = {}
        self._opened_at = 0.0

    @property
    def path(self) -> str | None:
        """The file being written now (the newest one after rotation)."""
        return self.stats.files[-1] if self.stats.files else None

    def start(self) -> FieldLog:
        self._open_file()
        self._thread = threading.Thread(target=self._run, name="field-log", daemon=True)
        self._thread.start()
        return self

    def log(self, topic: str, t_wall_s: float, payload: dict[str, Any] | Callable[[], dict[str, Any]]) -> bool:
        """Queue one message; False (and counted) when the queue is full or the writer failed."""
        if self.stats.error is not None:
            self.stats.dropped += 1
            return False
        try:
            self._queue.put_nowait((topic, t_wall_s, payload))
        except queue.Full:
            with self._lock:
                self.stats.dropped += 1
            return False
        with self._lock:
            self.stats.enqueued += 1
        return True

    def close(self, timeout_s: float = 10.0) -> None:
        """Write what is queued, the summary and the index; idempotent."""
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

    # -- writer thread ------------------------------------------------------------------------

    def _new_path(self) -> str:
        base = time.strftime(self._pattern, time.localtime(self._wall()))
        path = Path(base)
        if path.parent and not path.parent.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
        n = 1
        candidate = path
        while str(candidate) in self.stats.files or candidate.exists():
            candidate = path.with_name(f"{path.stem}-{n}{path.suffix}")
            n += 1
        return str(candidate)

    def _open_file(self) -> None:
        path = self._new_path()
        self._file = open(path, "wb")  # noqa: SIM115 - owned until _finish_file
        self._writer = Writer(self._file, compression=self._compression, chunk_size=1024 * 1024)
        self._writer.start(profile="", library="vipsm-robot")
        self._channels.clear()
        self._schemas.clear()
        self._opened_at = time.monotonic()
        self.stats.files.append(path)

    def _finish_file(self) -> None:
        if self._writer is None:
            return
        try:
            self._writer.finish()
            self._file.flush()
            os.fsync(self._file.fileno())
        finally:
            self._file.close()
            self._writer = None
            self._file = None

    def _channel(self, topic: str) -> int:
        cid = self._channels.get(topic)
        if cid is not None:
            return cid
        assert self._writer is not None
        name = schema_for(topic)
        sid = self._schemas.get(name)
        if sid is None:
            sid = self._writer.register_schema(name, "jsonschema", json.dumps(SCHEMAS[name]).encode())
            self._schemas[name] = sid
        cid = self._writer.register_channel(topic, "json", sid)
        self._channels[topic] = cid
        return cid

    def _write(self, topic: str, t_wall_s: float, payload: Any) -> None:
        assert self._writer is not None
        try:
            if callable(payload):
                payload = payload()
            data = encode_json(payload)
        except (TypeError, ValueError, ArithmeticError) as exc:
            self.stats.bad_messages += 1
            self.stats.last_bad_message = f"{topic}: {type(exc).__name__}: {exc}"
            return
        ns = int(round(t_wall_s * 1e9))
        self._writer.add_message(self._channel(topic), log_time=ns, publish_time=ns, data=data)
        self.stats.written += 1
        self.stats.bytes_written += len(data)

    def _flush(self) -> None:
        assert self._writer is not None
        self._writer.flush()
        if self._fsync:
            os.fsync(self._file.fileno())

    def _run(self) -> None:
        last_flush = time.monotonic()
        try:
            while True:
                timeout = max(0.0, self._flush_s - (time.monotonic() - last_flush))
                try:
                    item = self._queue.get(timeout=timeout)
                except queue.Empty:
                    item = None
                if item is _STOP:
                    self._flush()
                    return
                if item is not None:
                    self._write(*item)
                now = time.monotonic()
                if now - last_flush >= self._flush_s:
                    self._flush()
                    last_flush = now
                    if self._file.tell() >= self._rotate_bytes or now - self._opened_at >= self._rotate_s:
                        self._finish_file()
                        self._open_file()
        except BaseException as exc:  # noqa: BLE001 - surfaced through stats.error and the daemon's status
            self.stats.error = f"{type(exc).__name__}: {exc}"


# ---------------------------------------------------------------------------------------------
# reading


@dataclass(frozen=True)
class LogMessage:
    topic: str
    log_time_ns: int
    data: dict[str, Any]


@dataclass
class LogReadResult:
    truncated: bool = False
    reason: str = ""


def read_log(path: str | Path, result: LogReadResult | None = None) -> Iterator[LogMessage]:
    """Every message in file order, JSON decoded.

    A file cut short (SIGKILL, power loss, copy in progress) yields everything up to the cut; the
    cut is reported in ``result`` (``truncated``, ``reason``) rather than raised. A file that is not
    MCAP at all raises :class:`LogFormatError`.
    """
    result = result if result is not None else LogReadResult()
    p = Path(path)
    try:
        f = open(p, "rb")  # noqa: SIM115 - closed below
    except OSError as exc:
        raise LogFormatError(f"cannot open {p}: {exc}") from exc
    with f:
        head = f.read(8)
        magic = b"\x89MCAP0\r\n"
        if head != magic:
            if magic.startswith(head):  # empty or cut inside the magic: a log that was just started
                result.truncated = True
                result.reason = f"only {len(head)} bytes"
                return
            raise LogFormatError(f"{p} is not an MCAP file")
        f.seek(0)
        channels: dict[int, str] = {}
        count = 0
        try:
            for record in StreamReader(f).records:
                if isinstance(record, Channel):
                    channels[record.id] = record.topic
                elif isinstance(record, Schema):
                    continue
                elif isinstance(record, Message):
                    topic = channels.get(record.channel_id)
                    if topic is None:
                        raise LogFormatError(f"{p}: message on unknown channel {record.channel_id}")
                    try:
                        data = json.loads(record.data)
                    except ValueError as exc:
                        raise LogFormatError(f"{p}: message {count} on {topic} is not JSON") from exc
                    count += 1
                    yield LogMessage(topic, record.log_time, data)
        except LogFormatError:
            raise
        except (McapError, struct.error, EOFError, ValueError, OSError, Exception) as exc:  # noqa: BLE001
            # a cut or corrupt tail (zstd errors included): report it, keep what was read
            result.truncated = True
            result.reason = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
