"""The 24-bit clock: wraps vs resets, and the TM round-trip offset."""

from __future__ import annotations

import pytest

from drivers.hokuyo_scip.errors import ScipConfigError
from drivers.hokuyo_scip.timebase import TIMESTAMP_MODULUS, ClockOffsetEstimator, TimestampUnwrapper


def test_wrap_is_continuous() -> None:
    u = TimestampUnwrapper()
    a = u.update(TIMESTAMP_MODULUS - 10, 100.0)
    b = u.update(15, 100.025)
    assert b.unwrapped_ms - a.unwrapped_ms == 25 and b.epoch == a.epoch and u.wraps == 1 and u.resets == 0


def test_reset_to_zero_is_a_reset_not_a_wrap() -> None:
    u = TimestampUnwrapper()
    u.update(5000, 10.0)
    b = u.update(30, 10.5)  # RS: the counter restarted
    assert b.epoch == 1 and b.unwrapped_ms == 30 and u.resets == 1 and u.wraps == 0


def test_reset_near_the_top_is_not_taken_for_a_wrap_when_host_time_disagrees() -> None:
    u = TimestampUnwrapper(tolerance_ms=500)
    u.update(TIMESTAMP_MODULUS - 200, 0.0)
    b = u.update(100, 5.0)  # modular step 300 ms, but 5 s passed on the host: a reset
    assert b.epoch == 1 and u.resets == 1 and u.wraps == 0


def test_slightly_older_stamp_is_continuous() -> None:
    u = TimestampUnwrapper()
    a = u.update(10_000, 1.0)  # a TM1 reading
    b = u.update(9_985, 1.01)  # a scan whose step 0 was 15 ms before it
    assert b.epoch == a.epoch and b.unwrapped_ms == a.unwrapped_ms - 15


def test_announced_reset_starts_a_new_epoch() -> None:
    u = TimestampUnwrapper()
    u.update(123, 0.0)
    u.reset()
    b = u.update(125, 0.002)
    assert b.epoch == 1 and b.unwrapped_ms == 125
    with pytest.raises(ScipConfigError):
        u.update(TIMESTAMP_MODULUS, 0.0)


def test_offset_is_the_median_of_midpoints() -> None:
    est = ClockOffsetEstimator()
    # device = host - 100 s; round trips of 2 ms, one slow outlier
    for host, rtt in [(200.0, 0.002), (200.01, 0.002), (200.02, 0.050), (200.03, 0.002), (200.04, 0.002)]:
        est.add(host, host + rtt, round((host + rtt / 2 - 100.0) * 1000))
    off = est.estimate(epoch=3)
    assert off.offset_s == pytest.approx(100.0, abs=0.001)
    assert off.samples == 5 and off.epoch == 3 and off.round_trip_s == pytest.approx(0.002)
    with pytest.raises(ScipConfigError):
        est.add(1.0, 0.5, 0)
    with pytest.raises(ScipConfigError):
        ClockOffsetEstimator().estimate(0)


def test_drift_tracker_follows_the_lower_envelope() -> None:
    from drivers.hokuyo_scip.timebase import ClockOffset, DriftTracker

    tracker = DriftTracker(window_s=1.0, min_frames=5)
    assert tracker.update(0, 0.0) is None  # no TM offset yet
    tracker.reset(ClockOffset(offset_s=100.0, epoch=0, samples=10, spread_s=0.0, round_trip_s=0.001))
    drift = 0.001  # the device clock runs 1000 ppm slow: host - device grows 1 ms per s
    out = None
    for k in range(400):  # 10 s of 40 Hz frames, latency 20 ms + noise that is never negative
        host = 100.0 + k * 0.025 + 0.020 + (0.004 if k % 3 else 0.0)
        device_ms = round((host - 0.020 - (0.004 if k % 3 else 0.0) - 100.0) * (1 - drift) * 1000)
        out = tracker.update(device_ms, host)
    assert out is not None and tracker.windows >= 8
    # after ~10 s the offset moved by ~10 ms (minus the first window, which is the baseline)
    assert tracker.correction_s == pytest.approx(0.0095, abs=0.002)
    tracker.reset(None)
    assert tracker.correction_s == 0.0 and tracker.update(0, 1.0) is None
