"""Reading damaged field logs (issue 32 rows 5 and 6): every chunk's CRC is checked, a bad chunk is
skipped and counted and the chunks after it are read, a damaged record header is skipped to the next
chunk, a message on an undeclared channel is skipped and counted; no damaged message is ever
delivered."""

from __future__ import annotations

import json
import random
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.records import Chunk
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from app import logmessages as lm
from app.fieldlog import FieldLog
from app.logread import LogReadResult, read_log

N_MESSAGES = 60


def write_chunked(path: Path, n: int = N_MESSAGES, chunk_size: int = 600, compression: CompressionType =
                  CompressionType.ZSTD, data_crc: bool = True) -> None:
    """A JSON log of ``n`` messages ``{"i": k}`` in many small chunks, with a summary."""
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=chunk_size, compression=compression, enable_data_crcs=data_crc)
        w.start()
        sid = w.register_schema("vipsm.LoopDiagnostics", "jsonschema", b"{}")
        cid = w.register_channel("/diagnostics", "json", sid)
        for k in range(n):
            w.add_message(cid, log_time=k, publish_time=k, data=json.dumps({"i": k, "pad": "x" * 40}).encode())
        w.finish()


def chunk_offsets(path: Path) -> list[tuple[int, int]]:
    """(offset, length) of each chunk record, found independently of the reader under test."""
    data = path.read_bytes()
    out, pos = [], 8
    while pos + 9 <= len(data):
        op, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        if op == 0x06:
            out.append((pos, length))
        if op in (0x0F, 0x02):
            break
        pos += 9 + length
    return out


def read(path: Path) -> tuple[list[int], LogReadResult]:
    result = LogReadResult()
    return [m.data["i"] for m in read_log(path, result)], result


def flip(path: Path, offset: int, bit: int = 0) -> None:
    data = bytearray(path.read_bytes())
    data[offset] ^= 1 << bit
    path.write_bytes(bytes(data))


def test_a_corrupt_chunk_is_skipped_counted_and_the_chunks_after_it_are_read(tmp_path: Path) -> None:
    log = tmp_path / "log.mcap"
    write_chunked(log)
    chunks = chunk_offsets(log)
    assert len(chunks) >= 5
    with open(log, "rb") as f:
        per_chunk = [sum(1 for _ in _chunk_messages(c)) for c in StreamReader(f, emit_chunks=True).records
                     if isinstance(c, Chunk)]
    off, length = chunks[2]
    flip(log, off + 9 + length - 3)  # inside the compressed records of the third chunk
    got, result = read(log)
    lost = set(range(N_MESSAGES)) - set(got)
    assert len(lost) == per_chunk[2] and got == sorted(got)
    assert max(got) == N_MESSAGES - 1, "the chunks after the bad one must be read"
    assert result.bad_chunks == 1 and not result.truncated and result.damaged
    assert f"chunk at byte {off}" in result.corruption[0]


def _chunk_messages(chunk: Chunk) -> list[object]:
    from mcap.stream_reader import breakup_chunk

    return [r for r in breakup_chunk(chunk) if type(r).__name__ == "Message"]


@pytest.mark.parametrize("compression", [CompressionType.ZSTD, CompressionType.LZ4, CompressionType.NONE])
def test_a_chunk_crc_mismatch_is_found_whatever_the_compression(tmp_path: Path, compression: CompressionType) -> None:
    """A flip in an uncompressed chunk's records decodes fine as JSON; only the CRC tells."""
    log = tmp_path / "log.mcap"
    write_chunked(log, compression=compression)
    off, length = chunk_offsets(log)[1]
    flip(log, off + 9 + length - 5, bit=1)
    got, result = read(log)
    assert result.bad_chunks == 1 and ("CRC" in result.corruption[0] or "decompress" in result.corruption[0])
    assert max(got) == N_MESSAGES - 1


def test_a_damaged_chunk_length_is_skipped_to_the_next_chunk(tmp_path: Path) -> None:
    log = tmp_path / "log.mcap"
    write_chunked(log)
    off, _ = chunk_offsets(log)[1]
    flip(log, off + 1 + 6, bit=3)  # the length field now points far past the end of the file
    got, result = read(log)
    assert max(got) == N_MESSAGES - 1 and 0 in got
    assert not result.truncated and result.corruption_count >= 1 and "skipped to the next chunk" in result.corruption[0]


def test_the_first_chunk_lost_the_channels_come_from_the_summary(tmp_path: Path) -> None:
    log = tmp_path / "log.mcap"
    write_chunked(log)
    off, length = chunk_offsets(log)[0]  # holds the schema and channel records
    flip(log, off + 9 + length - 2)
    got, result = read(log)
    assert result.bad_chunks == 1 and result.bad_messages == 0
    assert got and max(got) == N_MESSAGES - 1


def test_a_message_on_an_undeclared_channel_is_skipped_and_counted(tmp_path: Path) -> None:
    log = tmp_path / "log.mcap"
    with open(log, "wb") as f:
        w = Writer(f, use_chunking=False, repeat_channels=False)
        w.start()
        sid = w.register_schema("vipsm.LoopDiagnostics", "jsonschema", b"{}")
        cid = w.register_channel("/diagnostics", "json", sid)
        for k in range(4):
            w.add_message(cid + 7 if k == 1 else cid, log_time=k, publish_time=k, data=json.dumps({"i": k}).encode())
        w.finish()
    got, result = read(log)
    assert got == [0, 2, 3]
    assert result.bad_messages == 1 and "does not declare" in result.bad[0] and not result.truncated


def test_single_bit_flips_are_found_or_harmless_and_never_deliver_a_damaged_message(tmp_path: Path) -> None:
    """A log written by the Foxglove SDK as the daemon writes it (data-section and chunk CRCs), one bit
    flipped at a time across the whole file."""
    src = tmp_path / "sdk.mcap"
    log = FieldLog(str(src), flush_s=0.05).start()
    t0 = time.time()
    for i in range(30):
        log.log("/diagnostics", t0 + i, {"i": i})
        log.log("/scan", t0 + i, lm.laser_scan([1.0, 2.0, float("inf")], -1.0, 1.0, None, t0 + i))
        if i % 10 == 9:
            time.sleep(0.15)  # a chunk closes after 0.6 * flush_s
    log.close()
    original = src.read_bytes()
    ref = [(m.topic, m.log_time_ns, repr(m.data)) for m in read_log(src)]
    with open(src, "rb") as f:
        largest_chunk = max(len(_chunk_messages(c)) for c in StreamReader(f, emit_chunks=True).records
                            if isinstance(c, Chunk))
    rng = random.Random(5)
    damaged = tmp_path / "flip.mcap"
    silent = []
    for _ in range(400):
        pos, bit = rng.randrange(8, len(original)), rng.randrange(8)
        data = bytearray(original)
        data[pos] ^= 1 << bit
        damaged.write_bytes(bytes(data))
        result = LogReadResult()
        got = [(m.topic, m.log_time_ns, repr(m.data)) for m in read_log(damaged, result)]
        assert set(got) <= set(ref), f"flip at byte {pos} bit {bit} delivered a damaged message"
        assert len(ref) - len(got) <= largest_chunk, f"flip at byte {pos} bit {bit} lost more than one chunk"
        if got != ref and not (result.damaged or result.truncated):
            silent.append(pos)
    assert not silent, f"flips lost messages silently at bytes {silent}"


def test_a_cut_file_is_truncated_not_corrupt_wherever_it_is_cut(tmp_path: Path) -> None:
    log = tmp_path / "log.mcap"
    write_chunked(log)
    data = log.read_bytes()
    cut = tmp_path / "cut.mcap"
    for n in range(8, len(data) - 1, 5):
        cut.write_bytes(data[:n])
        got, result = read(cut)
        assert got == list(range(len(got))) and result.truncated and not result.corruption, n


def test_replay_reports_a_bad_chunk_with_exit_3(tmp_path: Path) -> None:
    from tests.app.test_replay_crafted import good_cycle

    log = tmp_path / "log.mcap"
    with open(log, "wb") as f:
        w = Writer(f, chunk_size=2000)
        w.start()
        cid = w.register_channel("/vipsm/cycle", "json", w.register_schema("vipsm.Cycle", "jsonschema", b"{}"))
        for k in range(12):
            w.add_message(cid, log_time=k, publish_time=k, data=json.dumps(good_cycle(k)).encode())
        w.finish()
    off, length = chunk_offsets(log)[1]
    flip(log, off + 9 + length - 4)
    proc = subprocess.run([sys.executable, "-m", "app", "replay", str(log), "--json"], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 3, proc.stderr
    out = json.loads(proc.stdout)
    assert out["bad_chunks"] == 1 and "chunk at byte" in out["corruption"][0] and out["cycles"] < 12
    assert "damaged part" in proc.stderr and "Traceback" not in proc.stderr


def test_a_damaged_footer_or_message_index_costs_no_message(tmp_path: Path) -> None:
    """Records outside the chunks: a damaged footer (its summary_start) or message index length is
    reported, and every message is still read."""
    log = tmp_path / "log.mcap"
    write_chunked(log, data_crc=False)
    data = log.read_bytes()
    footer = len(data) - 8 - 29
    off, length = chunk_offsets(log)[1]
    index = off + 9 + length  # the message index record after the second chunk
    assert data[index] == 0x07
    for pos in (footer + 9 + 2, index + 1 + 1):
        damaged = tmp_path / f"flip{pos}.mcap"
        damaged.write_bytes(data)
        flip(damaged, pos, bit=4)
        got, result = read(damaged)
        assert got == list(range(N_MESSAGES)), pos
        assert result.corruption_count >= 1 and result.damaged, pos


def structure_bytes(path: Path) -> list[int]:
    """Offsets of every byte of the data section that no chunk CRC covers: record headers, chunk
    headers, message indexes, the data end; and the footer."""
    data = path.read_bytes()
    out, pos = [], 8
    while pos + 9 <= len(data):
        op, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        if op == 0x06:
            clen = struct.unpack_from("<I", data, pos + 9 + 28)[0]
            out += range(pos, pos + 9 + 40 + clen)
        else:
            out += range(pos, pos + 9 + length)
        if op == 0x0F:
            break
        pos += 9 + length
    return out + list(range(len(data) - 8 - 29, len(data) - 8))


def test_every_flip_outside_the_chunk_payloads_is_reported_and_costs_at_most_one_chunk(tmp_path: Path) -> None:
    """Exhaustive over the bytes a chunk CRC does not cover (where a damaged length could lead the
    reader astray): each is reported, and at most one chunk's messages are lost."""
    log = tmp_path / "log.mcap"
    write_chunked(log, data_crc=True)
    with open(log, "rb") as f:
        largest = max(len(_chunk_messages(c)) for c in StreamReader(f, emit_chunks=True).records
                      if isinstance(c, Chunk))
    original = log.read_bytes()
    damaged = tmp_path / "flip.mcap"
    for pos in structure_bytes(log):
        data = bytearray(original)
        data[pos] ^= 1 << (pos % 8)
        damaged.write_bytes(bytes(data))
        got, result = read(damaged)
        assert result.damaged or result.truncated or got == list(range(N_MESSAGES)), f"silent loss, byte {pos}"
        assert N_MESSAGES - len(got) <= largest and got == sorted(got), f"byte {pos}: {N_MESSAGES - len(got)} lost"


def test_a_file_cut_while_a_chunk_was_written_is_truncated_not_corrupt(tmp_path: Path) -> None:
    """A writer streams a chunk and patches its lengths afterwards: a file cut in between ends with a
    chunk whose length fields are still placeholders. That is a cut (exit 0 in replay), not damage."""
    log = tmp_path / "log.mcap"
    write_chunked(log)
    off, length = chunk_offsets(log)[3]
    data = bytearray(log.read_bytes()[: off + 9 + length // 2])
    data[off + 1: off + 9] = bytes(8)  # the record length, not yet patched
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(bytes(data))
    got, result = read(cut)
    assert result.truncated and not result.damaged and got == list(range(len(got))) and got
