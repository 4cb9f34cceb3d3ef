"""Static clutter: chairs, tables, boxes, a bin, posts.

Furniture is what makes a real room hard for a moving-obstacle detector: at the laser's height
(0.30 m) a chair is four 20-30 mm legs, a table four 40-50 mm legs, and from a moving robot these
small segments appear, vanish behind each other and jitter with the laser's noise. Nothing here
ever moves.

Dimensions are those of ordinary office furniture (EN 1335 / EN 527 ranges): a chair's legs on a
0.40-0.45 m square, seat at 0.45 m; a table 1.2 x 0.8 m on four legs, top at 0.74 m; cardboard
boxes 0.3-0.6 m; a waste bin 0.3 m across; posts 0.1 m. Round parts are vertical cylinders
(:class:`StaticCircle`, with the heights they span, so the laser sees only what crosses its plane and
the camera sees the rest); boxes are four low walls.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .geometry import Wall


@dataclass(frozen=True)
class StaticCircle:
    x_m: float
    y_m: float
    radius_m: float
    z0_m: float
    z1_m: float
    reflectivity: float = 0.5
    #: what it belongs to ("chair", "table", "bin", "post"): for the evaluation's reports
    kind: str = "post"


@dataclass(frozen=True)
class Clutter:
    circles: tuple[StaticCircle, ...] = ()
    walls: tuple[Wall, ...] = ()

    def footprints(self) -> list[tuple[float, float, float, str]]:
        """(x_m, y_m, radius_m, kind) of every piece, boxes as their bounding circle."""
        out = [(c.x_m, c.y_m, c.radius_m, c.kind) for c in self.circles]
        for k in range(0, len(self.walls), 4):
            xs = [w.x0_m for w in self.walls[k : k + 4]]
            ys = [w.y0_m for w in self.walls[k : k + 4]]
            cx, cy = float(np.mean(xs)), float(np.mean(ys))
            out.append((cx, cy, max(math.hypot(x - cx, y - cy) for x, y in zip(xs, ys, strict=True)), "box"))
        return out


def _rot(x: float, y: float, yaw: float) -> tuple[float, float]:
    c, s = math.cos(yaw), math.sin(yaw)
    return c * x - s * y, s * x + c * y


def chair(x: float, y: float, yaw: float) -> list[StaticCircle]:
    legs = [_rot(dx, dy, yaw) for dx, dy in ((0.21, 0.21), (0.21, -0.21), (-0.21, 0.21), (-0.21, -0.21))]
    out = [StaticCircle(x + dx, y + dy, 0.0125, 0.0, 0.45, 0.35, "chair") for dx, dy in legs]
    out.append(StaticCircle(x, y, 0.24, 0.43, 0.47, 0.4, "chair"))  # the seat (camera only)
    return out


def table(x: float, y: float, yaw: float) -> list[StaticCircle]:
    legs = [_rot(dx, dy, yaw) for dx, dy in ((0.55, 0.35), (0.55, -0.35), (-0.55, 0.35), (-0.55, -0.35))]
    out = [StaticCircle(x + dx, y + dy, 0.022, 0.0, 0.74, 0.45, "table") for dx, dy in legs]
    out.append(StaticCircle(x, y, 0.62, 0.72, 0.75, 0.55, "table"))  # the top (camera only)
    return out


def box(x: float, y: float, yaw: float, size_m: float, height_m: float) -> list[Wall]:
    h = size_m / 2
    c = [_rot(dx, dy, yaw) for dx, dy in ((h, h), (-h, h), (-h, -h), (h, -h))]
    pts = [(x + dx, y + dy) for dx, dy in c]
    return [
        Wall(pts[k][0], pts[k][1], pts[(k + 1) % 4][0], pts[(k + 1) % 4][1], height_m=height_m, reflectivity=0.45)
        for k in range(4)
    ]


def _segment_distance(x: float, y: float, seg: tuple[float, float, float, float]) -> float:
    x0, y0, x1, y1 = seg
    dx, dy = x1 - x0, y1 - y0
    t = ((x - x0) * dx + (y - y0) * dy) / max(dx * dx + dy * dy, 1e-12)
    t = min(1.0, max(0.0, t))
    return math.hypot(x - x0 - t * dx, y - y0 - t * dy)


def furnish(
    rng: np.random.Generator,
    level: int,
    room_x: tuple[float, float],
    room_y: tuple[float, float],
    lane_halfwidth_m: float,
    keepout: tuple[tuple[float, float, float, float, float], ...] = (),
) -> Clutter:
    """A furnished room: ``level`` (1-3) sets how much (level 1: 2 chairs, a table, 2 boxes, a bin, a
    post; each level adds as much again). Pieces stand beside the robot's lane (|y| >
    ``lane_halfwidth_m``), off the walls and clear of the ``keepout`` segments (x0, y0, x1, y1,
    clearance_m: the moving bodies' paths), randomly placed and turned with ``rng``."""
    circles: list[StaticCircle] = []
    walls: list[Wall] = []
    taken: list[tuple[float, float, float]] = []

    def place(radius: float) -> tuple[float, float, float] | None:
        for _ in range(200):
            x = float(rng.uniform(room_x[0] + radius + 0.1, room_x[1] - radius - 0.1))
            side = 1.0 if rng.random() < 0.5 else -1.0
            lo, hi = lane_halfwidth_m + radius, room_y[1] - radius - 0.1
            if hi <= lo:
                return None
            y = side * float(rng.uniform(lo, hi))
            clear = all(_segment_distance(x, y, k[:4]) > radius + k[4] for k in keepout)
            if clear and all(math.hypot(x - a, y - b) > radius + r + 0.15 for a, b, r in taken):
                taken.append((x, y, radius))
                return x, y, float(rng.uniform(-math.pi, math.pi))
        return None

    for _ in range(max(0, level)):
        for maker, radius in ((chair, 0.32), (chair, 0.32), (table, 0.67)):
            spot = place(radius)
            if spot:
                circles.extend(maker(*spot))
        for size in (0.4, 0.55):
            spot = place(size * 0.72)
            if spot:
                walls.extend(box(*spot, size_m=size, height_m=float(rng.uniform(0.35, 0.6))))
        spot = place(0.15)
        if spot:
            circles.append(StaticCircle(spot[0], spot[1], 0.15, 0.0, 0.6, 0.5, "bin"))
        spot = place(0.05)
        if spot:
            circles.append(StaticCircle(spot[0], spot[1], 0.05, 0.0, 2.6, 0.6, "post"))
    return Clutter(tuple(circles), tuple(walls))
