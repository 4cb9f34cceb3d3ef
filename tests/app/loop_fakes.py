"""Fakes for driving ``ControlLoop`` on a simulated clock: the clock and a base (the scanners differ
per test: what they deliver and when is what each test is about)."""

from __future__ import annotations

from app.daemon import OdomSample
from vipsm.types import Odometry


class SimClock:
    """A monotonic clock the test advances by hand (``now_s``)."""

    def __init__(self, now_s: float = 100.0) -> None:
        self.now_s = now_s

    def __call__(self) -> float:
        return self.now_s


class FakeBase:
    """A base whose odometry is sampled with every cycle: standing still, or (``moving``) reporting the
    last commanded speed, as a base that follows its commands at once."""

    def __init__(self, clock: SimClock, moving: bool = False) -> None:
        self.clock, self.moving = clock, moving
        self.commands: list[tuple[float, float]] = []

    def state(self) -> str:
        return "ok"

    def poll(self) -> list[OdomSample]:
        v = self.commands[-1][0] if self.moving and self.commands else 0.0
        return [OdomSample(Odometry(0.0, 0.0, 0.0, v, 0.0, self.clock.now_s))]

    def command(self, v_mps: float, w_radps: float) -> None:
        self.commands.append((v_mps, w_radps))

    def stop(self) -> None:
        self.commands.append((0.0, 0.0))

    def counters(self) -> dict[str, int]:
        return {}

    def close(self) -> None:
        pass
