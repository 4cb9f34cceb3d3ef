"""``loop.trigger = "scan"``: a cycle for every scan as it arrives, checked on a simulated clock (the
end-to-end run in test_daemon_e2e.py checks the same on the wall clock, which a busy machine slows)."""

from __future__ import annotations

import dataclasses
import math
import threading

import numpy as np

from app.config import Config
from app.daemon import ControlLoop, ScanSample
from tests.app.loop_fakes import FakeBase, SimClock
from vipsm.estimator import Estimator
from vipsm.types import Scan

SCAN_PERIOD_S = 0.025  # the UTM-30LX's 40 scans a second


def _room_ranges(bearings_rad: np.ndarray) -> np.ndarray:
    """A 6 m x 4 m room seen from its middle."""
    c, s = np.cos(bearings_rad), np.sin(bearings_rad)
    with np.errstate(divide="ignore"):
        tx = np.where(np.abs(c) > 1e-9, 3.0 / np.abs(c), np.inf)
        ty = np.where(np.abs(s) > 1e-9, 2.0 / np.abs(s), np.inf)
    return np.minimum(tx, ty)


class _Scanner:
    """Scans every 25 ms on the simulated clock; waiting for one moves the clock to it."""

    def __init__(self, clock: SimClock, silent_after_s: float = math.inf) -> None:
        self.clock = clock
        self.bearings = np.linspace(-0.75 * math.pi, 0.75 * math.pi, 1081)
        self.ranges = _room_ranges(self.bearings)
        self.next_s = clock.now_s + SCAN_PERIOD_S
        self.seq = 0
        self.delivered = 0
        self.silent_after_s = clock.now_s + silent_after_s

    def state(self) -> str:
        return "ok"

    def wait_scan(self, timeout_s: float) -> bool:
        if self.next_s >= self.silent_after_s:
            self.clock.now_s += timeout_s
            return False
        if self.next_s <= self.clock.now_s:
            return True
        if self.next_s - self.clock.now_s <= timeout_s:
            self.clock.now_s = self.next_s
            return True
        self.clock.now_s += timeout_s
        return False

    def poll(self) -> list[ScanSample]:
        out = []
        while self.next_s <= self.clock.now_s and self.next_s < self.silent_after_s:
            out.append(ScanSample(Scan(self.ranges.copy(), self.bearings, self.next_s, seq=self.seq)))
            self.seq += 1
            self.next_s += SCAN_PERIOD_S
        self.delivered += len(out)
        return out

    def counters(self) -> dict[str, int]:
        return {"scans": self.delivered}

    def close(self) -> None:
        pass


def _loop(trigger: str, clock: SimClock, scanner: _Scanner) -> ControlLoop:
    base = Config()
    config = dataclasses.replace(base, loop=dataclasses.replace(base.loop, trigger=trigger, period_s=0.1),
                                 status=dataclasses.replace(base.status, enabled=False))
    return ControlLoop(config, scanner=scanner, base=FakeBase(clock), camera=None, estimator=Estimator(plain_psm=True),
                       clock=clock, wall_clock=lambda: 1.7e9)


def test_a_scan_triggered_loop_estimates_on_every_scan() -> None:
    clock = SimClock()
    scanner = _Scanner(clock)
    loop = _loop("scan", clock, scanner)
    loop.run(threading.Event(), duration_s=2.0)
    assert scanner.delivered == 80  # 2 s at 40 scans a second
    assert loop.stats.estimates == scanner.delivered  # every scan, none superseded unused


def test_a_timer_loop_estimates_on_the_newest_scan_once_per_period() -> None:
    """The contrast: with the 0.1 s timer, four scans arrive per cycle and only the newest is used."""
    clock = SimClock()
    scanner = _Scanner(clock)
    loop = _loop("timer", clock, scanner)
    stop = threading.Event()
    stop.wait = lambda timeout=None: _advance(clock, timeout)  # type: ignore[method-assign]
    loop.run(stop, duration_s=2.0)
    assert 19 <= loop.stats.estimates <= 21 and scanner.delivered >= 4 * (loop.stats.estimates - 1)


def _advance(clock: SimClock, timeout_s: float | None) -> bool:
    clock.now_s += timeout_s or 0.0
    return False


def test_a_scan_triggered_loop_still_cycles_when_the_scanner_falls_silent() -> None:
    """Without scans a cycle still runs every period: the stall is noticed and the base stopped."""
    clock = SimClock()
    scanner = _Scanner(clock, silent_after_s=0.5)
    loop = _loop("scan", clock, scanner)
    loop.run(threading.Event(), duration_s=2.0)
    assert scanner.delivered == 19  # scans at 25, 50, ... 475 ms
    assert loop._states["scanner"] == "stalled" and loop.mission_state == "device_stop"
    assert loop.base is not None and loop.base.commands[-1] == (0.0, 0.0)  # type: ignore[attr-defined]
