"""The fake Pioneer's world side: the plant it drives (a unicycle or the simulated world) and what
its sonar sees."""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Protocol

from ..kinematics import Unicycle

# ---------------------------------------------------------------------------------------------
# interfaces (INTERFACES.md)


class Plant(Protocol):
    def command(self, v_mps: float, w_radps: float, now_s: float) -> None: ...

    def e_stop(self, now_s: float) -> None: ...

    def state(self, now_s: float) -> tuple[float, float, float, float, float]:
        """true (x_m, y_m, theta_rad, v_mps, w_radps) advanced to now_s"""
        ...


class SonarWorld(Protocol):
    def ray_range_m(self, x_m: float, y_m: float, angle_rad: float, max_range_m: float) -> float:
        """distance to the first surface along the ray from (x, y) at world angle angle_rad; NaN if none"""
        ...


class UnicyclePlant:
    """The standalone plant: a :class:`Unicycle` advanced lazily to each queried time (thread-safe)."""

    def __init__(self, unicycle: Unicycle | None = None, max_step_s: float = 0.01) -> None:
        self.unicycle = unicycle or Unicycle()
        self._max_step_s = max_step_s
        self._t_s: float | None = None
        self._lock = threading.Lock()

    def _advance(self, now_s: float) -> None:
        if self._t_s is None:
            self._t_s = now_s
            return
        while now_s > self._t_s:
            dt = min(self._max_step_s, now_s - self._t_s)
            self.unicycle.advance(dt)
            self._t_s += dt

    def command(self, v_mps: float, w_radps: float, now_s: float) -> None:
        with self._lock:
            self._advance(now_s)
            self.unicycle.command(v_mps, w_radps)

    def e_stop(self, now_s: float) -> None:
        with self._lock:
            self._advance(now_s)
            self.unicycle.stop_now()

    def set_accelerations(self, accel_mps2: float, rot_accel_radps2: float) -> None:
        with self._lock:
            self.unicycle.max_accel_mps2 = accel_mps2
            self.unicycle.max_rot_accel_radps2 = rot_accel_radps2

    def state(self, now_s: float) -> tuple[float, float, float, float, float]:
        with self._lock:
            self._advance(now_s)
            u = self.unicycle
            return (u.x_m, u.y_m, u.theta_rad, u.v_mps, u.w_radps)


@dataclass(frozen=True)
class RectangularRoom:
    """Axis-aligned walls around the start pose (default: 8 m x 5 m, robot 2 m from the back wall)."""

    x_min_m: float = -2.0
    x_max_m: float = 6.0
    y_min_m: float = -2.5
    y_max_m: float = 2.5

    def ray_range_m(self, x_m: float, y_m: float, angle_rad: float, max_range_m: float) -> float:
        dx, dy = math.cos(angle_rad), math.sin(angle_rad)
        best = math.inf
        if dx > 1e-12:
            best = min(best, (self.x_max_m - x_m) / dx)
        elif dx < -1e-12:
            best = min(best, (self.x_min_m - x_m) / dx)
        if dy > 1e-12:
            best = min(best, (self.y_max_m - y_m) / dy)
        elif dy < -1e-12:
            best = min(best, (self.y_min_m - y_m) / dy)
        if best < 0 or best > max_range_m:
            return math.nan
        return best


# ---------------------------------------------------------------------------------------------
# wire format, written from the fact sheet section 1.2 (independent of drivers/p2os)

_ANGLE_UNIT_RAD = 2.0 * math.pi / 4096.0


# p3dx.p sonar poses (x mm, y mm, heading deg), fact sheet 1.9
SONAR_POSES_MM_DEG: tuple[tuple[float, float, float], ...] = (
    (69, 136, 90), (114, 119, 50), (148, 78, 30), (166, 27, 10),
    (166, -27, -10), (148, -78, -30), (114, -119, -50), (69, -136, -90),
    (-157, -136, -90), (-203, -119, -130), (-237, -78, -150), (-255, -27, -170),
    (-255, 27, 170), (-237, 78, 150), (-203, 119, 130), (-157, 136, 90),
)  # fmt: skip
