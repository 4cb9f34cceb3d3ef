"""Issue 32 row 13: a loop the CPU cannot keep up with degrades gracefully instead of flapping between
"scanner stalled" and ok. Simulated clock; the estimator's slowness is injected (no wall-clock speed)."""

from __future__ import annotations

import dataclasses
import math
import threading

import numpy as np
import pytest

from app.config import Config
from app.daemon import ControlLoop, ScanSample
from app.health import OverloadMonitor
from tests.app.loop_fakes import FakeBase, SimClock
from vipsm.estimator import Estimator
from vipsm.types import Scan

SCAN_PERIOD_S = 0.025
BEARINGS = np.linspace(-0.75 * math.pi, 0.75 * math.pi, 1081)


def _room(b: np.ndarray) -> np.ndarray:
    c, s = np.cos(b), np.sin(b)
    with np.errstate(divide="ignore"):
        return np.minimum(np.where(np.abs(c) > 1e-9, 3.0 / np.abs(c), np.inf),
                          np.where(np.abs(s) > 1e-9, 2.0 / np.abs(s), np.inf))


class _StarvedScanner:
    """A scan every 25 ms; its reader thread cannot run while the estimator holds the interpreter, so a
    scan taken then is received only 2 ms after the estimator returns (what a busy CPython does)."""

    def __init__(self, clock: SimClock) -> None:
        self.clock = clock
        self.blocked: list[tuple[float, float]] = []
        self.k = 0
        self.t0 = clock.now_s
        self.delivered = 0

    def _receipt(self, k: int) -> float:
        t = self.t0 + (k + 1) * SCAN_PERIOD_S
        for a, b in self.blocked:
            if a <= t < b:
                return b + 0.002
        return t + 0.001

    def state(self) -> str:
        return "ok"

    def wait_scan(self, timeout_s: float) -> bool:
        r = self._receipt(self.k)
        if r <= self.clock.now_s:
            return True
        if r - self.clock.now_s <= timeout_s:
            self.clock.now_s = r
            return True
        self.clock.now_s += timeout_s
        return False

    def poll(self) -> list[ScanSample]:
        out = []
        while self._receipt(self.k) <= self.clock.now_s:
            stamp = self.t0 + self.k * SCAN_PERIOD_S
            scan = Scan(_room(BEARINGS), BEARINGS, stamp, seq=self.k)
            out.append(ScanSample(scan, host_stamp_s=self._receipt(self.k)))
            self.k += 1
        self.delivered += len(out)
        return out

    def counters(self) -> dict[str, int]:
        return {}

    def close(self) -> None:
        pass


class _SlowEstimator:
    """The real estimator, taking ``compute_s`` of simulated time, during which the reader is blocked."""

    def __init__(self, clock: SimClock, scanner: _StarvedScanner, compute_s: float) -> None:
        self.inner, self.clock, self.scanner, self.compute_s = Estimator(plain_psm=True), clock, scanner, compute_s

    def step(self, *args: object) -> object:
        est = self.inner.step(*args)  # type: ignore[arg-type]
        start = self.clock.now_s
        self.clock.now_s += self.compute_s
        self.scanner.blocked.append((start, self.clock.now_s))
        return est


def _loop(compute_s: float, trigger: str = "scan") -> tuple[ControlLoop, SimClock, _StarvedScanner, _SlowEstimator]:
    clock = SimClock()
    scanner = _StarvedScanner(clock)
    est = _SlowEstimator(clock, scanner, compute_s)
    c = Config()
    config = dataclasses.replace(c, loop=dataclasses.replace(c.loop, trigger=trigger, period_s=0.1),
                                 mission=dataclasses.replace(c.mission, mode="cruise"),
                                 status=dataclasses.replace(c.status, enabled=False))
    loop = ControlLoop(config, scanner=scanner, base=FakeBase(clock), camera=None, estimator=est,  # type: ignore[arg-type]
                       clock=clock, wall_clock=lambda: 1.7e9)
    return loop, clock, scanner, est


def _run_for(loop: ControlLoop, clock: SimClock, seconds: float, trigger: str = "scan") -> None:
    stop = threading.Event()
    if trigger == "timer":
        def wait(timeout: float | None = None) -> bool:
            clock.now_s += timeout or 0.0
            return False
        stop.wait = wait  # type: ignore[method-assign]
    loop.run(stop, duration_s=seconds)


def test_a_late_loop_is_overloaded_not_a_stalled_scanner(capsys: pytest.CaptureFixture[str]) -> None:
    """The audit's case: each estimate takes 254 ms at 40 scans a second."""
    loop, clock, scanner, est = _loop(0.254)
    _run_for(loop, clock, 10.0)
    err = capsys.readouterr().err
    assert "scanner: ok -> stalled" not in err and loop.stats.device_stop_cycles == 0
    assert loop.mission_state == "moving"
    assert err.count("loop: overloaded") == 1 and "obstacles from 1 scan in 15" in err  # ceil(254 / 25 / 0.7)
    assert loop.overload.overloaded and loop.overload.transitions == 1
    # the newest scan each time, the rest skipped and counted; obstacles at the lower rate
    s = loop.stats
    assert s.estimates + s.scans_skipped + 1 >= scanner.delivered > 300
    assert 10.0 / (15 * SCAN_PERIOD_S + 0.254) - 2 <= s.estimates <= 10.0 / (14 * SCAN_PERIOD_S) + 2
    assert s.overload_cycles > 0.9 * loop.health.cycles
    # the estimator gets quick again: overload ends, once, and every scan is estimated again
    est.compute_s = 0.005
    before = s.estimates
    _run_for(loop, clock, 5.0)
    err = capsys.readouterr().err
    assert err.count("loop: overload over") == 1 and "loop: overloaded" not in err
    assert not loop.overload.overloaded and s.estimates - before > 0.8 * 5.0 / SCAN_PERIOD_S


def test_a_timer_loop_under_overload_keeps_the_scanner_ok() -> None:
    loop, clock, _, _ = _loop(0.254, trigger="timer")
    _run_for(loop, clock, 10.0, trigger="timer")
    assert loop._states["scanner"] == "ok" and loop.stats.device_stop_cycles == 0
    assert loop.overload.overloaded and loop.overload.every == 4  # ceil(2.54 / 0.7)


def test_a_scanner_that_falls_silent_is_still_stalled_under_overload() -> None:
    loop, clock, scanner, _ = _loop(0.254)
    _run_for(loop, clock, 2.0)
    scanner._receipt = lambda k: math.inf  # type: ignore[method-assign]
    _run_for(loop, clock, 1.0)
    assert loop._states["scanner"] == "stalled" and loop.mission_state == "device_stop"


def test_overload_has_hysteresis() -> None:
    m = OverloadMonitor(enter_load=1.0, leave_load=0.7, window=1, leave_after=3)
    assert not m.record(0.020, 0.025) and not m.overloaded  # load 0.8
    assert m.record(0.030, 0.025) and m.overloaded and m.every == 2  # load 1.2: enter
    assert not m.record(0.020, 0.025) and m.overloaded  # 0.8: inside the band, stays
    assert not m.record(0.017, 0.025) and not m.record(0.017, 0.025) and m.overloaded  # 0.68 twice: dwell
    assert not m.record(0.020, 0.025) and m.overloaded  # back in the band: the dwell starts over
    for _ in range(2):
        assert not m.record(0.017, 0.025)
    assert m.record(0.017, 0.025) and not m.overloaded and m.every == 1  # three in a row: leave
    assert m.transitions == 1


def test_one_slow_estimate_is_no_overload_but_most_of_the_recent_ones_are() -> None:
    m = OverloadMonitor()  # median of the last 5
    for _ in range(5):
        m.record(0.010, 0.025)
    assert not m.record(0.655, 0.025) and not m.overloaded  # a kernel compiled late, a GC pause
    for _ in range(4):
        assert not m.record(0.010, 0.025) and not m.overloaded
    m.record(0.060, 0.025)
    m.record(0.060, 0.025)
    assert not m.overloaded  # two of the last five slow: the median still keeps up
    assert m.record(0.060, 0.025) and m.overloaded and m.every == 4  # three of five: ceil(2.4 / 0.7)


def test_overload_is_reported_in_the_status_registers() -> None:
    from app.status import STATUS_BITS, encode_registers

    loop, clock, _, _ = _loop(0.254)
    published: list[object] = []
    loop.status = type("S", (), {"publish": published.append, "stop_requested": False, "stop": lambda self: None})()
    _run_for(loop, clock, 2.0)
    regs = encode_registers(published[-1])  # type: ignore[arg-type]
    assert regs[0] & (1 << STATUS_BITS["overloaded"]) and regs[54] == 15
    assert loop.safety_summary()["overload_episodes"] == 1
