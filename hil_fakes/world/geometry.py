"""2-D geometry of the simulated world: walls, scripted round obstacles and vectorised ray casting.

World frame: x forward along the robot's start heading, y left, angles counter-clockwise, metres.
Everything is vectorised over rays (and over ray times for obstacles that move during a sweep).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

_EPS = 1e-9


@dataclass(frozen=True)
class Wall:
    """A vertical wall standing on the segment (x0, y0)-(x1, y1), ``height_m`` tall."""

    x0_m: float
    y0_m: float
    x1_m: float
    y1_m: float
    height_m: float = 2.6
    #: diffuse reflectivity 0..1 (scales the laser intensity and the rendered brightness)
    reflectivity: float = 0.6

    @property
    def length_m(self) -> float:
        return math.hypot(self.x1_m - self.x0_m, self.y1_m - self.y0_m)


@dataclass(frozen=True)
class Gait:
    """How a walking person moves their legs (see :mod:`hil_fakes.world.people` for the model)."""

    stride_m: float = 1.3
    stance_frac: float = 0.6
    #: radius of a leg (trousered shin) at laser height: 0.10-0.15 m diameter
    leg_radius_m: float = 0.06
    hip_halfwidth_m: float = 0.10
    leg_length_m: float = 0.90
    #: body radius for the ground truth and collision checks (shoulders about 0.45 m wide)
    body_radius_m: float = 0.25
    height_m: float = 1.75
    #: gait phase at the start of the path (0.3: both feet under the pelvis, side by side)
    phase0: float = 0.3

    def __post_init__(self) -> None:
        if not (0.3 <= self.stride_m <= 2.5 and 0.4 <= self.stance_frac <= 0.8 and self.leg_radius_m > 0):
            raise ValueError(f"implausible gait {self}")


@dataclass(frozen=True)
class ObstaclePath:
    """A vertical cylinder moving along a polyline at constant speed.

    It stands at ``waypoints[0]`` until ``start_s``, then moves at ``speed_mps`` along the polyline and
    stands at the last waypoint once it gets there. Times are world times (scenario seconds).
    """

    radius_m: float
    waypoints: tuple[tuple[float, float], ...]
    speed_mps: float
    start_s: float
    height_m: float = 1.7
    reflectivity: float = 0.5
    #: a walking person (legs at the laser, a body in the camera) instead of a cylinder; ``radius_m``
    #: is then the body's radius for the ground truth
    gait: Gait | None = None

    def __post_init__(self) -> None:
        if len(self.waypoints) < 1:
            raise ValueError("ObstaclePath needs at least one waypoint")
        if self.radius_m <= 0 or self.speed_mps < 0:
            raise ValueError("ObstaclePath: radius_m must be > 0 and speed_mps >= 0")
        pts = np.asarray(self.waypoints, dtype=float).reshape(-1, 2)
        seg = np.hypot(*np.diff(pts, axis=0).T) if len(pts) > 1 else np.zeros(0)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        pts.setflags(write=False)
        cum.setflags(write=False)
        object.__setattr__(self, "_pts_cum", (pts, cum))  # cache (not a field: eq/hash/repr unaffected)

    def _cumulative(self) -> tuple[np.ndarray, np.ndarray]:
        return self._pts_cum  # type: ignore[attr-defined, no-any-return]

    @property
    def length_m(self) -> float:
        return float(self._cumulative()[1][-1])

    @property
    def end_s(self) -> float:
        """Time the obstacle reaches its last waypoint (= start_s for a standing obstacle)."""
        if self.speed_mps <= 0:
            return self.start_s
        return self.start_s + self.length_m / self.speed_mps

    def positions(self, t_s: np.ndarray | float) -> np.ndarray:
        """Centres (..., 2) at the times ``t_s``."""
        t = np.asarray(t_s, dtype=float)
        pts, cum = self._cumulative()
        if len(pts) == 1 or cum[-1] <= 0:
            return np.broadcast_to(pts[0], t.shape + (2,)).copy()
        s = np.clip((t - self.start_s) * self.speed_mps, 0.0, cum[-1])
        return np.stack([np.interp(s, cum, pts[:, 0]), np.interp(s, cum, pts[:, 1])], axis=-1)

    def velocities(self, t_s: np.ndarray | float) -> np.ndarray:
        """Velocity vectors (..., 2) at the times ``t_s`` (zero while standing)."""
        t = np.asarray(t_s, dtype=float)
        pts, cum = self._cumulative()
        out = np.zeros(t.shape + (2,))
        if len(pts) == 1 or cum[-1] <= 0 or self.speed_mps <= 0:
            return out
        s = (t - self.start_s) * self.speed_mps
        moving = (s > 0) & (s < cum[-1])
        idx = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(pts) - 2)
        d = pts[idx + 1] - pts[idx]
        norm = np.hypot(d[..., 0], d[..., 1])[..., None]
        vel = self.speed_mps * d / np.where(norm > 0, norm, 1.0)
        out[moving] = vel[moving]
        return out


def walls_array(walls: tuple[Wall, ...] | list[Wall]) -> np.ndarray:
    """(M, 4) array of x0, y0, x1, y1."""
    if not walls:
        return np.zeros((0, 4))
    return np.array([[w.x0_m, w.y0_m, w.x1_m, w.y1_m] for w in walls], dtype=float)


def cast_walls(
    ox: np.ndarray, oy: np.ndarray, dx: np.ndarray, dy: np.ndarray, walls: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First wall hit of each ray o + t*d (unit d).

    Returns (distance_m (inf: no hit), wall index (-1: none), position along the wall in metres from
    its first end point), each shaped like ``dx``.
    """
    shape = np.broadcast(ox, oy, dx, dy).shape
    if walls.shape[0] == 0:
        return np.full(shape, np.inf), np.full(shape, -1, dtype=np.int64), np.zeros(shape)
    ox, oy, dx, dy = (np.broadcast_to(a, shape)[..., None] for a in (ox, oy, dx, dy))
    x0, y0, x1, y1 = walls.T
    ex, ey = x1 - x0, y1 - y0
    px, py = x0 - ox, y0 - oy
    denom = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv = 1.0 / denom
        t = (px * ey - py * ex) * inv
        u = (px * dy - py * dx) * inv
    ok = (np.abs(denom) > _EPS) & (t > 1e-6) & (u >= 0.0) & (u <= 1.0)
    t = np.where(ok, t, np.inf)
    idx = np.argmin(t, axis=-1)
    dist = np.take_along_axis(t, idx[..., None], axis=-1)[..., 0]
    along = np.take_along_axis(np.where(ok, u, 0.0), idx[..., None], axis=-1)[..., 0] * np.hypot(ex, ey)[idx]
    idx = np.where(np.isfinite(dist), idx, -1)
    return dist, idx, along


def cast_circles(
    ox: np.ndarray, oy: np.ndarray, dx: np.ndarray, dy: np.ndarray, cx: np.ndarray, cy: np.ndarray, r: np.ndarray
) -> np.ndarray:
    """Entry distance of rays o + t*d (unit d) into circles; inf where missed.

    ``cx, cy`` broadcast against the rays with a trailing circle axis (..., K); ``r`` is (K,).
    Returns (..., K). A ray starting inside a circle hits it at distance 0.
    """
    fx = ox[..., None] - cx
    fy = oy[..., None] - cy
    b = fx * dx[..., None] + fy * dy[..., None]
    c = fx * fx + fy * fy - r * r
    disc = b * b - c
    with np.errstate(invalid="ignore"):
        sq = np.sqrt(np.maximum(disc, 0.0))
    t = -b - sq
    hit = (disc >= 0) & ((t > 1e-6) | (c < 0))
    t = np.where(c < 0, 0.0, t)
    return np.where(hit & (-b + sq > 0), t, np.inf)


def wrap_pi(a: np.ndarray | float) -> np.ndarray | float:
    return np.arctan2(np.sin(a), np.cos(a))
