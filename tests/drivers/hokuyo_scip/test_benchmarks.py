"""pytest-benchmark figures (CI runs them once with --benchmark-disable; they never assert on time)."""

from __future__ import annotations

from typing import Any

import numpy as np

from drivers.hokuyo_scip.codec import ScanFrame, ScipDecoder, encode_data_block, encode_timestamp_line, encode_values


def _frame(intensity: bool) -> bytes:
    rng = np.random.default_rng(0)
    values = rng.integers(23, 60000, 2162 if intensity else 1081)
    echo = b"ME0000108001000" if intensity else b"MD0000108001000"
    return echo + b"\n99b\n" + encode_timestamp_line(1) + encode_data_block(encode_values(values, 3)) + b"\n"


def test_bench_decode_md_frame(benchmark: Any) -> None:
    frame = _frame(False)
    decoder = ScipDecoder()
    events = benchmark(decoder.feed, frame)
    assert len(events) == 1 and isinstance(events[0], ScanFrame) and events[0].distances.size == 1081


def test_bench_decode_me_frame(benchmark: Any) -> None:
    frame = _frame(True)
    decoder = ScipDecoder()
    events = benchmark(decoder.feed, frame)
    assert len(events) == 1 and isinstance(events[0], ScanFrame) and events[0].intensities is not None
