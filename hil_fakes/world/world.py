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

import cv2
import numpy as np

from hil_fakes.kinematics import Unicycle
from hil_fakes.wheel_odometry import WheelOdometry

from .camera_effects import CameraClock, distortion_maps, light_and_gain, photometric
from .geometry import RigidBox, cast_boxes, cast_circles, cast_walls, walls_array
from .laser_effects import footprint_return
from .people import body_parts, leg_centres
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
    #: "cylinder", "person" (x_m, y_m is then the body centre, radius_m the body's radius), or a rigid
    #: box: "cart" (pushed by a person), "door" (a panel turning about its hinge); radius_m: its half diagonal
    kind: str = "cylinder"
    #: a person's leg centres at the laser's height
    legs: tuple[tuple[float, float], ...] = ()


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
        self._fx_rng = np.random.default_rng([scenario.seed, 3])
        seen = [w.height_m >= self.mount.laser_z_m for w in scenario.walls]
        self._laser_walls = self._walls[np.array(seen, bool)] if scenario.walls else self._walls
        self._laser_wall_refl = np.array([w.reflectivity for w, ok in zip(scenario.walls, seen, strict=True) if ok])
        z = self.mount.laser_z_m
        self._static = np.array(
            [(c.x_m, c.y_m, c.radius_m, c.reflectivity) for c in scenario.clutter.circles if c.z0_m <= z <= c.z1_m],
            dtype=float,
        ).reshape(-1, 4)
        self._clock = CameraClock(scenario.camera_effects, scenario.seed)
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
            legs: tuple[tuple[float, float], ...] = ()
            if o.gait is not None:
                lc = leg_centres(o, o.gait, np.array(ts), self.mount.laser_z_m)
                legs = tuple((float(a), float(b)) for a, b in lc)
            obs.append(
                ObstacleTruth(i, float(p[0]), float(p[1]), float(vel[0]), float(vel[1]), o.radius_m,
                              bool(np.hypot(*vel) > 0), o.kind, legs)
            )
        return Truth(t_s, x, y, math.atan2(math.sin(th), math.cos(th)), v, w, tuple(obs))

    def odometry(self, t_s: float) -> tuple[float, float, float, float, float]:
        """The wheel odometry (x_m, y_m, theta_rad, v_mps, w_radps) at ``t_s`` (noisy pose; the
        velocities are the odometry's own: true ones scaled by the scale error).

        The realistic world reports the state ``sip_delay_s`` before ``t_s`` (the controller samples its
        encoders before it sends the SIP) in ARCOS integer units (mm, 2 pi / 4096 rad, mm/s)."""
        sc = self.scenario
        with self._lock:
            t_q = max(t_s - sc.sip_delay_s, self.start_s)
            x, y, th, v, w = (float(a) for a in self._interp(np.array(t_q, float), (_OX, _OY, _OTH, _V, _W)))
        v *= 1.0 + sc.odometry_noise.scale_error
        th = math.atan2(math.sin(th), math.cos(th))
        if sc.odom_quantize:
            unit = 2 * math.pi / 4096
            x, y, v = round(x * 1000) / 1000, round(y * 1000) / 1000, round(v * 1000) / 1000
            th, w = round(th / unit) * unit, round(w / math.radians(0.1)) * math.radians(0.1)
        return x, y, th, v, w

    # ------------------------------------------------------------------ laser
    def sweep(
        self, t0_s: float, angles_rad: np.ndarray | None = None, beam_dt_s: float | None = None
    ) -> LaserSweep:
        """Ray-cast one UTM-30LX sweep: beam i at ``t0_s + i*beam_dt_s`` from the laser's pose then,
        against the walls, the clutter and the moving bodies where they are then; in the realistic
        world through the beam's footprint with the artefacts of :mod:`.laser_effects`."""
        lm = self.laser
        fx = self.scenario.laser_effects
        a = lm.angles_rad() if angles_rad is None else np.asarray(angles_rad, float)
        dt = lm.beam_dt_s if beam_dt_s is None else float(beam_dt_s)
        times = t0_s + np.arange(a.size) * dt
        with self._lock:
            x, y, th = self._interp(times, (_X, _Y, _TH))
            noise = self._rng.standard_normal(a.size)
            fx_rng = np.random.default_rng(self._fx_rng.integers(1 << 62))
        m = self.mount
        c, s = np.cos(th), np.sin(th)
        ox = x + c * m.laser_x_m - s * m.laser_y_m
        oy = y + s * m.laser_x_m + c * m.laser_y_m
        ang = (th + m.laser_theta_rad + a)[:, None] + fx.offsets_rad()[None, :]
        dist, owner, refl_s, cos_inc, surface = self._cast_laser(ox[:, None], oy[:, None], ang, times)
        if fx.enabled:
            dist0, src = footprint_return(dist, cos_inc, surface, fx, fx_rng, refl_s)
            pick = np.maximum(src, 0)[:, None]
            hit_ob = np.where(src >= 0, np.take_along_axis(owner, pick, axis=1)[:, 0], -1)
            refl = np.where(src >= 0, np.take_along_axis(refl_s, pick, axis=1)[:, 0], 0.4)
        else:
            dist0, hit_ob, refl = dist[:, 0], owner[:, 0], refl_s[:, 0]
        finite = np.isfinite(dist0)
        sigma = lm.sigma_m(np.where(finite, dist0, 0.0)) * self.scenario.laser_effects.noise_scale
        ranges = np.where(finite, dist0 + sigma * noise, np.nan)
        bad = ~finite | (ranges > lm.max_range_m) | (ranges < lm.dmin_m)
        ranges[bad] = np.nan
        hit_ob = np.where(bad, -1, hit_ob)
        # intensity: reflectivity, incidence (normal of a wall / radial on a cylinder ~ ray), 1/(1+r/3)
        inten = np.where(bad, 0.0, lm.intensity_scale * refl / (1.0 + np.nan_to_num(ranges) / 3.0))
        return LaserSweep(ranges, inten, hit_ob, float(t0_s), dt)

    def _moving_circles(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Circles of the moving bodies at the laser's height at ``times`` (N,): centres (N, K, 2),
        radii (K,), owner obstacle index (K,). A person is two legs, a cylinder one circle."""
        centres, radii, owners = [], [], []
        t = np.asarray(times, float) - self.start_s
        for k, o in enumerate(self.scenario.obstacles):
            if isinstance(o, RigidBox):
                continue
            if o.gait is None:
                centres.append(o.positions(t)[..., None, :])
                radii.append(o.radius_m)
                owners.append(k)
            else:
                centres.append(leg_centres(o, o.gait, t, self.mount.laser_z_m))
                radii += [o.gait.leg_radius_m] * 2
                owners += [k, k]
        if not centres:
            return np.zeros(t.shape + (0, 2)), np.zeros(0), np.zeros(0, np.int64)
        return np.concatenate(centres, axis=-2), np.array(radii), np.array(owners, np.int64)

    def _cast_laser(
        self, ox: np.ndarray, oy: np.ndarray, ang: np.ndarray, times: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """First hit of rays from (ox, oy) (N, 1) at angles ``ang`` (N, S): distance (inf: none), owner
        (obstacle index, -1 static), reflectivity, cosine of the incidence and the surface hit (wall
        index, 100000 + circle index, -1 none), each (N, S)."""
        dx, dy = np.cos(ang), np.sin(ang)
        lw = self._laser_walls
        dist, w_idx, _ = cast_walls(ox, oy, dx, dy, lw)
        wi = np.maximum(w_idx, 0)
        refl = np.where(w_idx >= 0, self._laser_wall_refl[wi] if lw.shape[0] else 0.0, 0.0)
        if lw.shape[0]:
            ex, ey = (lw[:, 2] - lw[:, 0])[wi], (lw[:, 3] - lw[:, 1])[wi]
            cos_inc = np.abs(dx * ey - dy * ex) / np.maximum(np.hypot(ex, ey), 1e-12)
        else:
            cos_inc = np.ones_like(dist)
        owner = np.full(dist.shape, -1, dtype=np.int64)
        surface = w_idx.copy()
        centres, radii, owners = self._moving_circles(times)
        cx, cy = centres[:, None, :, 0], centres[:, None, :, 1]
        if self._static.shape[0]:
            cx = np.concatenate([cx, np.broadcast_to(self._static[:, 0], cx.shape[:2] + (len(self._static),))], -1)
            cy = np.concatenate([cy, np.broadcast_to(self._static[:, 1], cy.shape[:2] + (len(self._static),))], -1)
            radii = np.concatenate([radii, self._static[:, 2]])
            owners = np.concatenate([owners, np.full(len(self._static), -1, np.int64)])
        if radii.size:
            refl_c = np.concatenate([self._obs_refl[owners[owners >= 0]], self._static[:, 3]])
            t_c = cast_circles(np.broadcast_to(ox, dx.shape), np.broadcast_to(oy, dy.shape), dx, dy, cx, cy, radii)
            k = np.argmin(t_c, axis=-1)
            t_k = np.take_along_axis(t_c, k[..., None], axis=-1)[..., 0]
            closer = t_k < dist
            t_k = np.where(closer, t_k, 0.0)
            hx = ox + t_k * dx - np.take_along_axis(cx, k[..., None], axis=-1)[..., 0]
            hy = oy + t_k * dy - np.take_along_axis(cy, k[..., None], axis=-1)[..., 0]
            with np.errstate(invalid="ignore"):
                cos_c = np.abs(hx * dx + hy * dy) / radii[k]
            dist = np.where(closer, t_k, dist)
            owner = np.where(closer, owners[k], owner)
            refl = np.where(closer, refl_c[k], refl)
            cos_inc = np.where(closer, np.nan_to_num(cos_c, nan=1.0), cos_inc)
            surface = np.where(closer, 100000 + k, surface)
        return self._cast_boxes(ox, oy, dx, dy, times, (dist, owner, refl, cos_inc, surface))

    def _cast_boxes(
        self, ox: np.ndarray, oy: np.ndarray, dx: np.ndarray, dy: np.ndarray, times: np.ndarray,
        hits: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The rigid boxes (carts, doors) crossing the laser's plane, where they are at each beam's time,
        in front of the first hits found so far (surface id 200000 + box index)."""
        z = self.mount.laser_z_m
        boxes = [(k, o) for k, o in enumerate(self.scenario.obstacles)
                 if isinstance(o, RigidBox) and o.z0_m <= z <= o.height_m]
        dist, owner, refl, cos_inc, surface = hits
        if not boxes:
            return hits
        t = np.asarray(times, float) - self.start_s
        poses = np.stack([o.poses(t) for _, o in boxes], axis=-2)  # (N, K, 3)
        half = np.array([(o.length_m / 2, o.width_m / 2) for _, o in boxes])
        t_b, cos_b = cast_boxes(np.broadcast_to(ox, dx.shape), np.broadcast_to(oy, dy.shape), dx, dy, poses, half)
        j = np.argmin(t_b, axis=-1)
        t_j = np.take_along_axis(t_b, j[..., None], axis=-1)[..., 0]
        closer = t_j < dist
        index = np.array([k for k, _ in boxes])
        refl_b = np.array([o.reflectivity for _, o in boxes])
        return (np.where(closer, t_j, dist), np.where(closer, index[j], owner), np.where(closer, refl_b[j], refl),
                np.where(closer, np.take_along_axis(cos_b, j[..., None], axis=-1)[..., 0], cos_inc),
                np.where(closer, 200000 + index[j], surface))

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
        """The camera image (BGR uint8) exposed at ``t_s`` with the given pan/tilt/HFOV; in the realistic
        world through the lens, mount and photometry of :mod:`.camera_effects`."""
        cm = self.camera
        fx_ = self.scenario.camera_effects
        w = width_px or cm.width_px
        h = height_px or cm.height_px
        hfov = cm.hfov_wide_rad if hfov_rad is None else hfov_rad
        fx, fy, cx, cy = intrinsics(w, h, hfov)
        if not fx_.enabled:
            return self._render_pinhole(t_s, pan_rad, tilt_rad, (fx, fy, cx, cy), w, h)
        margin = int(0.12 * max(w, h))
        cxt, cyt = cx + fx_.pp_offset_px[0], cy + fx_.pp_offset_px[1]
        times = (t_s - fx_.exposure_s / 2, t_s + fx_.exposure_s / 2) if fx_.exposure_s > 0 else (t_s,)
        k = (fx, fy, cxt + margin, cyt + margin)
        # a dim room (lights off) is rendered with the sensor noise 1 / level as large against the scene:
        # the camera's gain then scales both, so the image has the old brightness and gain x the noise
        level, gain = light_and_gain(t_s, fx_)
        shots = [self._render_pinhole(t, pan_rad + fx_.mount_yaw_rad, tilt_rad, k, w + 2 * margin, h + 2 * margin,
                                      1.0 / level)
                 for t in times]
        img = shots[0] if len(shots) == 1 else cv2.addWeighted(shots[0], 0.5, shots[1], 0.5, 0.0)
        map_x, map_y = distortion_maps(w, h, fx, fy, cxt, cyt, fx_.k1, fx_.k2, margin)
        img = cv2.remap(img, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return photometric(img, self._clock.exposure_gain(t_s) * level * gain, fx_)

    @property
    def camera_clock(self) -> CameraClock:
        """The camera's free-running frame clock (capture instants and delivery latencies)."""
        return self._clock

    def _camera_bodies(self, t_s: float) -> list[tuple[float, float, float, float, float]]:
        """Vertical cylinders (x, y, radius, z0, z1) the camera sees at ``t_s`` besides the walls."""
        t = np.array(t_s - self.start_s, float)
        out: list[tuple[float, float, float, float, float]] = []
        for o in self.scenario.obstacles:
            if o.gait is None:
                out.extend(o.camera_parts(float(t)))
            else:
                out.extend(body_parts(o, o.gait, float(t)))
        out.extend((c.x_m, c.y_m, c.radius_m, c.z0_m, c.z1_m) for c in self.scenario.clutter.circles)
        return out

    def _render_pinhole(
        self, t_s: float, pan_rad: float, tilt_rad: float, k: tuple[float, float, float, float], w: int, h: int,
        noise_scale: float = 1.0,
    ) -> np.ndarray:
        fx, fy, cx, cy = k
        with self._lock:
            x, y, th = (float(v) for v in self._interp(np.array(t_s, float), (_X, _Y, _TH)))
            view = self._view_renderer()
            rng = np.random.default_rng(self._cam_rng.integers(1 << 62))
        m = self.mount
        c, s = math.cos(th), math.sin(th)
        cam_x = x + c * m.camera_x_m - s * m.camera_y_m
        cam_y = y + s * m.camera_x_m + c * m.camera_y_m
        bodies = self._camera_bodies(t_s)
        return view.render(cam_x, cam_y, m.camera_z_m, th + pan_rad, tilt_rad, fx, fy, cx, cy, w, h, bodies, rng,
                           noise_scale)

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
        """The state the controller samples for the SIP it sends at ``now_s`` (``sip_delay_s`` before)."""
        return self.world.state(now_s - self.world.scenario.sip_delay_s)


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
        self._rng = np.random.default_rng([world.scenario.seed, 9])
        self.width_px = int(width_px)
        self.height_px = int(height_px)

    def render(self, t_s: float, pan_rad: float, tilt_rad: float, hfov_rad: float) -> np.ndarray:
        """The frame the camera delivers at ``t_s``: exposed one capture-to-delivery latency earlier."""
        lo, hi = self.world.scenario.camera_effects.latency_s
        latency = self._rng.uniform(lo, hi) if self.world.scenario.camera_effects.enabled else 0.0
        return self.world.render(t_s - latency, pan_rad, tilt_rad, hfov_rad, self.width_px, self.height_px)
