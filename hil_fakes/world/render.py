"""Camera rendering of the 2-D world: a pinhole camera looking at textured walls, floor, ceiling and
cylindrical obstacles, vectorised over the image.

Every surface carries a band-limited random texture fixed to it (walls and floor to the world, an
obstacle to its own body), so dense optical flow has structure to follow, and it is sampled from a
small mip-map chosen per pixel from its footprint, so distant floor does not alias into flicker.
Sensor noise is additive Gaussian on the luminance.

Camera geometry (fact sheet visca_snc_rz50.md §3.4): pixel (u, v) has x = (u - cx)/fx (right) and
y = (v - cy)/fy (down); with tilt phi (up positive) its ray in a level frame is right = x,
up = sin(phi) - y cos(phi), forward = cos(phi) + y sin(phi); pan psi is counter-clockwise positive
relative to the robot's x axis, so the world azimuth of the ray is theta_robot + psi - atan2(right,
forward).
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from .geometry import cast_circles, cast_walls

_LEVELS = 5
_TILE = 512

# BGR tints per surface class
_TINTS = np.array(
    [
        [0.16, 0.16, 0.18],  # 0 open space beyond the room (dark)
        [0.92, 0.96, 1.00],  # 1 wall
        [0.55, 0.68, 0.80],  # 2 floor
        [0.95, 0.95, 0.95],  # 3 ceiling
        [0.45, 0.55, 1.05],  # 4.. obstacles (reddish)
        [0.95, 0.60, 0.40],
        [0.50, 1.00, 0.60],
        [0.90, 0.45, 0.90],
    ],
    dtype=np.float32,
)


#: horizontal direction the room's main light comes from (world frame, unit vector)
_LIGHT = np.array([math.cos(math.radians(200.0)), math.sin(math.radians(200.0))])


def _lambert(nx: np.ndarray, ny: np.ndarray) -> np.ndarray:
    """Brightness of a cylinder's side with outward normal (nx, ny): ambient plus diffuse light."""
    return 0.55 + 0.45 * np.maximum(0.0, nx * _LIGHT[0] + ny * _LIGHT[1])


_TINT_TABLE = np.clip(
    np.round(np.arange(256, dtype=np.float32)[None, :, None] * _TINTS[:, None, :]), 0, 255
).astype(np.uint8).reshape(-1, 3)


def _periodic_blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian blur with wrap-around borders (through the FFT), so the texture tiles seamlessly."""
    f = np.fft.fftfreq(img.shape[0])
    g = np.exp(-2.0 * (np.pi * sigma) ** 2 * (f[:, None] ** 2 + f[None, :] ** 2))
    return np.real(np.fft.ifft2(np.fft.fft2(img) * g)).astype(np.float32)


@functools.lru_cache(maxsize=4)
def make_texture_atlas(seed: int) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """A float32 atlas holding ``_LEVELS`` mip levels of a tileable band-limited noise texture.

    Returns (atlas, [(x_offset, size) per level]); each level is padded by one wrapped texel.
    """
    rng = np.random.default_rng(seed)
    base = np.zeros((_TILE, _TILE), np.float32)
    for sigma, weight in ((1.2, 0.35), (3.0, 0.35), (8.0, 0.30), (24.0, 0.25)):
        noise = rng.standard_normal((_TILE, _TILE)).astype(np.float32)
        blurred = _periodic_blur(noise, sigma)
        blurred /= float(blurred.std()) + 1e-9
        base += weight * blurred
    base = (base - base.mean()) / (base.std() + 1e-9)
    base = np.clip(150.0 + 45.0 * base, 10.0, 250.0).astype(np.float32)
    levels = [base]
    for _ in range(_LEVELS - 1):
        prev = levels[-1]
        levels.append(cv2.resize(prev, (prev.shape[1] // 2, prev.shape[0] // 2), interpolation=cv2.INTER_AREA))
    width = sum(lv.shape[1] + 2 for lv in levels)
    atlas = np.zeros((_TILE + 2, width), np.float32)
    offsets = []
    x = 0
    for lv in levels:
        n = lv.shape[0]
        padded = np.pad(lv, 1, mode="wrap")
        atlas[: n + 2, x : x + n + 2] = padded
        offsets.append((x, n))
        x += n + 2
    atlas.setflags(write=False)
    return atlas, offsets


class ViewRenderer:
    """Renders images of a static wall set plus round obstacles given the camera pose."""

    def __init__(
        self,
        walls: np.ndarray,
        wall_heights_m: np.ndarray,
        wall_reflectivity: np.ndarray,
        room_box: tuple[float, float, float, float],
        ceiling_height_m: float,
        texel_m: float,
        noise_sigma: float,
        texture_seed: int,
    ) -> None:
        self.walls = walls
        self.wall_heights_m = wall_heights_m
        self.wall_gain = (0.7 + 0.5 * wall_reflectivity).astype(np.float32)
        self.room_box = room_box
        self.ceiling_height_m = ceiling_height_m
        self.texel_m = texel_m
        self.noise_sigma = noise_sigma
        self.atlas, self.offsets = make_texture_atlas(texture_seed)
        self._off_x = np.array([o[0] for o in self.offsets], np.float32)
        self._size = np.array([o[1] for o in self.offsets], np.float32)
        self._scale = (1.0 / (texel_m * 2.0 ** np.arange(_LEVELS))).astype(np.float32)

    def render(
        self,
        cam_x_m: float,
        cam_y_m: float,
        cam_z_m: float,
        heading_rad: float,
        tilt_rad: float,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        width_px: int,
        height_px: int,
        obstacles: list[tuple[float, float, float, float, float]],
        rng: np.random.Generator,
        noise_scale: float = 1.0,
    ) -> np.ndarray:
        """BGR uint8 image. ``obstacles``: vertical cylinders (centre x, centre y, radius, z bottom, z top);
        ``noise_scale`` multiplies the sensor noise (a dim scene rendered before the camera's gain)."""
        if tilt_rad == 0.0:
            return self._render_level(
                cam_x_m, cam_y_m, cam_z_m, heading_rad, fx, fy, cx, cy, width_px, height_px, obstacles, rng,
                noise_scale,
            )
        xs = ((np.arange(width_px, dtype=np.float64) - cx) / fx)[None, :]
        ys = ((np.arange(height_px, dtype=np.float64) - cy) / fy)[:, None]
        fwd = math.cos(tilt_rad) + ys * math.sin(tilt_rad)
        up = math.sin(tilt_rad) - ys * math.cos(tilt_rad)
        az = heading_rad - np.arctan2(xs, fwd)  # (H, W)
        tan_el = up / np.hypot(xs, fwd)
        shape = (height_px, width_px)
        dx, dy = np.cos(az), np.sin(az)
        ox = np.full(dx.shape, cam_x_m)
        oy = np.full(dx.shape, cam_y_m)
        d_wall, w_idx, along = cast_walls(ox, oy, dx, dy, self.walls)
        d_wall_b = np.broadcast_to(d_wall, shape)
        w_idx_b = np.broadcast_to(w_idx, shape)
        tan_el = np.broadcast_to(tan_el, shape)
        with np.errstate(invalid="ignore", over="ignore"):
            z_wall = np.where(np.isfinite(d_wall_b), cam_z_m + d_wall_b * tan_el, np.where(tan_el < 0, -np.inf, np.inf))
        wall_h = np.where(w_idx_b >= 0, self.wall_heights_m[np.maximum(w_idx_b, 0)], 0.0)

        label = np.zeros(shape, np.int8)  # open space
        dist = np.full(shape, np.inf)
        s_m = np.zeros(shape)
        t_m = np.zeros(shape)
        dxb, dyb = np.broadcast_to(dx, shape), np.broadcast_to(dy, shape)
        # floor
        down = tan_el < 0
        with np.errstate(divide="ignore"):
            d_floor = np.where(down, cam_z_m / np.where(down, -tan_el, 1.0), np.inf)
        is_floor = down & (z_wall < 0)
        label[is_floor] = 2
        dist[is_floor] = d_floor[is_floor]
        s_m[is_floor] = cam_x_m + d_floor[is_floor] * dxb[is_floor]
        t_m[is_floor] = cam_y_m + d_floor[is_floor] * dyb[is_floor] + 37.0
        foot = np.zeros(shape)
        foot[is_floor] = d_floor[is_floor] * np.sqrt(np.maximum(1.0, d_floor[is_floor] / cam_z_m))
        # walls
        is_wall = (w_idx_b >= 0) & (z_wall >= 0) & (z_wall <= wall_h)
        label[is_wall] = 1
        dist[is_wall] = d_wall_b[is_wall]
        along_b = np.broadcast_to(along, shape)
        s_m[is_wall] = along_b[is_wall] + 11.3 * w_idx_b[is_wall]
        t_m[is_wall] = z_wall[is_wall]
        foot[is_wall] = d_wall_b[is_wall]
        # ceiling (only over the room)
        up_ = tan_el > 0
        ch = self.ceiling_height_m - cam_z_m
        with np.errstate(divide="ignore"):
            d_ceil = np.where(up_, ch / np.where(up_, tan_el, 1.0), np.inf)
        cxh = cam_x_m + d_ceil * dxb
        cyh = cam_y_m + d_ceil * dyb
        x0, y0, x1, y1 = self.room_box
        is_ceil = up_ & ~is_wall & (cxh >= x0) & (cxh <= x1) & (cyh >= y0) & (cyh <= y1) & (d_ceil < d_wall_b + 1e-6)
        label[is_ceil] = 3
        dist[is_ceil] = d_ceil[is_ceil]
        s_m[is_ceil] = cxh[is_ceil] + 3.1
        t_m[is_ceil] = cyh[is_ceil] + 5.7
        foot[is_ceil] = d_ceil[is_ceil] * np.sqrt(np.maximum(1.0, d_ceil[is_ceil] / max(ch, 0.1)))
        # obstacles, front to back does not matter: each only overwrites what is farther
        if obstacles:
            ob = np.asarray(obstacles, dtype=float)
            t_ob = cast_circles(ox, oy, dx, dy, ob[:, 0], ob[:, 1], ob[:, 2])  # (.., K)
            obj_gain = np.ones(shape)
            for k in range(ob.shape[0]):
                tk = np.broadcast_to(t_ob[..., k], shape)
                with np.errstate(invalid="ignore"):
                    zk = cam_z_m + tk * tan_el
                hit = np.isfinite(tk) & (tk < dist) & (zk >= ob[k, 3]) & (zk <= ob[k, 4])
                if not hit.any():
                    continue
                label[hit] = 4 + (k % 4)
                dist[hit] = tk[hit]
                hx = cam_x_m + tk[hit] * dxb[hit] - ob[k, 0]
                hy = cam_y_m + tk[hit] * dyb[hit] - ob[k, 1]
                s_m[hit] = np.arctan2(-hy, -hx) * ob[k, 2] + 23.0 * k + 61.0
                obj_gain[hit] = _lambert(hx / ob[k, 2], hy / ob[k, 2])
                t_m[hit] = zk[hit] + 3.3
                foot[hit] = tk[hit]
        gain = np.where(is_wall, self.wall_gain[np.maximum(w_idx_b, 0)], 1.0)
        if obstacles:
            gain = np.where(label >= 4, obj_gain, gain)
        return self._shade(s_m, t_m, foot / fx, label, gain, rng, noise_scale)

    def _shade(
        self, s_m: np.ndarray, t_m: np.ndarray, foot_m: np.ndarray, label: np.ndarray, gain: np.ndarray,
        rng: np.random.Generator, noise_scale: float = 1.0,
    ) -> np.ndarray:
        """Sample the texture at surface coordinates (s, t) in metres, tint per surface class, add noise."""
        shape = label.shape
        f32 = np.float32
        # trilinear mip-mapping: blend the two levels around the footprint, so the texture does not
        # "pop" (a spurious image change) when a surface crosses a level boundary as the robot moves
        foot32 = np.maximum(foot_m.astype(f32, copy=False), f32(1e-9))
        lf = np.clip(np.log2(foot32 * f32(1.0 / self.texel_m)), f32(0), f32(_LEVELS - 1))
        l0 = np.minimum(np.floor(lf), f32(_LEVELS - 2))
        frac = lf - l0
        # texel coordinates at level 0, wrapped once into the tile; level L is the same tile 2^L
        # times smaller, so its coordinates are these times 2^-L and need no further wrap
        u0 = s_m.astype(f32, copy=False) * f32(1.0 / self.texel_m)
        v0 = t_m.astype(f32, copy=False) * f32(1.0 / self.texel_m)
        u0 -= np.floor(u0 * f32(1.0 / _TILE)) * f32(_TILE)
        v0 -= np.floor(v0 * f32(1.0 / _TILE)) * f32(_TILE)
        p0 = np.exp2(-l0)
        grey = None
        for p, level, wgt in ((p0, l0, f32(1.0) - frac), (p0 * f32(0.5), l0 + f32(1.0), frac)):
            # level L starts at x = sum_{j<L} (TILE/2^j + 2) = 2*TILE*(1 - 2^-L) + 2L in the atlas
            map_x = u0 * p + (f32(1.0 + 2 * _TILE) - f32(2 * _TILE) * p + f32(2.0) * level)
            map_y = v0 * p + f32(1.0)
            sample = cv2.remap(self.atlas, map_x, map_y, interpolation=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REFLECT)
            grey = sample * wgt if grey is None else grey + sample * wgt
        assert grey is not None
        grey *= gain.astype(f32)
        if self.noise_sigma > 0:
            # OpenCV's Gaussian generator is ~3x faster than numpy's here; it is seeded from ``rng`` every
            # frame so images stay reproducible (cv2's RNG is per thread: this reseeds the caller's)
            noise = np.empty(shape, f32)
            cv2.setRNGSeed(int(rng.integers(1 << 31)))
            cv2.randn(noise, 0.0, float(self.noise_sigma * noise_scale))
            grey += noise
        grey_u8 = np.clip(grey, 0.0, 255.0).astype(np.uint8)
        grey_u8[label == 0] = 150
        # tint per surface class through one lookup: table[label * 256 + grey] = BGR
        idx = label.astype(np.intp) * 256 + grey_u8
        return np.take(_TINT_TABLE, idx, axis=0)

    def _render_level(
        self,
        cam_x_m: float,
        cam_y_m: float,
        cam_z_m: float,
        heading_rad: float,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        width_px: int,
        height_px: int,
        obstacles: list[tuple[float, float, float, float, float]],
        rng: np.random.Generator,
        noise_scale: float = 1.0,
    ) -> np.ndarray:
        """Fast path for a level camera (tilt 0): every ray of a column has the same azimuth, so the
        scene is cast once per column and each column is a band of ceiling, wall and floor with the
        obstacles' bands in front."""
        f32 = np.float32
        xs = (np.arange(width_px, dtype=np.float64) - cx) / fx
        az = heading_rad - np.arctan(xs)
        hn = np.sqrt(1.0 + xs * xs)
        yr = (np.arange(height_px, dtype=np.float64) - cy) / fy  # image y per row (down positive)
        q = (-yr[:, None] / hn[None, :]).astype(f32)  # tan(elevation) per pixel
        dx, dy = np.cos(az), np.sin(az)
        ox = np.full(width_px, cam_x_m)
        oy = np.full(width_px, cam_y_m)
        d_wall, w_idx, along = cast_walls(ox, oy, dx, dy, self.walls)
        has_wall = w_idx >= 0
        wi = np.maximum(w_idx, 0)
        wall_h = np.where(has_wall, self.wall_heights_m[wi], 0.0)
        d_safe = np.where(has_wall, d_wall, 1.0)
        q_lo = np.where(has_wall, -cam_z_m / d_safe, 0.0).astype(f32)
        q_hi = np.where(has_wall, (wall_h - cam_z_m) / d_safe, -1.0).astype(f32)
        wall = (q >= q_lo) & (q <= q_hi)
        wall_f = wall.astype(f32)
        # floor (rows below the horizon) and ceiling (above): horizontal distance to the plane is
        # plane_h / |tan(elev)| = (plane_h / |y|)(row) * hn(col)
        ch = self.ceiling_height_m - cam_z_m
        below = yr > 0
        plane_h = np.where(below, cam_z_m, ch)
        row_k = (plane_h / np.maximum(np.abs(yr), 1e-6)).astype(f32)[:, None]
        d_fc = row_k * hn.astype(f32)[None, :]
        s_fc = f32(cam_x_m) + d_fc * dx.astype(f32)
        t_fc = f32(cam_y_m) + d_fc * dy.astype(f32)
        x0, y0, x1, y1 = self.room_box
        up = ~below[:, None]
        open_ = up & ~wall & ((s_fc < x0) | (s_fc > x1) | (t_fc < y0) | (t_fc > y1))
        # labels: 1 wall, 2 floor, 3 ceiling, 0 open space
        label = np.where(below, np.int8(2), np.int8(3))[:, None] * ~wall + wall.astype(np.int8)
        label[open_] = 0
        s_wall = (along + 11.3 * wi).astype(f32)[None, :]
        z_wall = f32(cam_z_m) + d_safe.astype(f32)[None, :] * q
        t_fc += np.where(below, f32(37.0), f32(5.7)).astype(f32)[:, None]
        s_m = s_fc + wall_f * (s_wall - s_fc)
        t_m = t_fc + wall_f * (z_wall - t_fc)
        foot_fc = d_fc * np.sqrt(np.maximum(f32(1.0), d_fc * (1.0 / plane_h).astype(f32)[:, None]))
        foot = foot_fc + wall_f * (d_safe.astype(f32)[None, :] - foot_fc)
        gain = f32(1.0) + wall_f * (self.wall_gain[wi] - f32(1.0))[None, :]
        if obstacles:
            ob = np.asarray(obstacles, dtype=float)
            t_ob = cast_circles(ox, oy, dx, dy, ob[:, 0], ob[:, 1], ob[:, 2])  # (W, K)
            order = np.argsort(np.min(t_ob, axis=0))[::-1]  # paint far to near: nearer bodies occlude
            for k in order:
                tk = t_ob[:, k]
                visible = np.isfinite(tk) & (tk < np.where(has_wall, d_wall, np.inf))
                if not visible.any():
                    continue
                tks = np.where(visible, tk, 1.0)
                lo = np.where(visible, (ob[k, 3] - cam_z_m) / np.maximum(tks, 1e-6), 1.0).astype(f32)
                hi = np.where(visible, (ob[k, 4] - cam_z_m) / np.maximum(tks, 1e-6), -1.0).astype(f32)
                hit = (q >= lo) & (q <= hi)
                hit_f = hit.astype(f32)
                hx = cam_x_m + tks * dx - ob[k, 0]
                hy = cam_y_m + tks * dy - ob[k, 1]
                s_ob = (np.arctan2(-hy, -hx) * ob[k, 2] + 23.0 * k + 61.0).astype(f32)[None, :]
                tk32 = tks.astype(f32)[None, :]
                label[hit] = 4 + (k % 4)
                s_m += hit_f * (s_ob - s_m)
                t_m += hit_f * ((f32(cam_z_m + 3.3) + tk32 * q) - t_m)
                foot += hit_f * (tk32 - foot)
                shade = _lambert(hx / ob[k, 2], hy / ob[k, 2]).astype(f32)[None, :]
                gain += hit_f * (shade - gain)
        return self._shade(s_m, t_m, foot / f32(fx), label, gain, rng, noise_scale)
