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
    #: optional distance walked against time: knots (t_s, s_m), both non-decreasing, linear between them
    #: (a walker who stops and walks on, or a speed that varies); it replaces ``start_s`` + ``speed_mps``
    #: (which then only describe it: its first start and its top speed)
    profile: tuple[tuple[float, float], ...] = ()

    kind = property(lambda self: "cylinder" if self.gait is None else "person")

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
        if self.profile:
            knots = np.asarray(self.profile, dtype=float).reshape(-1, 2)
            if len(knots) < 2 or np.any(np.diff(knots[:, 0]) <= 0) or np.any(np.diff(knots[:, 1]) < -1e-12):
                raise ValueError("ObstaclePath.profile needs >= 2 knots, times increasing, distances non-decreasing")
            knots.setflags(write=False)
            object.__setattr__(self, "_knots", knots)

    def _cumulative(self) -> tuple[np.ndarray, np.ndarray]:
        return self._pts_cum  # type: ignore[attr-defined, no-any-return]

    @property
    def length_m(self) -> float:
        return float(self._cumulative()[1][-1])

    @property
    def end_s(self) -> float:
        """Time the obstacle reaches its last waypoint (= start_s for a standing obstacle)."""
        if self.profile:
            knots = self._knots  # type: ignore[attr-defined]
            done = np.flatnonzero(knots[:, 1] >= self.length_m - 1e-9)
            return float(knots[done[0], 0]) if done.size else math.inf
        if self.speed_mps <= 0:
            return self.start_s
        return self.start_s + self.length_m / self.speed_mps

    def distance_m(self, t_s: np.ndarray | float) -> np.ndarray:
        """Distance walked along the polyline at the times ``t_s``."""
        t = np.asarray(t_s, dtype=float)
        if self.profile:
            knots = self._knots  # type: ignore[attr-defined]
            s = np.interp(t, knots[:, 0], knots[:, 1])
        else:
            s = (t - self.start_s) * self.speed_mps
        return np.clip(s, 0.0, self.length_m)

    def speeds(self, t_s: np.ndarray | float) -> np.ndarray:
        """Speed along the polyline (m/s) at the times ``t_s`` (zero while standing)."""
        t = np.asarray(t_s, dtype=float)
        s = self.distance_m(t)
        inside = (s > 0) & (s < self.length_m)
        if self.profile:
            knots = self._knots  # type: ignore[attr-defined]
            k = np.clip(np.searchsorted(knots[:, 0], t, side="right") - 1, 0, len(knots) - 2)
            slope = (knots[k + 1, 1] - knots[k, 1]) / (knots[k + 1, 0] - knots[k, 0])
            inside &= (t >= knots[0, 0]) & (t < knots[-1, 0])
            return np.where(inside, slope, 0.0)
        return np.where(inside & (t > self.start_s), self.speed_mps, 0.0)

    def walk_starts_s(self) -> list[float]:
        """The instants the body starts moving after standing (the first start, and every start after a stop)."""
        if not self.profile:
            return [self.start_s] if self.speed_mps > 0 and self.length_m > 0 else []
        knots = self._knots  # type: ignore[attr-defined]
        slope = np.diff(knots[:, 1]) / np.diff(knots[:, 0])
        moving = slope > 1e-9
        return [float(knots[i, 0]) for i in range(len(slope)) if moving[i] and (i == 0 or not moving[i - 1])]

    def positions(self, t_s: np.ndarray | float) -> np.ndarray:
        """Centres (..., 2) at the times ``t_s``."""
        return self.positions_at_distance(self.distance_m(np.asarray(t_s, dtype=float)))

    def positions_at_distance(self, s_m: np.ndarray | float) -> np.ndarray:
        """Points (..., 2) of the polyline ``s_m`` along it (clamped to its ends)."""
        s = np.asarray(s_m, dtype=float)
        pts, cum = self._cumulative()
        if len(pts) == 1 or cum[-1] <= 0:
            return np.broadcast_to(pts[0], s.shape + (2,)).copy()
        return np.stack([np.interp(s, cum, pts[:, 0]), np.interp(s, cum, pts[:, 1])], axis=-1)

    def velocities(self, t_s: np.ndarray | float) -> np.ndarray:
        """Velocity vectors (..., 2) at the times ``t_s`` (zero while standing)."""
        t = np.asarray(t_s, dtype=float)
        pts, cum = self._cumulative()
        out = np.zeros(t.shape + (2,))
        if len(pts) == 1 or cum[-1] <= 0 or (self.speed_mps <= 0 and not self.profile):
            return out
        s = self.distance_m(t)
        speed = self.speeds(t)
        moving = speed > 0
        idx = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(pts) - 2)
        d = pts[idx + 1] - pts[idx]
        norm = np.hypot(d[..., 0], d[..., 1])[..., None]
        vel = speed[..., None] * d / np.where(norm > 0, norm, 1.0)
        out[moving] = vel[moving]
        return out

    def camera_parts(self, t_s: float) -> list[tuple[float, float, float, float, float]]:
        """A cylinder's vertical cylinder (x, y, radius, z0, z1) for the camera (people: see people.py)."""
        px, py = (float(v) for v in self.positions(np.array(t_s, float)))
        return [(px, py, self.radius_m, 0.0, self.height_m)]


@dataclass(frozen=True)
class RigidBox:
    """A rigid box moving in the plane: a cart pushed by a person, a door panel about its hinge.

    Its pose (centre x, y and yaw of its length axis) is given as knots ``(t_s, x_m, y_m, yaw_rad)``,
    dense enough to interpolate linearly (the scenarios sample every 20 ms); before the first knot and
    after the last it stands. The laser sees the box's four faces between ``z0_m`` and ``height_m``; the
    camera sees it as the vertical cylinders of :meth:`camera_parts`. ``radius_m`` is its bounding circle
    (half the diagonal), what the ground truth and the sonar use."""

    kind: str
    length_m: float
    width_m: float
    knots: tuple[tuple[float, float, float, float], ...]
    height_m: float = 1.0
    z0_m: float = 0.0
    reflectivity: float = 0.5
    gait: None = None

    def __post_init__(self) -> None:
        k = np.asarray(self.knots, dtype=float).reshape(-1, 4)
        if self.length_m <= 0 or self.width_m <= 0 or len(k) < 2 or np.any(np.diff(k[:, 0]) <= 0):
            raise ValueError("RigidBox needs a positive size and >= 2 pose knots with increasing times")
        k[:, 3] = np.unwrap(k[:, 3])
        k.setflags(write=False)
        object.__setattr__(self, "_k", k)

    @property
    def radius_m(self) -> float:
        return 0.5 * math.hypot(self.length_m, self.width_m)

    def poses(self, t_s: np.ndarray | float) -> np.ndarray:
        """(..., 3) centre x, y and yaw (unwrapped) at the times ``t_s``."""
        t = np.asarray(t_s, dtype=float)
        k = self._k  # type: ignore[attr-defined]
        return np.stack([np.interp(t, k[:, 0], k[:, c]) for c in (1, 2, 3)], axis=-1)

    def positions(self, t_s: np.ndarray | float) -> np.ndarray:
        return self.poses(t_s)[..., :2]

    def rates(self, t_s: np.ndarray | float) -> np.ndarray:
        """(..., 3) d/dt of the pose (vx, vy, yaw rate): the slope of the knot segment holding t."""
        t = np.asarray(t_s, dtype=float)
        k = self._k  # type: ignore[attr-defined]
        i = np.clip(np.searchsorted(k[:, 0], t, side="right") - 1, 0, len(k) - 2)
        slope = (k[i + 1, 1:] - k[i, 1:]) / (k[i + 1, 0] - k[i, 0])[..., None]
        inside = ((t >= k[0, 0]) & (t < k[-1, 0]))[..., None]
        return np.where(inside, slope, 0.0)

    def velocities(self, t_s: np.ndarray | float) -> np.ndarray:
        """Velocity (..., 2) of the centre; a door turning about its hinge moves its centre too."""
        return self.rates(t_s)[..., :2]

    @property
    def start_s(self) -> float:
        """The first instant the box moves (inf: never)."""
        starts = self.walk_starts_s()
        return starts[0] if starts else math.inf

    @property
    def end_s(self) -> float:
        """The last instant the box moves (-inf: never)."""
        k = self._k  # type: ignore[attr-defined]
        step = np.flatnonzero(np.abs(np.diff(k[:, 1:], axis=0)).sum(axis=1) > 1e-12)
        return float(k[step[-1] + 1, 0]) if step.size else -math.inf

    def walk_starts_s(self) -> list[float]:
        k = self._k  # type: ignore[attr-defined]
        step = np.abs(np.diff(k[:, 1:], axis=0)).sum(axis=1) > 1e-12
        return [float(k[i, 0]) for i in range(len(step)) if step[i] and (i == 0 or not step[i - 1])]

    @property
    def waypoints(self) -> tuple[tuple[float, float], ...]:
        """The centre's path (thinned knots), e.g. to keep furniture off it."""
        k = self._k  # type: ignore[attr-defined]
        idx = np.unique(np.linspace(0, len(k) - 1, min(len(k), 50)).round().astype(int))
        return tuple((float(k[i, 1]), float(k[i, 2])) for i in idx)

    def corners(self, t_s: float) -> np.ndarray:
        """(4, 2) corners at ``t_s`` (counter-clockwise)."""
        x, y, yaw = (float(v) for v in self.poses(t_s))
        hl, hw = self.length_m / 2, self.width_m / 2
        c, s = math.cos(yaw), math.sin(yaw)
        local = np.array([(hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw)])
        return np.stack([x + c * local[:, 0] - s * local[:, 1], y + s * local[:, 0] + c * local[:, 1]], axis=-1)

    def camera_parts(self, t_s: float) -> list[tuple[float, float, float, float, float]]:
        """The box in the camera: vertical cylinders of its width's diameter along its length (the
        renderer draws cylinders; a 0.04 m door is a row of 4 cm slats, a cart two rounded halves)."""
        x, y, yaw = (float(v) for v in self.poses(np.array(t_s, float)))
        r = self.width_m / 2
        n = max(1, math.ceil(self.length_m / self.width_m))
        step = (self.length_m - self.width_m) / max(n - 1, 1)
        offs = [-self.length_m / 2 + r + i * step for i in range(n)] if n > 1 else [0.0]
        c, s = math.cos(yaw), math.sin(yaw)
        return [(x + c * a, y + s * a, r, self.z0_m, self.height_m) for a in offs]


def cast_boxes(
    ox: np.ndarray, oy: np.ndarray, dx: np.ndarray, dy: np.ndarray, poses: np.ndarray, half: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Entry distance of rays o + t*d (unit d, shape (N, S)) into oriented boxes, and the cosine of the
    incidence on the face hit. ``poses`` (N, K, 3): centre and yaw of box k at ray n's time; ``half``
    (K, 2): half length, half width. Returns (N, S, K) each; inf where missed (slab method in the box's
    own frame)."""
    cx, cy, yaw = (poses[:, None, :, c] for c in range(3))
    c, s = np.cos(yaw), np.sin(yaw)
    px, py = ox[..., None] - cx, oy[..., None] - cy
    lo = np.stack([c * px + s * py, -s * px + c * py], axis=-1)  # origin in the box frame (N, S, K, 2)
    ld = np.stack([c * dx[..., None] + s * dy[..., None], -s * dx[..., None] + c * dy[..., None]], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / np.where(np.abs(ld) > 1e-12, ld, 1e-12)
        t1, t2 = (-half - lo) * inv, (half - lo) * inv
    t_near_ax = np.minimum(t1, t2)
    t_near = np.max(t_near_ax, axis=-1)
    t_far = np.min(np.maximum(t1, t2), axis=-1)
    hit = (t_near <= t_far) & (t_near > 1e-6)
    axis = np.argmax(t_near_ax, axis=-1)
    cos_inc = np.abs(np.take_along_axis(ld, axis[..., None], axis=-1)[..., 0])
    return np.where(hit, t_near, np.inf), cos_inc


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
