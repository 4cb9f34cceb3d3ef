"""Codec and odometry speed (pytest-benchmark; CI runs these with --benchmark-disable, never timed asserts)."""

from __future__ import annotations

import struct
from typing import Any

import pytest

from drivers.p2os import codec
from drivers.p2os.odometry import OdometryTracker, params_for_subclass


def _full_sip(k: int) -> bytes:
    payload = bytearray(struct.pack("<BHHhhhBHhHBB", 0x33, (k * 7) & 0x7FFF, 0, 0, 200, 200, 125, 0, 0, 0x1F, 0, 16))
    for i in range(16):
        payload += struct.pack("<BH", i, 1000 + i)
    payload += bytes(5) + struct.pack("<HBhH", 125, 0, 0, 0)
    return codec.frame(bytes(payload))


WIRE = b"".join(_full_sip(k) for k in range(100))


def test_decode_100_full_sips(benchmark: Any) -> None:
    def run() -> int:
        return sum(isinstance(e, codec.Sip) for e in codec.ArcosDecoder().feed(WIRE))

    assert benchmark(run) == 100


def test_odometry_100_sips(benchmark: Any) -> None:
    sips = [e for e in codec.ArcosDecoder().feed(WIRE) if isinstance(e, codec.Sip)]

    def run() -> float:
        tracker = OdometryTracker(params_for_subclass("p3dx"))
        s = None
        for k, sip in enumerate(sips):
            s = tracker.update(sip, k * 0.1)
        assert s is not None
        return s.x_m

    assert benchmark(run) == pytest.approx(99 * 7 * 0.485e-3, abs=1e-12)
