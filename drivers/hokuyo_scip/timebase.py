"""The UTM-30LX's 24-bit millisecond clock against the host clock. Pure (times are passed in).

* :class:`TimestampUnwrapper` turns the raw 24-bit counter (wraps every 2^24 ms = 4 h 39 min 37 s)
  into a continuous millisecond count. The modular step from the previous stamp (signed: scan
  stamps mark step 0, so one may be slightly older than a TM1 reading taken just before it) counts
  as continuous when it agrees with the host time elapsed within ``tolerance_ms``; a counter that
  jumps back (RS/RT/RB, a power cycle seen through a reconnect) or forward by far more than the
  host time elapsed is a *reset*: a new epoch starts, ``resets`` counts it,
  and the host-clock offset must be measured again. The client also calls :meth:`reset` itself
  after RS and after every reconnect.
* :class:`ClockOffsetEstimator` estimates host_time - device_time from TM1 round trips: each
  sample is the midpoint of request and reply against the device stamp; the estimate is the
  median (robust to one slow round trip).
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass

from .errors import ScipConfigError

TIMESTAMP_MODULUS = 1 << 24
_HALF = TIMESTAMP_MODULUS // 2


@dataclass(frozen=True)
class UnwrappedStamp:
    raw_ms: int  # as the sensor sent it (0 .. 2^24 - 1)
    unwrapped_ms: int  # monotonic within an epoch; epochs restart at the raw value
    epoch: int  # increases on every detected or announced reset


class TimestampUnwrapper:
    """Unwrap the 24-bit ms counter; tell a wrap from a reset with the host's elapsed time.

    ``tolerance_ms`` is how far the device step may differ from the host's elapsed time (USB
    latency, buffering, TM round trips) and still count as continuous.
    """

    def __init__(self, tolerance_ms: float = 2000.0, drift_fraction: float = 0.01) -> None:
        if tolerance_ms <= 0 or drift_fraction < 0:
            raise ScipConfigError("tolerance_ms must be > 0 and drift_fraction >= 0")
        self._tol_ms = tolerance_ms
        self._drift = drift_fraction
        self._last_raw: int | None = None
        self._last_host_s: float | None = None
        self._unwrapped = 0
        self.epoch = 0
        self.resets = 0
        self.wraps = 0

    def reset(self) -> None:
        """The device clock restarted (RS, reconnect): the next stamp begins a new epoch."""
        if self._last_raw is not None:
            self.epoch += 1
        self._last_raw = None
        self._last_host_s = None

    def update(self, raw_ms: int, host_s: float | None = None) -> UnwrappedStamp:
        if not 0 <= raw_ms < TIMESTAMP_MODULUS:
            raise ScipConfigError(f"raw timestamp {raw_ms} outside the 24-bit range")
        if self._last_raw is None:
            self._unwrapped = raw_ms
        else:
            step = (raw_ms - self._last_raw) % TIMESTAMP_MODULUS
            if step >= _HALF:
                step -= TIMESTAMP_MODULUS  # a (small) step back: an older stamp, or a reset
            if host_s is not None and self._last_host_s is not None:
                elapsed_ms = max(0.0, host_s - self._last_host_s) * 1000.0
                continuous = abs(step - elapsed_ms) <= self._tol_ms + self._drift * elapsed_ms
            else:
                continuous = step >= -self._tol_ms
            if continuous:
                if step > 0 and raw_ms < self._last_raw:
                    self.wraps += 1
                self._unwrapped += step
            else:
                self.resets += 1
                self.epoch += 1
                self._unwrapped = raw_ms
        self._last_raw = raw_ms
        if host_s is not None:
            self._last_host_s = host_s
        return UnwrappedStamp(raw_ms, self._unwrapped, self.epoch)


@dataclass(frozen=True)
class ClockOffset:
    """host_s = device_ms / 1000 + offset_s, valid for the unwrapper epoch it was measured in."""

    offset_s: float
    epoch: int
    samples: int
    spread_s: float  # max - min of the per-sample offsets
    round_trip_s: float  # median request-to-reply time


class ClockOffsetEstimator:
    """Collect TM1 round trips (host send time, host receive time, device ms) and take the median."""

    def __init__(self) -> None:
        self._offsets: list[float] = []
        self._rtts: list[float] = []

    def add(self, host_sent_s: float, host_received_s: float, device_ms: int) -> None:
        if host_received_s < host_sent_s:
            raise ScipConfigError("a reply cannot arrive before its request was sent")
        midpoint = 0.5 * (host_sent_s + host_received_s)
        self._offsets.append(midpoint - device_ms / 1000.0)
        self._rtts.append(host_received_s - host_sent_s)

    @property
    def count(self) -> int:
        return len(self._offsets)

    def estimate(self, epoch: int) -> ClockOffset:
        if not self._offsets:
            raise ScipConfigError("no TM1 round trips collected")
        return ClockOffset(
            offset_s=statistics.median(self._offsets),
            epoch=epoch,
            samples=len(self._offsets),
            spread_s=max(self._offsets) - min(self._offsets),
            round_trip_s=statistics.median(self._rtts),
        )


class DriftTracker:
    """Keep the TM offset current while streaming, from frame arrival times (clock drift).

    After a TM sync, ``latency = host_arrival - (device_ms / 1000 + offset_tm)`` of a stream frame is
    the sweep plus the transfer plus scheduling noise, always >= its fixed part. Its minimum over a
    window of ``window_s`` is that fixed part plus the drift accumulated since the sync. The first
    full window sets the fixed part (the baseline); each later window's minimum minus the baseline
    is the drift correction added to the TM offset (the lower envelope ignores late frames, the idea
    of urg_stamped and urg_node2's synchronisation). Call :meth:`reset` at every sync and stream
    start (the fixed part depends on the step window).
    """

    def __init__(self, window_s: float = 10.0, min_frames: int = 20) -> None:
        if window_s <= 0 or min_frames < 1:
            raise ScipConfigError("window_s must be > 0 and min_frames >= 1")
        self.window_s = window_s
        self.min_frames = min_frames
        self._base: ClockOffset | None = None
        self._baseline_s: float | None = None
        self._window_start: float | None = None
        self._window_min = math.inf
        self._window_count = 0
        self.correction_s = 0.0
        self.windows = 0

    def reset(self, base: ClockOffset | None) -> None:
        self._base = base
        self._baseline_s = None
        self._window_start = None
        self._window_min = math.inf
        self._window_count = 0
        self.correction_s = 0.0
        self.windows = 0

    def update(self, device_ms: int, host_arrival_s: float) -> float | None:
        """Feed one stream frame; returns the corrected offset_s (None without a TM offset)."""
        base = self._base
        if base is None:
            return None
        latency = host_arrival_s - (device_ms / 1000.0 + base.offset_s)
        if self._window_start is None:
            self._window_start = host_arrival_s
        self._window_min = min(self._window_min, latency)
        self._window_count += 1
        if host_arrival_s - self._window_start >= self.window_s and self._window_count >= self.min_frames:
            if self._baseline_s is None:
                self._baseline_s = self._window_min
            else:
                self.correction_s = self._window_min - self._baseline_s
            self.windows += 1
            self._window_start = host_arrival_s
            self._window_min = math.inf
            self._window_count = 0
        return base.offset_s + self.correction_s
