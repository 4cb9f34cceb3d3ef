"""A scan is paired with the camera frame taken nearest it, however late the scan reaches the loop
(``app.framesync``). Simulated clock throughout."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from app.config import Config
from app.daemon import ControlLoop, FrameSample, ScanSample
from app.framesync import RecentFrames
from tests.app.loop_fakes import FakeBase, SimClock
from vipsm.estimator import Estimator
from vipsm.types import EstimateFlag, Scan

BEARINGS = np.linspace(-0.75 * math.pi, 0.75 * math.pi, 1081)


def _sample(stamp_s: float) -> FrameSample:
    return FrameSample(SimpleNamespace(stamp_s=stamp_s), b"")  # type: ignore[arg-type]


def test_the_frame_nearest_the_scan_within_the_gap_and_never_an_older_one_than_last_time() -> None:
    frames = RecentFrames(keep=8)
    for t in (1.0, 1.1, 1.2, 1.3):
        frames.add(_sample(t))
    s = frames.nearest(1.12, max_gap_s=0.3)
    assert s is not None and s.frame.stamp_s == pytest.approx(1.1)
    assert frames.nearest(0.5, max_gap_s=0.3) is None  # nothing near enough
    s = frames.nearest(1.04, max_gap_s=0.3)  # 1.0 is nearer, but older than the frame already used
    assert s is not None and s.frame.stamp_s == pytest.approx(1.1)
    assert frames.nearest(1.9, max_gap_s=0.3) is None


def test_the_ring_is_bounded_and_a_camera_restart_starts_it_again() -> None:
    frames = RecentFrames(keep=4)
    for k in range(10):
        frames.add(_sample(float(k)))
    assert len(frames) == 4 and frames.nearest(2.0, max_gap_s=0.5) is None  # 0..5 were dropped
    newest = frames.newest
    assert newest is not None and newest.frame.stamp_s == 9.0
    s = frames.nearest(9.0, max_gap_s=0.5)
    assert s is not None and s.frame.stamp_s == 9.0
    frames.add(_sample(0.5))  # the camera's stamps went back: a new stream
    assert len(frames) == 1
    s = frames.nearest(0.5, max_gap_s=0.1)
    assert s is not None and s.frame.stamp_s == 0.5
    with pytest.raises(ValueError, match="keep"):
        RecentFrames(keep=0)


class _LateScanner:
    """A scan every 0.1 s, received ``late_s`` after it was taken (a slow link or a busy reader)."""

    def __init__(self, clock: SimClock, late_s: float) -> None:
        self.clock, self.late_s, self.k, self.t0 = clock, late_s, 0, clock.now_s

    def state(self) -> str:
        return "ok"

    def poll(self) -> list[ScanSample]:
        out = []
        while self.t0 + self.k * 0.1 + self.late_s <= self.clock.now_s:
            stamp = self.t0 + self.k * 0.1
            out.append(ScanSample(Scan(np.full(BEARINGS.size, 4.0), BEARINGS, stamp, seq=self.k),
                                  host_stamp_s=stamp + self.late_s))
            self.k += 1
        return out

    def counters(self) -> dict[str, int]:
        return {}

    def close(self) -> None:
        pass


class _Camera:
    """A frame every 0.1 s, stamped when taken and received at once."""

    def __init__(self, clock: SimClock) -> None:
        self.clock, self.next_s = clock, clock.now_s

    def state(self) -> str:
        return "ok"

    def latest(self) -> FrameSample | None:
        if self.clock.now_s < self.next_s:
            return None
        stamp, self.next_s = self.next_s, self.next_s + 0.1
        return _sample(stamp)

    def counters(self) -> dict[str, int]:
        return {}

    def close(self) -> None:
        pass


class _Recorder:
    """The real estimator, recording each (scan, frame) pair it was given; it runs without the (imageless)
    frame, and says it used the frame when it was given one."""

    def __init__(self) -> None:
        self.inner = Estimator()
        self.pairs: list[tuple[float, float | None]] = []

    def step(self, scan: Scan, odometry: object, frame: object) -> object:
        self.pairs.append((scan.stamp_s, None if frame is None else frame.stamp_s))  # type: ignore[attr-defined]
        est = self.inner.step(scan, odometry, None)  # type: ignore[arg-type]
        return est if frame is None else dataclasses.replace(est, flags=est.flags & ~EstimateFlag.NO_FRAME)


@pytest.mark.parametrize("late_s", [0.0, 0.4])
def test_a_late_scan_is_paired_with_the_frame_taken_with_it_not_the_newest(late_s: float) -> None:
    clock = SimClock()
    rec = _Recorder()
    c = Config()
    config = dataclasses.replace(c, status=dataclasses.replace(c.status, enabled=False),
                                 loop=dataclasses.replace(c.loop, max_odometry_age_s=1.0))
    loop = ControlLoop(config, scanner=_LateScanner(clock, late_s), base=FakeBase(clock), camera=_Camera(clock),
                       estimator=rec, clock=clock, wall_clock=lambda: 1.7e9)  # type: ignore[arg-type]
    for _ in range(30):
        loop.step(clock.now_s)
        clock.now_s += 0.1
    paired = [(s, f) for s, f in rec.pairs if f is not None]
    assert len(rec.pairs) >= 20 and len(paired) >= len(rec.pairs) - 1
    assert all(abs(f - s) < 0.06 for s, f in paired)  # the newest frame would be late_s from the scan
    assert loop.stats.frames_used == len(paired) and loop._states["camera"] == "ok"


def test_an_estimate_on_a_frame_it_refused_counts_as_plain_psm() -> None:
    from app.daemon import WITHOUT_CAMERA

    for flag in (EstimateFlag.NO_FRAME, EstimateFlag.PLAIN_PSM, EstimateFlag.STALE_FRAME, EstimateFlag.FRAME_ERROR,
                 EstimateFlag.NO_FLOW):
        assert flag & WITHOUT_CAMERA
    assert not EstimateFlag.BRIDGE_INVALID & WITHOUT_CAMERA
