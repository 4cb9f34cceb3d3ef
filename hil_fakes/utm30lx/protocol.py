"""SCIP 2.0 encoding for the fake UTM-30LX: checksums, character encoding, data blocks, reply lines
(independent of drivers/hokuyo_scip)."""

from __future__ import annotations

import numpy as np

from .source import _MASK24

# --------------------------------------------------------------------------------------------
# Wire helpers (independent of the driver's codec)
# --------------------------------------------------------------------------------------------


def scip_sum(content: bytes) -> bytes:
    """The one-byte SCIP checksum of ``content``."""
    return bytes([(sum(content) & 0x3F) + 0x30])


def encode(values: np.ndarray, width: int) -> bytes:
    """``width`` characters per value, 6 bits each, most significant first (values must fit)."""
    v = np.asarray(values, dtype=np.int64).reshape(-1, 1)
    shifts = 6 * np.arange(width - 1, -1, -1, dtype=np.int64).reshape(1, -1)
    return (((v >> shifts) & 0x3F) + 0x30).astype(np.uint8).tobytes()


def data_block(chars: bytes) -> bytes:
    """64-character lines, each with its sum and LF; the closing empty line is not included."""
    n = len(chars)
    if n == 0:
        return b""
    rows = -(-n // 64)
    padded = np.zeros(rows * 64, dtype=np.uint8)
    padded[:n] = np.frombuffer(chars, dtype=np.uint8)
    grid = padded.reshape(rows, 64)
    sums = ((grid.sum(axis=1, dtype=np.int64) & 0x3F) + 0x30).astype(np.uint8)
    out = np.empty((rows, 66), dtype=np.uint8)
    out[:, :64] = grid
    out[:, 64] = sums
    out[:, 65] = 0x0A
    flat = out.reshape(-1).tobytes()
    tail = n - (rows - 1) * 64
    if tail == 64:
        return flat
    # the last line is shorter: rebuild it with its own sum
    last = chars[(rows - 1) * 64 :]
    return flat[: (rows - 1) * 66] + last + scip_sum(last) + b"\n"


def status_line(code: str) -> bytes:
    raw = code.encode("ascii")
    return raw + scip_sum(raw) + b"\n"


def info_line(key: str, value: str) -> bytes:
    content = f"{key}:{value}".encode("ascii")
    return content + b";" + scip_sum(content) + b"\n"


def time_line(ms: int) -> bytes:
    chars = encode(np.array([ms & _MASK24]), 4)
    return chars + scip_sum(chars) + b"\n"
