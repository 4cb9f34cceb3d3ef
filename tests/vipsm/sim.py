"""A small 2-D ray-caster and pinhole renderer for the estimator's tests (independent of hil_fakes).

Worlds are line-segment walls plus circles; scans are ray-cast exactly (optionally with Gaussian
range noise); images are rendered column by column from the same geometry with textured walls,
floor and bodies so optical flow has something to follow.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from vipsm.types import Frame, Intrinsics, Odometry, Pose2D, Scan

UTM_BEARINGS = np.radians(-135.0 + 0.25 * np.arange(1081))


@dataclass
class Circle:
    x_m: float
    y_m: float
    radius_m: float
    vx_mps: float = 0.0
    vy_mps: float = 0.0
    texture_seed: int = 7

    def at(self, t_s: float) -> tuple[float, float]:
        return self.x_m + self.vx_mps * t_s, self.y_m + self.vy_mps * t_s


@dataclass
class World:
    walls: np.ndarray  # (k, 4): x0, y0, x1, y1
    circles: list[Circle] = field(default_factory=list)
    max_range_m: float = 30.0

    def cast(self, ox: float, oy: float, angles: np.ndarray, t_s: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Distance along each world angle to the first surface (inf if none) and a surface id
        (wall index, or -(1 + circle index))."""
        dx, dy = np.cos(angles)[:, None], np.sin(angles)[:, None]
        x0, y0, x1, y1 = (self.walls[:, k][None, :] for k in range(4))
        ex, ey = x1 - x0, y1 - y0
        den = dx * ey - dy * ex
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            t = ((x0 - ox) * ey - (y0 - oy) * ex) / den
            u = ((x0 - ox) * dy - (y0 - oy) * dx) / den
        hit = (np.abs(den) > 1e-12) & (t > 1e-9) & (u >= 0.0) & (u <= 1.0)
        t = np.where(hit, t, np.inf)
        best = np.argmin(t, axis=1)
        dist = t[np.arange(angles.size), best]
        ident = best.astype(np.int64)
        for ci, c in enumerate(self.circles):
            cx, cy = c.at(t_s)
            fx, fy = ox - cx, oy - cy
            b = fx * dx[:, 0] + fy * dy[:, 0]
            cc = fx * fx + fy * fy - c.radius_m**2
            disc = b * b - cc
            with np.errstate(invalid="ignore"):
                tc = -b - np.sqrt(disc)
            ok = (disc >= 0) & (tc > 1e-9) & (tc < dist)
            dist = np.where(ok, tc, dist)
            ident = np.where(ok, -(1 + ci), ident)
        return dist, ident

    def scan(
        self,
        pose: Pose2D,
        bearings: np.ndarray = UTM_BEARINGS,
        t_s: float = 0.0,
        noise_m: float = 0.0,
        rng: np.random.Generator | None = None,
        stamp_s: float | None = None,
    ) -> Scan:
        d, _ = self.cast(pose.x_m, pose.y_m, bearings + pose.theta_rad, t_s)
        r = d.copy()
        if noise_m > 0.0:
            gen = rng or np.random.default_rng(0)
            r = r + gen.normal(0.0, noise_m, r.size)
        r[~np.isfinite(d) | (d > self.max_range_m)] = np.nan
        return Scan(r, bearings.copy(), t_s if stamp_s is None else stamp_s)


def box_room(w_m: float, h_m: float, x0: float = -2.0, y0: float = -3.0, pillars: bool = True) -> World:
    """A rectangular room with a few wall features (so every direction is constrained)."""
    x1, y1 = x0 + w_m, y0 + h_m
    walls = [
        (x0, y0, x1, y0),
        (x1, y0, x1, y1),
        (x1, y1, x0, y1),
        (x0, y1, x0, y0),
    ]
    if pillars:
        walls += [
            (x0 + 0.3 * w_m, y0, x0 + 0.3 * w_m, y0 + 0.5),
            (x0 + 0.3 * w_m, y0 + 0.5, x0 + 0.3 * w_m + 0.4, y0 + 0.5),
            (x1, y0 + 0.6 * h_m, x1 - 0.6, y0 + 0.6 * h_m),
            (x1 - 0.6, y0 + 0.6 * h_m, x1 - 0.6, y0 + 0.6 * h_m + 0.5),
            (x0, y0 + 0.4 * h_m, x0 + 0.8, y0 + 0.4 * h_m + 0.3),
            (x0 + 0.6 * w_m, y1, x0 + 0.6 * w_m + 0.5, y1 - 0.4),
        ]
    return World(np.array(walls, dtype=float))


def corridor(length_m: float = 30.0, width_m: float = 2.0) -> World:
    walls = [
        (-5.0, -width_m / 2, length_m, -width_m / 2),
        (-5.0, width_m / 2, length_m, width_m / 2),
        (4.0, width_m / 2, 4.0, width_m / 2 + 1.0),  # a door recess gives some along-corridor structure
        (4.0, width_m / 2 + 1.0, 5.0, width_m / 2 + 1.0),
        (5.0, width_m / 2 + 1.0, 5.0, width_m / 2),
    ]
    w = World(np.array(walls, dtype=float))
    return w


def odometry_at(pose: Pose2D, t_s: float, v: float = 0.0, w: float = 0.0) -> Odometry:
    return Odometry(pose.x_m, pose.y_m, pose.theta_rad, v, w, t_s)


# ----------------------------------------------------------------------------------------------
# Rendering


def _texture(u: np.ndarray, v: np.ndarray, seed: int) -> np.ndarray:
    """Deterministic multi-scale texture in about [60, 200] from surface coordinates (m)."""
    rng = np.random.default_rng(seed)
    acc = np.zeros(np.broadcast(u, v).shape)
    u = np.nan_to_num(u, nan=0.0, posinf=0.0, neginf=0.0)
    v = np.nan_to_num(v, nan=0.0, posinf=0.0, neginf=0.0)
    for _ in range(10):
        k = rng.uniform(5.0, 30.0)
        a = rng.uniform(0, 2 * math.pi)
        ph = rng.uniform(0, 2 * math.pi)
        acc += (12.0 / math.sqrt(k / 5.0)) * np.sin(k * (math.cos(a) * u + math.sin(a) * v) + ph)
    return 128.0 + acc


@dataclass
class Camera:
    width_px: int = 320
    height_px: int = 240
    hfov_rad: float = math.radians(50.0)
    x_m: float = 0.10  # mount on the robot
    y_m: float = 0.0
    z_m: float = 1.0
    wall_height_m: float = 2.5

    @property
    def intrinsics(self) -> Intrinsics:
        fx = (self.width_px / 2.0) / math.tan(self.hfov_rad / 2.0)
        return Intrinsics(fx, fx, (self.width_px - 1) / 2.0, (self.height_px - 1) / 2.0, self.width_px, self.height_px)

    def render(self, world: World, robot: Pose2D, t_s: float, pan_rad: float = 0.0) -> np.ndarray:
        """Grey uint8 image: walls and circles are vertical textured surfaces of finite height, the
        floor is textured, the rest is a flat grey ceiling."""
        K = self.intrinsics
        c, s = math.cos(robot.theta_rad), math.sin(robot.theta_rad)
        camx = robot.x_m + c * self.x_m - s * self.y_m
        camy = robot.y_m + s * self.x_m + c * self.y_m
        cols = np.arange(self.width_px, dtype=float)
        rows = np.arange(self.height_px, dtype=float)
        az = robot.theta_rad + pan_rad - np.arctan((cols - K.cx_px) / K.fx_px)  # world azimuth per column
        dist, ident = world.cast(camx, camy, az, t_s)
        # horizontal distance along the optical axis direction per column: the ray's horizontal length
        cos_off = np.cos(np.arctan((cols - K.cx_px) / K.fx_px))
        # per pixel: elevation slope (up positive) = (cy - v) / fy / cos_off (rays through a column)
        slope = (K.cy_px - rows)[:, None] / K.fy_px * cos_off[None, :]
        dfin = np.where(np.isfinite(dist), dist, 0.0)
        hx = camx + dfin * np.cos(az)
        hy = camy + dfin * np.sin(az)
        z_hit = self.z_m + slope * dfin[None, :]
        img = np.full((self.height_px, self.width_px), 90.0)
        # surface coordinate along the surface for texture
        surf_u = np.where(ident >= 0, hx + hy, 0.0)
        for ci, cobj in enumerate(world.circles):
            cx, cy = cobj.at(t_s)
            ang = np.arctan2(hy - cy, hx - cx)
            surf_u = np.where(ident == -(1 + ci), ang * cobj.radius_m, surf_u)
        seeds = np.where(ident >= 0, 3, 0)
        wall_tex = _texture(surf_u[None, :], z_hit, 3)
        on_surface = np.isfinite(dist)[None, :] & (z_hit >= 0.0) & (z_hit <= self.wall_height_m)
        img = np.where(on_surface, wall_tex, img)
        for ci, cobj in enumerate(world.circles):
            m = on_surface & (ident == -(1 + ci))[None, :]
            img = np.where(m, _texture(surf_u[None, :], z_hit, cobj.texture_seed + 100), img)
        # floor
        with np.errstate(divide="ignore"):
            floor_d = np.where(slope < 0, self.z_m / -slope, np.inf)
        floor_vis = floor_d < np.where(on_surface, dist[None, :], np.inf)
        floor_vis &= slope < 0
        fd = np.where(np.isfinite(floor_d), floor_d, 0.0)
        fx_ = camx + fd * np.cos(az)[None, :]
        fy_ = camy + fd * np.sin(az)[None, :]
        fade = np.clip(3.0 / np.maximum(floor_d, 1e-3), 0.0, 1.0)  # far floor: detail below a pixel
        floor_tex = 128.0 + fade * (_texture(fx_, fy_, 11) - 128.0)
        img = np.where(floor_vis & np.isfinite(floor_d), floor_tex, img)
        del seeds
        img = cv2.GaussianBlur(img, (0, 0), 0.8)  # the lens' blur (and an anti-aliasing filter)
        return np.clip(img, 0, 255).astype(np.uint8)

    def frame(self, world: World, robot: Pose2D, t_s: float, pan_rad: float = 0.0, seq: int = 0) -> Frame:
        return Frame(self.render(world, robot, t_s, pan_rad), t_s, self.intrinsics, pan_rad, 0.0, seq)
