"""Reading field logs: every message as a plain dict, whatever the log's version.

Version 2 logs (Foxglove SDK) carry the ``foxglove.*`` channels in protobuf: they are decoded with
the schema embedded in the file itself (a ``FileDescriptorSet``), so any conforming MCAP file reads,
and converted to the same dict shape as the JSON encoding of those schemas (``timestamp`` as
``{"sec", "nsec"}``, enums as integers, ``bytes`` fields as ``bytes``, floats as they were, +inf,
-inf and NaN included). Version 1 logs (JSON everywhere) read as they are.

The file is read record by record (:func:`_records`), not through a library reader that stops at
the first fault, so that one damaged part costs only itself:

* every chunk's CRC is checked (and its size, compression and records); a bad chunk is skipped,
  counted in :attr:`LogReadResult.bad_chunks` with its reason, and reading goes on with the next one;
* every record's own lengths must agree with its record length (:func:`_shape_error`), so a damaged
  length or opcode is found where it is, never followed into other records; the reader then scans
  forward for the next self-consistent chunk record and reads on from there;
* a complete file's data-section and summary CRCs are checked too (they cover chunk headers and
  indexes, which the chunk CRC does not);
* the summary's schemas and channels are read first, so messages whose channel was declared in a
  lost chunk still decode; a message on a channel the log never declares is skipped and counted.

A file cut short (SIGKILL, power loss, disk full, copy in progress) yields everything up to the cut
and reports the cut (``truncated``) rather than raising; a message that cannot be decoded is
skipped and counted; a file that is not MCAP raises :class:`LogFormatError`.
"""

from __future__ import annotations

import json
import mmap
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from google.protobuf.message import DecodeError

from .errors import LogFormatError

MAGIC = b"\x89MCAP0\r\n"
#: at most this many reasons are kept in ``LogReadResult.bad`` and ``.corruption`` (all are counted)
MAX_BAD_REASONS = 20
#: a chunk that claims to decompress to more than this is damaged (this program writes 1 MiB chunks;
#: a chunk holds at least one message, and no message of a field log comes near this)
MAX_CHUNK_BYTES = 256 * 1024 * 1024

OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_MESSAGE_INDEX, OP_ATTACHMENT, OP_METADATA, OP_DATA_END = 0x07, 0x09, 0x0C, 0x0F
#: opcodes of the MCAP specification (0x01-0x0F) and those it reserves for private records (0x80-0xFF);
#: anything else where a record should start is damage
_VALID_OPCODES = frozenset(range(0x01, 0x10)) | frozenset(range(0x80, 0x100))
_COMPRESSIONS = ("", "zstd", "lz4")


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
    #: messages that could not be decoded or name an undeclared channel (skipped), and the first reasons
    bad_messages: int = 0
    bad: list[str] = field(default_factory=list)
    #: chunks skipped because they are damaged (CRC, size, compression, records)
    bad_chunks: int = 0
    #: every damage found (bad chunks, unreadable byte ranges, CRC mismatches of the data or summary
    #: section), the first reasons
    corruption: list[str] = field(default_factory=list)
    corruption_count: int = 0

    def note_bad(self, reason: str) -> None:
        self.bad_messages += 1
        if len(self.bad) < MAX_BAD_REASONS:
            self.bad.append(reason)

    def note_corrupt(self, reason: str, *, chunk: bool = False) -> None:
        self.bad_chunks += int(chunk)
        self.corruption_count += 1
        if len(self.corruption) < MAX_BAD_REASONS:
            self.corruption.append(reason)

    @property
    def damaged(self) -> bool:
        """Something was skipped: a bad message or damaged bytes (``replay`` and ``export`` exit 3)."""
        return self.bad_messages > 0 or self.corruption_count > 0

    def summary(self) -> dict[str, Any]:
        """The read's fields of ``replay --json`` and ``export --json``."""
        return {"truncated": self.truncated, "truncation": self.reason, "bad_messages": self.bad_messages,
                "bad_message_reasons": list(self.bad), "bad_chunks": self.bad_chunks,
                "corruption": list(self.corruption)}

    def warning(self, path: str | Path) -> str | None:
        """One stderr line saying what was skipped, or None."""
        parts = []
        if self.corruption_count:
            parts.append(f"{self.corruption_count} damaged part(s) skipped ({self.bad_chunks} chunk(s)), "
                         f"the first: {self.corruption[0]}")
        if self.bad_messages:
            parts.append(f"{self.bad_messages} malformed message(s) skipped, the first: {self.bad[0]}")
        return f"vipsm-robot: warning: {path}: " + "; ".join(parts) if parts else None


class _Decoder:
    """Bytes of one channel -> dict."""

    def __init__(self, schema: _Schema | None, encoding: str) -> None:
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


def _protobuf_class(schema: _Schema) -> Any:
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


# ---------------------------------------------------------------------------------------------
# MCAP records, parsed with bounds checks (a damaged length raises ValueError, never reads past)


@dataclass(frozen=True)
class _Schema:
    id: int
    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True)
class _Channel:
    id: int
    schema_id: int
    topic: str
    message_encoding: str


@dataclass(frozen=True)
class _Message:
    channel_id: int
    log_time: int
    data: bytes


class _Cursor:
    def __init__(self, buf: memoryview) -> None:
        self.buf, self.at = buf, 0

    def take(self, n: int) -> memoryview:
        if n < 0 or self.at + n > len(self.buf):
            raise ValueError(f"a length of {n} runs past the record's end")
        out = self.buf[self.at:self.at + n]
        self.at += n
        return out

    def int(self, fmt: str) -> int:
        return int(struct.unpack(fmt, self.take(struct.calcsize(fmt)))[0])

    def string(self) -> str:
        return bytes(self.take(self.int("<I"))).decode("utf-8")


def _parse(op: int, body: memoryview) -> _Schema | _Channel | _Message | None:
    """A schema, channel or message record's body; other records: None."""
    c = _Cursor(body)
    if op == OP_SCHEMA:
        sid, name, enc = c.int("<H"), c.string(), c.string()
        return _Schema(sid, name, enc, bytes(c.take(c.int("<I"))))
    if op == OP_CHANNEL:
        cid, sid, topic, enc = c.int("<H"), c.int("<H"), c.string(), c.string()
        c.take(c.int("<I"))  # metadata map
        return _Channel(cid, sid, topic, enc)
    if op == OP_MESSAGE:
        cid, _seq, log_time, _pub = c.int("<H"), c.int("<I"), c.int("<Q"), c.int("<Q")
        return _Message(cid, log_time, bytes(body[c.at:]))
    return None


def _inner_records(data: memoryview) -> Iterator[tuple[int, memoryview]]:
    """(opcode, body) of each record in a byte run (a chunk's records, the summary section)."""
    at = 0
    while at < len(data):
        if at + 9 > len(data):
            raise ValueError(f"{len(data) - at} stray bytes after the last record")
        op, length = data[at], struct.unpack_from("<Q", data, at + 1)[0]
        if at + 9 + length > len(data):
            raise ValueError(f"record {op:#04x} of {length} bytes runs past the end")
        yield op, data[at + 9:at + 9 + length]
        at += 9 + length


def _chunk_payload(body: memoryview) -> memoryview:
    """A chunk record's records, decompressed and CRC-checked (ValueError says what is wrong)."""
    c = _Cursor(body)
    _t0, _t1, size, crc = c.int("<Q"), c.int("<Q"), c.int("<Q"), c.int("<I")
    compression = c.string()
    data = c.take(c.int("<Q"))
    if compression not in _COMPRESSIONS:
        raise ValueError(f"unknown compression {compression!r}")
    if size > MAX_CHUNK_BYTES:
        raise ValueError(f"claims {size} bytes uncompressed (more than {MAX_CHUNK_BYTES})")
    try:
        raw = _decompress(compression, data, size)
    except Exception as exc:  # noqa: BLE001 - zstd and lz4 raise their own types for damaged input
        raise ValueError(f"{compression} data does not decompress: {type(exc).__name__}: {exc}") from exc
    if len(raw) != size:
        raise ValueError(f"decompresses to {len(raw)} bytes, its header says {size}")
    if crc != 0 and zlib.crc32(raw) != crc:
        raise ValueError(f"CRC mismatch (recorded {crc:#010x}, computed {zlib.crc32(raw):#010x})")
    return memoryview(raw)


def _decompress(compression: str, data: memoryview, size: int) -> bytes:
    if compression == "zstd":
        import zstandard

        framed = zstandard.frame_content_size(data)  # -1: not in the frame header
        if framed not in (-1, size):
            raise ValueError(f"the zstd frame holds {framed} bytes, the chunk header says {size}")
        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    if compression == "lz4":
        import lz4.frame

        out = lz4.frame.LZ4FrameDecompressor().decompress(bytes(data), max_length=size + 1)
        return bytes(out)
    return bytes(data)


def _plausible_chunk(buf: Any, q: int) -> bool:
    """Whether a chunk record starts at ``q``: its lengths agree with each other and with the file,
    and a record or the end of the file follows it."""
    if q + 9 + 40 > len(buf) or buf[q] != OP_CHUNK:
        return False
    length = struct.unpack_from("<Q", buf, q + 1)[0]
    end = q + 9 + length
    clen = struct.unpack_from("<I", buf, q + 9 + 28)[0]
    if end > len(buf) or clen > 4 or q + 9 + 40 + clen > end:
        return False
    if bytes(buf[q + 9 + 32:q + 9 + 32 + clen]).decode("latin-1") not in _COMPRESSIONS:
        return False
    rlen = struct.unpack_from("<Q", buf, q + 9 + 32 + clen)[0]
    return length == 40 + clen + rlen and (end == len(buf) or buf[end] in _VALID_OPCODES)


def _next_chunk(buf: Any, start: int, stop: int) -> int | None:
    """The offset of the next plausible chunk record in ``[start, stop)``."""
    q = start
    while True:
        q = buf.find(bytes([OP_CHUNK]), q, stop)
        if q < 0:
            return None
        if _plausible_chunk(buf, q):
            return q
        q += 1


# ---------------------------------------------------------------------------------------------
# the file


class _Declared:
    """Schemas and channels seen so far (the summary's first, then the data section's)."""

    def __init__(self) -> None:
        self.schemas: dict[int, _Schema] = {}
        self.channels: dict[int, tuple[str, _Decoder | LogFormatError]] = {}

    def add(self, rec: _Schema | _Channel) -> None:
        if isinstance(rec, _Schema):
            self.schemas[rec.id] = rec
            return
        try:
            dec: _Decoder | LogFormatError = _Decoder(self.schemas.get(rec.schema_id), rec.message_encoding)
        except LogFormatError as exc:  # reported per message, the other channels still read
            dec = exc
        self.channels[rec.id] = (rec.topic, dec)


@dataclass
class _Footer:
    summary_start: int
    data_end: int  # where the data section's records stop (the summary, or the footer)


def _read_summary(buf: Any, declared: _Declared, result: LogReadResult) -> _Footer | None:
    """The footer of a complete file, its summary CRC checked and its schemas and channels declared."""
    size = len(buf)
    f0 = size - 8 - 29  # the footer record: opcode, length 20, summary_start, offset_start, crc
    if f0 < 8 or bytes(buf[size - 8:]) != MAGIC or buf[f0] != OP_FOOTER:
        return None
    length, start, _offsets, crc = struct.unpack_from("<QQQI", buf, f0 + 1)
    if length != 20 or not (start == 0 or 8 <= start <= f0):
        result.note_corrupt(f"the footer at byte {f0} is damaged; the summary is not used")
        return None
    if start == 0:
        return _Footer(0, f0)
    if crc != 0 and zlib.crc32(memoryview(buf)[start:f0 + 1 + 8 + 16]) != crc:
        result.note_corrupt(f"summary section (bytes {start}-{f0}): CRC mismatch; the summary is not used")
        return _Footer(start, f0)  # summary_start itself may be the damage: the data section ends at its data end
    try:
        for op, body in _inner_records(memoryview(buf)[start:f0]):
            rec = _parse(op, body) if op in (OP_SCHEMA, OP_CHANNEL) else None
            if rec is not None:
                declared.add(rec)  # type: ignore[arg-type]
    except (ValueError, UnicodeDecodeError) as exc:
        result.note_corrupt(f"summary section (bytes {start}-{f0}): {exc}")
    return _Footer(start, start)


def _records(buf: Any, result: LogReadResult, declared: _Declared) -> Iterator[_Schema | _Channel | _Message]:
    """The data section's schemas, channels and messages in file order, chunks opened; damage is
    skipped and reported in ``result``. The summary's schemas and channels go to ``declared`` first."""
    footer = _read_summary(buf, declared, result)
    stop = footer.data_end if footer is not None else len(buf)
    pos = 8
    while pos < stop:
        if pos + 9 > stop:
            return _cut(result, pos, f"{stop - pos} bytes of a record header")
        op, length = buf[pos], struct.unpack_from("<Q", buf, pos + 1)[0]
        end = pos + 9 + length
        body = memoryview(buf)[pos + 9:min(end, stop)]
        bad = _shape_error(op, body, pos) if end <= stop else f"a length of {length} past the end"
        if bad is not None:
            nxt = _next_chunk(buf, pos + 1, stop)
            if nxt is None and footer is None:  # the tail of a cut file (a chunk being written: its
                return _cut(result, pos, f"an unfinished record ({bad})")  # lengths not yet patched)
            result.note_corrupt(f"bytes {pos}-{nxt if nxt is not None else stop}: not a record ({bad}); skipped"
                                + (" to the next chunk" if nxt is not None else ""), chunk=op == OP_CHUNK)
            if nxt is None:
                return
            pos = nxt
            continue
        if op == OP_CHUNK:
            yield from _chunk_records(body, pos, result)
        elif op in (OP_SCHEMA, OP_CHANNEL, OP_MESSAGE):
            yield _parse(op, body)  # type: ignore[misc]  # parses: _shape_error tried it
        elif op == OP_DATA_END:
            _check_data_crc(buf, pos, body, result)
            if footer is None:
                _cut(result, end, "its summary cut short (every message is there)")
            return
        elif op == OP_FOOTER:
            return
        pos = end
    if footer is None:
        _cut(result, pos, "no footer")
    else:
        result.note_corrupt(f"the data section ends at byte {pos} without its data end record")


def _shape_error(op: int, body: memoryview, pos: int) -> str | None:
    """Why a data-section record's body does not fit its opcode (its own lengths disagree with each
    other or with the record's length), or None. A record whose length was damaged fails here, so a
    damaged length is never followed into the middle of other records."""
    if op not in _VALID_OPCODES:
        return f"opcode {op:#04x}"
    try:
        c = _Cursor(body)
        if op == OP_CHUNK:
            c.take(28)
            c.string()
            c.take(c.int("<Q"))
        elif op in (OP_SCHEMA, OP_CHANNEL, OP_MESSAGE):
            _parse(op, body)
            c.at = len(body) if op == OP_MESSAGE else _parsed_size(op, body)
        elif op == OP_MESSAGE_INDEX:
            c.take(2)
            entries = c.int("<I")
            if entries % 16:
                return "a message index whose entries are not 16 bytes each"
            c.take(entries)
        elif op == OP_HEADER:
            if pos != 8:
                return "a header record after the start"
            c.string()
            c.string()
        elif op in (OP_DATA_END, OP_FOOTER):
            c.take(4 if op == OP_DATA_END else 20)
        elif op == OP_ATTACHMENT:
            c.take(16)
            c.string()
            c.string()
            c.take(c.int("<Q"))
            c.take(4)
        elif op == OP_METADATA:
            c.string()
            c.take(c.int("<I"))
        elif op < 0x80:
            return f"a summary record ({op:#04x}) in the data section"
        else:  # a private record (0x80-0xFF): its layout is its writer's
            c.at = len(body)
    except (ValueError, struct.error, UnicodeDecodeError) as exc:
        return f"record {op:#04x}: {exc}"
    return None if c.at == len(body) else f"record {op:#04x}: its fields do not fill its length"


def _parsed_size(op: int, body: memoryview) -> int:
    """How many bytes a schema or channel record's fields take (all of its length, if it is sound)."""
    c = _Cursor(body)
    c.take(2 if op == OP_SCHEMA else 4)
    c.string()
    c.string()
    c.take(c.int("<I"))
    return c.at


def _chunk_records(body: memoryview, pos: int, result: LogReadResult) -> Iterator[_Schema | _Channel | _Message]:
    try:
        payload = _chunk_payload(body)
    except (ValueError, struct.error, UnicodeDecodeError) as exc:
        result.note_corrupt(f"chunk at byte {pos}: {exc}; skipped", chunk=True)
        return
    try:
        for op, rec_body in _inner_records(payload):
            rec = _parse(op, rec_body)
            if rec is not None:
                yield rec
    except (ValueError, struct.error, UnicodeDecodeError) as exc:  # records before the damage are kept
        result.note_corrupt(f"chunk at byte {pos}: {exc}; the rest of the chunk skipped", chunk=True)


def _check_data_crc(buf: Any, pos: int, body: memoryview, result: LogReadResult) -> None:
    recorded = struct.unpack_from("<I", body, 0)[0] if len(body) >= 4 else 0
    if recorded == 0 or result.corruption_count:  # no CRC written, or the damage is already reported
        return
    computed = zlib.crc32(memoryview(buf)[:pos])
    if computed != recorded:
        result.note_corrupt(f"data section CRC mismatch (recorded {recorded:#010x}, computed {computed:#010x}): "
                            "a chunk header, message index or other record outside the chunks' own CRCs is "
                            "damaged; every message read passed its chunk's CRC")


def _cut(result: LogReadResult, pos: int, what: str) -> None:
    result.truncated = True
    result.reason = f"the file ends at byte {pos} with {what} (cut: SIGKILL, power loss or a copy in progress)"


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
        # mapped, not read: a log may be hundreds of MB; unmapped when the last view of it goes
        buf = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
    yield from _messages(buf, result)


def _messages(buf: Any, result: LogReadResult) -> Iterator[LogMessage]:
    declared = _Declared()
    count = 0
    for rec in _records(buf, result, declared):
        if not isinstance(rec, _Message):
            declared.add(rec)
            continue
        count += 1
        msg = _decode(rec, declared, count, result)
        if msg is not None:
            yield msg


def _decode(rec: _Message, declared: _Declared, n: int, result: LogReadResult) -> LogMessage | None:
    entry = declared.channels.get(rec.channel_id)
    if entry is None:
        result.note_bad(f"message {n}: on channel {rec.channel_id}, which the log does not declare")
        return None
    topic, dec = entry
    if isinstance(dec, LogFormatError):
        result.note_bad(f"message {n} on {topic}: {dec}")
        return None
    try:
        data = dec.decode(rec.data)
    except (ValueError, RecursionError, TypeError, DecodeError) as exc:
        result.note_bad(f"message {n} on {topic}: {type(exc).__name__}: {str(exc)[:200]}")
        return None
    return LogMessage(topic, rec.log_time, data, dec.schema_name)
