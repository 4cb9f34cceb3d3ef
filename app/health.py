"""Loop health, the safety zone, and odometry interpolation: the daemon's pure logic (no I/O)."""

from __future__ import annotations

import bisect
import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from vipsm.types import Obstacle, Odometry


class LoopHealth:
    """Period jitter, compute time and deadline misses over a bounded window (no growth over a run)."""

    def __init__(self, period_s: float, window: int = 36000) -> None:
        self.period_s = period_s
        self._jitter = deque[float](maxlen=window)
        self._compute = deque[float](maxlen=window)
        #: per estimate: from the scan's last beam to the obstacles published (s), and the host's part
        #: of it, from the scan's last byte read to the obstacles published
        self._latency = deque[float](maxlen=window)
        self._host_latency = deque[float](maxlen=window)
        self.cycles = 0
        self.deadline_misses = 0
        self.skipped_periods = 0
        self.last_compute_s = 0.0

    def record(self, jitter_s: float, compute_s: float, missed: bool, skipped: int = 0) -> None:
        self.cycles += 1
        self._jitter.append(abs(jitter_s))
        self._compute.append(compute_s)
        self.last_compute_s = compute_s
        if missed:
            self.deadline_misses += 1
        self.skipped_periods += skipped

    def record_latency(self, latency_s: float, host_latency_s: float | None = None) -> None:
        self._latency.append(latency_s)
        if host_latency_s is not None:
            self._host_latency.append(host_latency_s)

    @staticmethod
    def _pct(values: deque[float], q: float) -> float:
        return float(np.percentile(np.fromiter(values, float), q)) if values else 0.0

    def jitter_p99_s(self) -> float:
        return self._pct(self._jitter, 99)

    def jitter_max_s(self) -> float:
        return max(self._jitter, default=0.0)

    def compute_median_s(self) -> float:
        return self._pct(self._compute, 50)

    def compute_p99_s(self) -> float:
        return self._pct(self._compute, 99)

    def summary(self) -> dict[str, float | int]:
        return {
            "cycles": self.cycles,
            "deadline_misses": self.deadline_misses,
            "skipped_periods": self.skipped_periods,
            "loop_jitter_p99_ms": round(self.jitter_p99_s() * 1e3, 4),
            "loop_jitter_max_ms": round(self.jitter_max_s() * 1e3, 4),
            "compute_median_ms": round(self.compute_median_s() * 1e3, 4),
            "compute_p99_ms": round(self.compute_p99_s() * 1e3, 4),
            "scan_to_obstacles_ms_median": round(self._pct(self._latency, 50) * 1e3, 3),
            "scan_to_obstacles_ms_p99": round(self._pct(self._latency, 99) * 1e3, 3),
            "scan_received_to_obstacles_ms_median": round(self._pct(self._host_latency, 50) * 1e3, 3),
            "scan_received_to_obstacles_ms_p99": round(self._pct(self._host_latency, 99) * 1e3, 3),
        }


@dataclass
class StopUntilClear:
    """A stop held from the first intrusion until no intrusion was seen for ``resume_after_clear_s``
    (the tracked safety stop and the protective field share it)."""

    resume_after_clear_s: float
    stopped: bool = False
    _clear_since_s: float | None = None

    def update(self, now_s: float, intrusion: bool) -> bool:
        """True while the base must stay stopped."""
        if intrusion:
            self.stopped = True
            self._clear_since_s = None
        elif self.stopped:
            if self._clear_since_s is None:
                self._clear_since_s = now_s
            if now_s - self._clear_since_s >= self.resume_after_clear_s:
                self.stopped = False
                self._clear_since_s = None
        return self.stopped


@dataclass
class SafetyMonitor:
    """Stop when a tracked obstacle's predicted path enters the zone around the robot's predicted path.

    Robot and obstacles are extrapolated at constant velocity over ``horizon_s``; the zone is
    ``radius_m`` plus the obstacle's radius around the robot at the same instant. Motion resumes only
    after the zone has stayed clear for ``resume_after_clear_s``.
    """

    radius_m: float
    horizon_s: float
    resume_after_clear_s: float
    step_s: float = 0.1

    def __post_init__(self) -> None:
        self._hold = StopUntilClear(self.resume_after_clear_s)

    @property
    def stopped(self) -> bool:
        return self._hold.stopped

    def intrusion(self, x_m: float, y_m: float, theta_rad: float, v_mps: float, obstacles: Sequence[Obstacle]) -> bool:
        if not obstacles:
            return False
        t = np.arange(0.0, self.horizon_s + 1e-9, self.step_s)
        rx = x_m + v_mps * math.cos(theta_rad) * t
        ry = y_m + v_mps * math.sin(theta_rad) * t
        for ob in obstacles:
            ox = ob.x_m + ob.vx_mps * t
            oy = ob.y_m + ob.vy_mps * t
            if np.any(np.hypot(ox - rx, oy - ry) <= self.radius_m + ob.radius_m):
                return True
        return False

    def update(
        self, now_s: float, x_m: float, y_m: float, theta_rad: float, v_mps: float, obstacles: Sequence[Obstacle]
    ) -> bool:
        """True while the base must stay stopped."""
        return self._hold.update(now_s, self.intrusion(x_m, y_m, theta_rad, v_mps, obstacles))


class OdometryHistory:
    """Recent odometry samples; the pose at a scan's stamp by interpolation (bounded extrapolation)."""

    def __init__(self, keep: int = 64, max_extrapolation_s: float = 0.2) -> None:
        self._samples: deque[Odometry] = deque(maxlen=keep)
        self.max_extrapolation_s = max_extrapolation_s

    def add(self, odom: Odometry) -> None:
        if self._samples and odom.stamp_s <= self._samples[-1].stamp_s:
            return  # out of order or repeated: keep the history monotonic
        self._samples.append(odom)

    @property
    def newest(self) -> Odometry | None:
        return self._samples[-1] if self._samples else None

    def at(self, t_s: float) -> Odometry | None:
        if not self._samples:
            return None
        stamps = [o.stamp_s for o in self._samples]
        i = bisect.bisect_left(stamps, t_s)
        if i == 0:
            a = self._samples[0]
            return a if a.stamp_s - t_s <= self.max_extrapolation_s else None
        if i == len(stamps):
            a = self._samples[-1]
            dt = t_s - a.stamp_s
            if dt > self.max_extrapolation_s:
                return None
            return _advance(a, dt)
        a, b = self._samples[i - 1], self._samples[i]
        f = (t_s - a.stamp_s) / (b.stamp_s - a.stamp_s)
        dth = math.atan2(math.sin(b.theta_rad - a.theta_rad), math.cos(b.theta_rad - a.theta_rad))
        th = a.theta_rad + f * dth
        return Odometry(
            x_m=a.x_m + f * (b.x_m - a.x_m),
            y_m=a.y_m + f * (b.y_m - a.y_m),
            theta_rad=math.atan2(math.sin(th), math.cos(th)),
            v_mps=a.v_mps + f * (b.v_mps - a.v_mps),
            w_radps=a.w_radps + f * (b.w_radps - a.w_radps),
            stamp_s=t_s,
        )


def _advance(o: Odometry, dt_s: float) -> Odometry:
    th = o.theta_rad + o.w_radps * dt_s / 2.0
    x = o.x_m + o.v_mps * dt_s * math.cos(th)
    y = o.y_m + o.v_mps * dt_s * math.sin(th)
    th2 = o.theta_rad + o.w_radps * dt_s
    return Odometry(x, y, math.atan2(math.sin(th2), math.cos(th2)), o.v_mps, o.w_radps, o.stamp_s + dt_s)


class OverloadMonitor:
    """Whether the estimator keeps up with the scans, with hysteresis, and the obstacle rate it can hold.

    ``load`` is the median of the estimator's last ``window`` times per scan over the budget (the
    scan period with a scan-triggered loop, ``loop.period_s`` with the timer): overload is the
    estimator being slower than the scans for most of its recent runs, so one slow run (a page
    fault, a garbage collection, a kernel loaded late) never enters it. Overload starts when the load reaches
    ``enter_load`` and ends only when it has stayed at or below ``leave_load`` for ``leave_after``
    estimates in a row (a band and a dwell, so a load near 1 does not flap). While overloaded the
    estimator runs on the newest scan every ``every`` budgets, with ``every`` the whole number of
    budgets that holds its time at ``leave_load`` of the interval; the scans in between are skipped
    (counted by the loop). Outside overload ``every`` is 1.
    """

    def __init__(self, enter_load: float = 1.0, leave_load: float = 0.7, window: int = 5,
                 leave_after: int = 10) -> None:
        if not 0.0 < leave_load < enter_load:
            raise ValueError("leave_load must be positive and below enter_load")
        if window < 1:
            raise ValueError("window must be >= 1")
        self.enter_load, self.leave_load, self.leave_after = enter_load, leave_load, leave_after
        self._recent: deque[float] = deque(maxlen=window)
        self._low = 0
        self.compute_s: float | None = None
        self.overloaded = False
        self.every = 1
        self.transitions = 0

    def record(self, compute_s: float, budget_s: float) -> bool:
        """One estimator run of ``compute_s`` against ``budget_s``; returns True when the state changed."""
        self._recent.append(compute_s)
        c = float(np.median(self._recent))
        self.compute_s = c
        load = c / budget_s if budget_s > 0 else 0.0
        was = self.overloaded
        self._low = self._low + 1 if load <= self.leave_load else 0
        if not was and load >= self.enter_load:
            self.overloaded = True
            self.transitions += 1
        elif was and self._low >= self.leave_after:
            self.overloaded = False
        self.every = max(1, math.ceil(load / self.leave_load)) if self.overloaded else 1
        return self.overloaded != was
