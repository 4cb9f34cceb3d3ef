"""The simulated world with one clock: the robot plant, scripted obstacles, the sensors, the truth.

All queries are thread-safe (one re-entrant lock) and advance the world lazily to the queried time
in fixed integration steps (10 ms); a pose history (``history_s``, default 5 s) serves queries in the past
by interpolation, so several fake threads may ask for slightly different times in any order.

Times: ``start_s`` is the caller's clock value at which the scenario's time 0 happens (the daemon's
``sim`` passes ``time.monotonic()``; the evaluation uses 0). Every method takes times on that clock.
A velocity command applies from the world's current time: if another query already advanced the
world past the command's ``now_s`` (a sweep's last beam can be 19 ms ahead), the command takes effect
that little later.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from hil_fakes.kinematics import Unicycle
from hil_fakes.wheel_odometry import WheelOdometry

from .geometry import cast_circles, cast_walls, walls_array
from .render import ViewRenderer
from .scenarios import ROOM_LENGTH_M, ROOM_WIDTH_M, Scenario
from .sensors import CameraModel, LaserModel, RobotMount, intrinsics


class WorldTimeError(ValueError):
    """A query for a time older than the world's retained history, or implausibly far ahead."""


@dataclass(frozen=True)
class ObstacleTruth:
    index: int
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    radius_m: float
    moving: bool


@dataclass(frozen=True)
class Truth:
    stamp_s: float
    x_m: float
    y_m: float
    theta_rad: float
    v_mps: float
    w_radps: float
    obstacles: tuple[ObstacleTruth, ...]


@dataclass(frozen=True)
class LaserSweep:
    ranges_m: np.ndarray  # NaN = no return
    intensities: np.ndarray
    hit_obstacle: np.ndarray  # index of the obstacle each beam hit, -1 for walls / no return
    t0_s: float
    beam_dt_s: float


# history columns
_T, _X, _Y, _TH, _V, _W, _OX, _OY, _OTH = range(9)


class World:
    def __init__(
        self,
        scenario: Scenario,
        *,
        mount: RobotMount | None = None,
        laser: LaserModel | None = None,
        camera: CameraModel | None = None,
        start_s: float = 0.0,
        step_s: float = 0.01,
        history_s: float = 5.0,
        max_jump_s: float = 3600.0,
    ) -> None:
        self.scenario = scenario
        self.mount = mount or RobotMount()
        self.laser = laser or LaserModel()
        self.camera = camera or CameraModel()
        self.start_s = float(start_s)
        self.step_s = float(step_s)
        self.history_s = float(history_s)
        #: a query further ahead than this is refused (a wrong clock would otherwise integrate for ever)
        self.max_jump_s = float(max_jump_s)
        self._lock = threading.RLock()
        x0, y0, th0 = scenario.robot_start
        self._robot = Unicycle(x_m=x0, y_m=y0, theta_rad=th0)
        self._odom = WheelOdometry(scenario.odometry_noise, x0, y0, th0)
        self._th_unwrapped = th0
        self._t = self.start_s
        self._hist = np.zeros((4096, 9))
        self._h0 = 0
        self._n = 0
        self._append()
        self._rng = np.random.default_rng([scenario.seed, 1])
        self._cam_rng = np.random.default_rng([scenario.seed, 2])
        self._walls = walls_array(scenario.walls)
        self._radii = np.array([o.radius_m for o in scenario.obstacles])
        self._obs_refl = np.array([o.reflectivity for o in scenario.obstacles])
        self._wall_refl = np.array([w.reflectivity for w in scenario.walls])
        self._view: ViewRenderer | None = None

    # ------------------------------------------------------------------ clock and history
    @property
    def now_s(self) -> float:
        with self._lock:
            return self._t

    def _append(self) -> None:
        if self._h0 + self._n >= self._hist.shape[0]:
            keep = self._hist[self._h0 : self._h0 + self._n]
            if self._n * 2 > self._hist.shape[0]:
                self._hist = np.zeros((self._hist.shape[0] * 2, 9))
            self._hist[: self._n] = keep
            self._h0 = 0
        r = self._robot
        ox, oy, _ = self._odom.pose()
        self._hist[self._h0 + self._n] = (
            self._t, r.x_m, r.y_m, self._th_unwrapped, r.v_mps, r.w_radps, ox, oy, self._odom.heading_unwrapped_rad
        )
        self._n += 1

    def _trim(self) -> None:
        t_keep = self._t - self.history_s
        h = self._hist[self._h0 : self._h0 + self._n, _T]
        drop = int(np.searchsorted(h, t_keep, side="left")) - 1
        if drop > 0:
            self._h0 += drop
            self._n -= drop

    def advance_to(self, t_s: float) -> None:
        """Integrate the robot (and its odometry) up to ``t_s`` on the world clock."""
        with self._lock:
            if t_s <= self._t:
                return
            if not math.isfinite(t_s) or t_s - self._t > self.max_jump_s:
                raise WorldTimeError(
                    f"time {t_s!r} is more than {self.max_jump_s} s ahead of the world ({self._t:.3f} s): wrong clock?"
                )
            r = self._robot
            while self._t < t_s - 1e-12:
                dt = min(self.step_s, t_s - self._t)
                r.advance(dt)
                ds, dth = r.v_mps * dt, r.w_radps * dt
                self._th_unwrapped += dth
                self._odom.step(ds, dth)
                self._t += dt
                self._append()
            self._trim()

    def _history(self) -> np.ndarray:
        return self._hist[self._h0 : self._h0 + self._n]

    def _interp(self, t_s: np.ndarray, cols: tuple[int, ...]) -> list[np.ndarray]:
        """History columns at the times ``t_s`` (advancing the world first if needed)."""
        t = np.asarray(t_s, dtype=float)
        tmax = float(np.max(t)) if t.size else self._t
        self.advance_to(tmax)
        h = self._history()
        if t.size and float(np.min(t)) < h[0, _T] - 1e-9 and h[0, _T] > self.start_s + 1e-9:
            raise WorldTimeError(
                f"time {float(np.min(t)):.3f} s is older than the world's history (from {h[0, _T]:.3f} s)"
            )
        return [np.interp(t, h[:, _T], h[:, c]) for c in cols]

    # ------------------------------------------------------------------ truth
    def robot_pose(self, t_s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        with self._lock:
            x, y, th = self._interp(np.asarray(t_s, float), (_X, _Y, _TH))
            return x, y, th

    def obstacle_centres(self, t_s: np.ndarray | float) -> np.ndarray:
        """(..., K, 2) obstacle centres at the times ``t_s`` (scenario clock offset applied)."""
        t = np.asarray(t_s, float) - self.start_s
        if not self.scenario.obstacles:
            return np.zeros(t.shape + (0, 2))
        return np.stack([o.positions(t) for o in self.scenario.obstacles], axis=-2)

    def truth(self, t_s: float) -> Truth:
        """True robot state and obstacles at ``t_s``."""
        with self._lock:
            x, y, th, v, w = (float(a) for a in self._interp(np.array(t_s, float), (_X, _Y, _TH, _V, _W)))
        ts = t_s - self.start_s
        obs = []
        for i, o in enumerate(self.scenario.obstacles):
            p = o.positions(ts)
            vel = o.velocities(ts)
            obs.append(
                ObstacleTruth(i, float(p[0]), float(p[1]), float(vel[0]), float(vel[1]), o.radius_m,
                              bool(np.hypot(*vel) > 0))
            )
        return Truth(t_s, x, y, math.atan2(math.sin(th), math.cos(th)), v, w, tuple(obs))

    def odometry(self, t_s: float) -> tuple[float, float, float, float, float]:
        """The wheel odometry (x_m, y_m, theta_rad, v_mps, w_radps) at ``t_s`` (noisy pose; the
        velocities are the odometry's own: true ones scaled by the scale error)."""
        with self._lock:
            x, y, th, v, w = (float(a) for a in self._interp(np.array(t_s, float), (_OX, _OY, _OTH, _V, _W)))
        v *= 1.0 + self.scenario.odometry_noise.scale_error
        return x, y, math.atan2(math.sin(th), math.cos(th)), v, w

    # ------------------------------------------------------------------ laser
    def sweep(
        self, t0_s: float, angles_rad: np.ndarray | None = None, beam_dt_s: float | None = None
    ) -> LaserSweep:
        """Ray-cast one UTM-30LX sweep: beam i at ``t0_s + i*beam_dt_s`` from the laser's pose then,
        against the walls and the obstacles where they are then."""
        lm = self.laser
        a = lm.angles_rad() if angles_rad is None else np.asarray(angles_rad, float)
        dt = lm.beam_dt_s if beam_dt_s is None else float(beam_dt_s)
        times = t0_s + np.arange(a.size) * dt
        with self._lock:
            x, y, th = self._interp(times, (_X, _Y, _TH))
            noise = self._rng.standard_normal(a.size)
        m = self.mount
        c, s = np.cos(th), np.sin(th)
        ox = x + c * m.laser_x_m - s * m.laser_y_m
        oy = y + s * m.laser_x_m + c * m.laser_y_m
        ang = th + m.laser_theta_rad + a
        dx, dy = np.cos(ang), np.sin(ang)
        d_wall, w_idx, _ = cast_walls(ox, oy, dx, dy, self._walls)
        dist = d_wall
        hit_ob = np.full(a.size, -1, dtype=np.int64)
        refl = np.where(w_idx >= 0, self._wall_refl[np.maximum(w_idx, 0)] if self._wall_refl.size else 0.0, 0.0)
        if self.scenario.obstacles:
            centres = self.obstacle_centres(times)  # (N, K, 2)
            t_ob = cast_circles(ox, oy, dx, dy, centres[..., 0], centres[..., 1], self._radii)
            k = np.argmin(t_ob, axis=1)
            t_k = t_ob[np.arange(a.size), k]
            closer = t_k < dist
            dist = np.where(closer, t_k, dist)
            hit_ob = np.where(closer, k, -1)
            refl = np.where(closer, self._obs_refl[k], refl)
        sigma = np.where(dist <= lm.near_limit_m, lm.sigma_near_m, lm.sigma_far_m)
        finite = np.isfinite(dist)
        ranges = np.where(finite, dist + sigma * noise, np.nan)
        bad = ~finite | (ranges > lm.max_range_m) | (ranges < lm.dmin_m)
        ranges[bad] = np.nan
        hit_ob[bad] = -1
        # intensity: reflectivity, incidence (normal of a wall / radial on a cylinder ~ ray), 1/(1+r/3)
        inten = np.where(bad, 0.0, lm.intensity_scale * refl / (1.0 + np.nan_to_num(ranges) / 3.0))
        return LaserSweep(ranges, inten, hit_ob, float(t0_s), dt)

    # ------------------------------------------------------------------ camera
    def _view_renderer(self) -> ViewRenderer:
        if self._view is None:
            cm = self.camera
            if self._walls.shape[0]:  # the ceiling covers the walls' bounding box
                xs, ys = self._walls[:, [0, 2]], self._walls[:, [1, 3]]
                box = (float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max()))
            else:
                box = (0.0, -ROOM_WIDTH_M / 2, ROOM_LENGTH_M, ROOM_WIDTH_M / 2)
            self._view = ViewRenderer(
                self._walls,
                np.array([w.height_m for w in self.scenario.walls]),
                self._wall_refl,
                box,
                cm.ceiling_height_m,
                cm.texel_m,
                cm.noise_sigma,
                cm.texture_seed,
            )
        return self._view

    def render(
        self,
        t_s: float,
        pan_rad: float = 0.0,
        tilt_rad: float = 0.0,
        hfov_rad: float | None = None,
        width_px: int | None = None,
        height_px: int | None = None,
    ) -> np.ndarray:
        """The camera image (BGR uint8) at ``t_s`` with the given pan/tilt/HFOV."""
        cm = self.camera
        w = width_px or cm.width_px
        h = height_px or cm.height_px
        hfov = cm.hfov_wide_rad if hfov_rad is None else hfov_rad
        fx, fy, cx, cy = intrinsics(w, h, hfov)
        with self._lock:
            x, y, th = (float(v) for v in self._interp(np.array(t_s, float), (_X, _Y, _TH)))
            view = self._view_renderer()
            rng = np.random.default_rng(self._cam_rng.integers(1 << 62))
        m = self.mount
        c, s = math.cos(th), math.sin(th)
        cam_x = x + c * m.camera_x_m - s * m.camera_y_m
        cam_y = y + s * m.camera_x_m + c * m.camera_y_m
        centres = self.obstacle_centres(np.array(t_s, float))
        obs = [
            (float(centres[k, 0]), float(centres[k, 1]), o.radius_m, o.height_m)
            for k, o in enumerate(self.scenario.obstacles)
        ]
        return view.render(cam_x, cam_y, m.camera_z_m, th + pan_rad, tilt_rad, fx, fy, cx, cy, w, h, obs, rng)

    # ------------------------------------------------------------------ sonar
    def sonar_range_m(
        self, x_m: float, y_m: float, angle_rad: float, max_range_m: float, t_s: float | None = None
    ) -> float:
        """Distance along a world ray to the first wall or obstacle at ``t_s`` (default: world time)."""
        with self._lock:
            t = self._t if t_s is None else t_s
        ox, oy = np.array([x_m]), np.array([y_m])
        dx, dy = np.array([math.cos(angle_rad)]), np.array([math.sin(angle_rad)])
        d, _, _ = cast_walls(ox, oy, dx, dy, self._walls)
        dist = float(d[0])
        if self.scenario.obstacles:
            c = self.obstacle_centres(np.array([t]))  # (1, K, 2)
            t_ob = cast_circles(ox, oy, dx, dy, c[..., 0], c[..., 1], self._radii)
            dist = min(dist, float(np.min(t_ob)))
        return dist if dist <= max_range_m else math.nan

    # ------------------------------------------------------------------ adapters for the fakes
    def range_source(self) -> RangeSourceAdapter:
        return RangeSourceAdapter(self)

    def plant(self) -> PlantAdapter:
        return PlantAdapter(self)

    def sonar(self) -> SonarAdapter:
        return SonarAdapter(self)

    def renderer(self, width_px: int = 320, height_px: int = 240) -> RendererAdapter:
        return RendererAdapter(self, width_px, height_px)

    def command(self, v_mps: float, w_radps: float, now_s: float) -> None:
        with self._lock:
            self.advance_to(now_s)
            self._robot.command(v_mps, w_radps)

    def e_stop(self, now_s: float) -> None:
        with self._lock:
            self.advance_to(now_s)
            self._robot.stop_now()
            self._hist[self._h0 + self._n - 1, _V : _W + 1] = 0.0

    def state(self, now_s: float) -> tuple[float, float, float, float, float]:
        with self._lock:
            x, y, th, v, w = (float(a) for a in self._interp(np.array(now_s, float), (_X, _Y, _TH, _V, _W)))
        return x, y, math.atan2(math.sin(th), math.cos(th)), v, w


class RangeSourceAdapter:
    """hil_fakes.utm30lx.RangeSource over the world."""

    def __init__(self, world: World) -> None:
        self.world = world

    def sweep(self, t0_s: float, angles_rad: np.ndarray, beam_dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        s = self.world.sweep(t0_s, angles_rad, beam_dt_s)
        return s.ranges_m, s.intensities


class PlantAdapter:
    """hil_fakes.pioneer.Plant over the world's robot."""

    def __init__(self, world: World) -> None:
        self.world = world

    def command(self, v_mps: float, w_radps: float, now_s: float) -> None:
        self.world.command(v_mps, w_radps, now_s)

    def e_stop(self, now_s: float) -> None:
        self.world.e_stop(now_s)

    def state(self, now_s: float) -> tuple[float, float, float, float, float]:
        return self.world.state(now_s)


class SonarAdapter:
    """hil_fakes.pioneer.SonarWorld over the world (obstacles where they are at the world's time)."""

    def __init__(self, world: World) -> None:
        self.world = world

    def ray_range_m(self, x_m: float, y_m: float, angle_rad: float, max_range_m: float) -> float:
        return self.world.sonar_range_m(x_m, y_m, angle_rad, max_range_m)


class RendererAdapter:
    """hil_fakes.snc_rz50.Renderer over the world."""

    def __init__(self, world: World, width_px: int, height_px: int) -> None:
        self.world = world
        self.width_px = int(width_px)
        self.height_px = int(height_px)

    def render(self, t_s: float, pan_rad: float, tilt_rad: float, hfov_rad: float) -> np.ndarray:
        return self.world.render(t_s, pan_rad, tilt_rad, hfov_rad, self.width_px, self.height_px)
