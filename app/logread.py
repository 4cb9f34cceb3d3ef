"""Reading field logs: every message as a plain dict, whatever the log's version.

Version 2 logs (Foxglove SDK) carry the ``foxglove.*`` channels in protobuf: they are decoded with
the schema embedded in the file itself (a ``FileDescriptorSet``), so any conforming MCAP file reads,
and converted to the same dict shape as the JSON encoding of those schemas (``timestamp`` as
``{"sec", "nsec"}``, enums as integers, ``bytes`` fields as ``bytes``, floats as they were, +inf,
-inf and NaN included). Version 1 logs (JSON everywhere) read as they are.

A file cut short (SIGKILL, power loss, disk full, copy in progress) yields everything up to the cut
and reports the cut in :class:`LogReadResult` rather than raising; a message that cannot be decoded
is skipped and counted there; a file that is not MCAP raises :class:`LogFormatError`.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from google.protobuf.message import DecodeError
from mcap.exceptions import McapError
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader

from .errors import LogFormatError

MAGIC = b"\x89MCAP0\r\n"
#: at most this many decode failures are described in ``LogReadResult.bad`` (all are counted)
MAX_BAD_REASONS = 20


@dataclass(frozen=True)
class LogMessage:
    topic: str
    log_time_ns: int
    data: dict[str, Any]
    schema: str = ""


@dataclass
class LogReadResult:
    truncated: bool = False
    reason: str = ""
    #: messages that could not be decoded (skipped), and the first few reasons
    bad_messages: int = 0
    bad: list[str] = field(default_factory=list)

    def note_bad(self, reason: str) -> None:
        self.bad_messages += 1
        if len(self.bad) < MAX_BAD_REASONS:
            self.bad.append(reason)


class _Decoder:
    """Bytes of one channel -> dict."""

    def __init__(self, schema: Schema | None, encoding: str) -> None:
        self.encoding = encoding
        self.schema_name = schema.name if schema is not None else ""
        self._cls: Any = None
        if encoding == "protobuf":
            if schema is None or schema.encoding != "protobuf":
                raise LogFormatError("a protobuf channel without a protobuf schema")
            self._cls = _protobuf_class(schema)
        elif encoding != "json":
            raise LogFormatError(f"message encoding {encoding!r} is not one this program writes")

    def decode(self, data: bytes) -> dict[str, Any]:
        if self._cls is None:
            value = json.loads(data)
            if not isinstance(value, dict):
                raise ValueError(f"a JSON {type(value).__name__}, not an object")
            return value
        return proto_to_dict(self._cls.FromString(data))


def _protobuf_class(schema: Schema) -> Any:
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    try:
        fds = descriptor_pb2.FileDescriptorSet.FromString(schema.data)
        pool = descriptor_pool.DescriptorPool()
        pending = list(fds.file)
        while pending:  # dependencies first, whatever order the set lists them in
            ready = [f for f in pending if all(_has_file(pool, d) for d in f.dependency)]
            if not ready:
                raise LogFormatError(f"schema {schema.name!r}: unresolved imports {[f.name for f in pending]}")
            for f in ready:
                pool.Add(f)
                pending.remove(f)
        return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
    except LogFormatError:
        raise
    except Exception as exc:  # noqa: BLE001 - protobuf raises many types for a crafted descriptor
        raise LogFormatError(f"schema {schema.name!r} is not a usable protobuf descriptor: {exc}") from exc


def _has_file(pool: Any, name: str) -> bool:
    try:
        pool.FindFileByName(name)
        return True
    except KeyError:
        return False


_TIME_TYPES = ("google.protobuf.Timestamp", "google.protobuf.Duration")


def proto_to_dict(msg: Any) -> dict[str, Any]:
    """A decoded protobuf message as the dict its JSON encoding would give (field names as in the
    schema, times as ``{"sec", "nsec"}``, enums as integers, bytes as bytes)."""
    if msg.DESCRIPTOR.full_name in _TIME_TYPES:
        return {"sec": msg.seconds, "nsec": msg.nanos}
    out: dict[str, Any] = {}
    for fd in msg.DESCRIPTOR.fields:
        value = getattr(msg, fd.name)
        if fd.message_type is not None:
            out[fd.name] = [proto_to_dict(v) for v in value] if _repeated(fd) else proto_to_dict(value)
        else:
            out[fd.name] = list(value) if _repeated(fd) else value
    return out


def _repeated(fd: Any) -> bool:
    flag = getattr(fd, "is_repeated", None)
    return bool(flag) if flag is not None else fd.label == fd.LABEL_REPEATED


def read_log(path: str | Path, result: LogReadResult | None = None) -> Iterator[LogMessage]:
    """Every message in file order, decoded to a dict."""
    result = result if result is not None else LogReadResult()
    p = Path(path)
    try:
        f = open(p, "rb")  # noqa: SIM115 - closed below
    except OSError as exc:
        raise LogFormatError(f"cannot open {p}: {exc}") from exc
    with f:
        head = f.read(8)
        if head != MAGIC:
            if MAGIC.startswith(head):  # empty or cut inside the magic: a log that was just started
                result.truncated = True
                result.reason = f"only {len(head)} bytes"
                return
            raise LogFormatError(f"{p} is not an MCAP file")
        f.seek(0)
        yield from _messages(p, f, result)


def _messages(p: Path, f: Any, result: LogReadResult) -> Iterator[LogMessage]:
    schemas: dict[int, Schema] = {}
    channels: dict[int, tuple[str, _Decoder | LogFormatError]] = {}
    count = 0
    try:
        for record in StreamReader(f).records:
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = (record.topic, _decoder(schemas.get(record.schema_id), record))
            elif isinstance(record, Message):
                count += 1
                msg = _decode(p, record, channels, count, result)
                if msg is not None:
                    yield msg
    except LogFormatError:
        raise
    except (McapError, struct.error, EOFError, ValueError, OSError, Exception) as exc:  # noqa: BLE001
        # a cut or corrupt tail (zstd errors included): report it, keep what was read
        result.truncated = True
        result.reason = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__


def _decoder(schema: Schema | None, channel: Channel) -> _Decoder | LogFormatError:
    try:
        return _Decoder(schema, channel.message_encoding)
    except LogFormatError as exc:  # reported per message, the other channels still read
        return exc


def _decode(p: Path, record: Message, channels: dict[int, tuple[str, _Decoder | LogFormatError]], n: int,
            result: LogReadResult) -> LogMessage | None:
    entry = channels.get(record.channel_id)
    if entry is None:
        raise LogFormatError(f"{p}: message on unknown channel {record.channel_id}")
    topic, dec = entry
    if isinstance(dec, LogFormatError):
        result.note_bad(f"message {n} on {topic}: {dec}")
        return None
    try:
        data = dec.decode(record.data)
    except (ValueError, RecursionError, TypeError, DecodeError) as exc:
        result.note_bad(f"message {n} on {topic}: {type(exc).__name__}: {str(exc)[:200]}")
        return None
    return LogMessage(topic, record.log_time, data, dec.schema_name)
