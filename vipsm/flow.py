"""Visual bearing of moving obstacles (the paper's step 1): dense optical flow between consecutive
frames, the robot's own image motion predicted from odometry and the previous laser scan and
removed, pixels whose remaining flow exceeds a speed-dependent threshold (the paper's alpha, eq. 1)
grouped into blobs, each blob's columns turned into a bearing interval.

Ego-motion prediction: every image column's viewing direction is known from the intrinsics and
the pan angle; the previous laser scan, seen from the camera's position, gives the horizontal
distance to the first surface along that direction (walls and bodies are vertical), and the floor
plane gives the distance of pixels below the horizon that hit the floor first. Those 3-D points are
moved by the odometry between the two frames and re-projected with the new pan/tilt: the
difference is the flow a static scene would show.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import cv2
import numpy as np
from numba import njit

from .distortion import distort, undistort
from .geometry import between, inverse, transform_point
from .restore import BearingInterval
from .types import Frame, Odometry, Pose2D

#: Numerical-method constants (not tuned parameters of the scene; issue 29 moved them out of the config):
#: frames wider than this are scaled down to it first (the flow's cost, and the pixel unit of the
#: thresholds below, are set at this working width)
WORK_WIDTH_PX = 320
#: OpenCV's DIS optical flow preset: ultrafast (patch 8 px, 12 gradient-descent steps, no variational step)
DIS_PRESET = cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST
#: the residual flow is evaluated on a grid of this step (px at the working width)
GRID_STEP_PX = 4
#: the moving cells are opened (specks gone) and closed (one body's fragments joined) with a square of
#: this many grid cells: the smallest symmetric kernel (the former ``open_px`` 6 and ``close_px`` 10 both
#: rounded to it at the 4 px grid)
MORPH_CELLS = 3


@dataclass(frozen=True)
class FlowConfig:
    """The flow stage's keys: times of the camera's frames, the flow's noise and the odometry's errors in
    pixels (at the working width ``WORK_WIDTH_PX``), depth edges in metres. Keys removed in the reduction of
    issue 29 are listed in ``REMOVED_KEYS``."""

    #: flow against the oldest kept frame at most this much older: a slow body's image motion grows with
    #: the baseline, the flow's noise does not
    baseline_s: float = 0.30
    #: frames further apart than this are not compared (the image moved too far for the flow to follow)
    max_frame_gap_s: float = 0.5
    #: the paper's threshold alpha (eq. 1), in px at the working width: the flow's own noise with the robot
    #: at rest ...
    alpha_base_px: float = 0.8
    #: ... growing with the distance driven and the angle turned between the two frames (the odometry's
    #: errors over that motion, as image motion; 30 px/rad is a 0.1 rad/rad heading error at the 54 deg
    #: camera's 314 px focal length) ...
    alpha_v_px_per_m: float = 10.0
    alpha_w_px_per_rad: float = 30.0
    #: ... up to this (a fast turn's threshold would hide every body)
    alpha_max_px: float = 6.0
    #: plus this share of the predicted flow: the depth behind each cell (nearest laser point, the floor
    #: plane) is good to about a quarter, and the prediction's error scales with it
    alpha_rel: float = 0.25
    #: cells with less image gradient than this (grey levels / px) carry no flow: a few times the camera's
    #: grey-level noise
    min_texture: float = 6.0
    #: a blob of moving cells smaller than this (px at the working width) is noise, not a body (a leg
    #: 0.1 m wide and 0.5 m high at 6 m covers about 6 x 30 px)
    min_blob_px: int = 250
    #: a blob's column belongs to the body when this share of its usable cells move (the closing's
    #: sparse fringe does not)
    column_share: float = 0.3
    #: the global fit of the residual (shift + scale of the predicted flow: the odometry's heading and
    #: distance errors between the two frames) corrects at most this shift (8 px: 1.5 deg at a 54 deg
    #: camera's 314 px focal length) ...
    global_shift_max_px: float = 8.0
    #: ... and this share of the predicted flow (a distance error of half the distance driven)
    global_scale_max: float = 0.5
    #: cells this close to the image's border (px at the working width, in the newest frame or where the
    #: motion takes them in the older) are not used: the flow's 8 px patches reach out of the image there
    #: (one whole patch, 8 px, was measured to locate a moving body in fewer cycles and to report it later:
    #: docs/estimator_evidence.md, stage 2)
    border_px: int = 6
    #: two neighbouring columns are two surfaces when their laser depths differ by more than this ...
    snap_jump_m: float = 0.20
    #: ... or by this share of the nearer one
    snap_jump_rel: float = 0.05

    #: keys removed (issue 29: fewer tuned parameters), with what replaced each: a config file that sets one
    #: is refused naming the key and this reason (``app.config``), never silently misread
    REMOVED_KEYS: ClassVar[dict[str, str]] = {
        "max_width_px": "a numerical constant now, vipsm.flow.WORK_WIDTH_PX (320)",
        "dis_preset": "a numerical constant now, vipsm.flow.DIS_PRESET (ultrafast)",
        "grid_step_px": "a numerical constant now, vipsm.flow.GRID_STEP_PX (4)",
        "open_px": "a numerical constant now, vipsm.flow.MORPH_CELLS (3 grid cells, what 6 px gave)",
        "close_px": "a numerical constant now, vipsm.flow.MORPH_CELLS (3 grid cells, what 10 px gave)",
        "fb_check": "the forward-backward check (off by default) was deleted: the nearest-depth prediction made it "
                    "unnecessary",
        "fb_tol_px": "the forward-backward check (off by default) was deleted",
        "fb_tol_rel": "the forward-backward check (off by default) was deleted",
        "fit_global": "the global fit is always on (the switch of a kept model, not a tuned value)",
        "trim_trailing": "the trailing trim is always on (the switch of a kept model, not a tuned value)",
        "snap_to_depth": "snapping to depth edges is always on (the switch of a kept model, not a tuned value)",
        "snap_blob_share": "replaced by a majority: a blob lying mostly (more than half) on one foreground run is "
                           "about that body",
        "max_depth_m": "a column with no laser surface is seen as at infinity (its flow is the rotation's only)",
        "min_flow_valid_depth_m": "deleted: every depth in front of the camera is predicted",
    }


@dataclass(frozen=True)
class CameraMount:
    """Camera position on the robot (robot frame, m)."""

    x_m: float = 0.0
    y_m: float = 0.0
    z_m: float = 1.0


@dataclass(frozen=True)
class FlowResult:
    intervals: tuple[BearingInterval, ...]  # in the robot frame at the frame's stamp, origin = camera
    alpha_px: float
    moving_cells: int
    blobs: tuple[tuple[int, int, int, int], ...]  # (u0, u1, v0, v1) pixels, inclusive-exclusive


def pose_at(odo: Odometry, t_s: float) -> Pose2D:
    """The odometry pose extrapolated to ``t_s`` with its own velocities (short spans only)."""
    dt = t_s - odo.stamp_s
    th = odo.theta_rad + odo.w_radps * dt * 0.5
    ds = odo.v_mps * dt
    return Pose2D(odo.x_m + ds * math.cos(th), odo.y_m + ds * math.sin(th), odo.theta_rad + odo.w_radps * dt)


def _grey(frame: Frame, max_width: int) -> tuple[np.ndarray, float]:
    img = frame.image
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    scale = 1.0
    if img.shape[1] > max_width:
        scale = max_width / img.shape[1]
        img = cv2.resize(img, (max_width, int(round(img.shape[0] * scale))), interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(img), scale


def _rays(us, vs, fx, fy, cx, cy, pan, tilt, dist=(0.0, 0.0, 0.0, 0.0)):
    """Unit-free ray directions (robot frame, z up) through pixels (u, v), undistorted first."""
    xn, yn = undistort((us - cx) / fx, (vs - cy) / fy, *dist)
    a = -xn  # left component
    b = -yn  # up component
    ct, st = math.cos(tilt), math.sin(tilt)
    fwd_x = ct - st * b
    up_z = st + ct * b
    cp, sp = math.cos(pan), math.sin(pan)
    rx = cp * fwd_x - sp * a
    ry = sp * fwd_x + cp * a
    return rx, ry, up_z


def _project(px, py, pz, fx, fy, cx, cy, pan, tilt, dist=(0.0, 0.0, 0.0, 0.0)):
    """Pixels (with lens distortion) of camera-relative points (robot frame axes) for a camera with pan/tilt."""
    cp, sp = math.cos(pan), math.sin(pan)
    xf = cp * px + sp * py  # forward (horizontal) after undoing pan
    yl = -sp * px + cp * py
    ct, st = math.cos(tilt), math.sin(tilt)
    f = ct * xf + st * pz
    up = -st * xf + ct * pz
    with np.errstate(divide="ignore", invalid="ignore"):
        xd, yd = distort(-yl / f, -up / f, *dist)
    return cx + fx * xd, cy + fy * yd, f


def _snap_to_depth(u0: float, u1: float, col_depth: np.ndarray, st: int, cfg: FlowConfig) -> tuple[float, float]:
    """Snap a blob's column span to the laser's depth edges: the columns are split where the laser
    depth jumps, and the foreground runs (nearer than both neighbours) that the blob covers for at
    least half their width, or that lie wholly in the image and hold most (more than half) of the blob,
    replace the span. Without such a run the span is kept. A blob lying mostly on one foreground run is
    about that body, however little of it moved clearly enough (the rest spilled onto the background at
    the edge it covers or uncovers): a slow body's leading side flows most (translation and looming
    add), its trailing side least (the paper's 0.15 m/s cylinder at 45 deg: a third of it at first).
    ``col_depth`` is inf where no laser surface lies."""
    d = col_depth
    n = d.size
    if n < 2:
        return u0, u1
    with np.errstate(invalid="ignore"):  # inf - inf: one far background, no edge
        jump = np.abs(np.diff(d)) > np.maximum(cfg.snap_jump_m, cfg.snap_jump_rel * np.minimum(d[1:], d[:-1]))
    starts = np.concatenate(([0], np.flatnonzero(jump) + 1))
    stops = np.concatenate((starts[1:], [n]))
    near = np.add.reduceat(d, starts) / (stops - starts)  # mean depth of each run
    left = np.concatenate(([np.inf], d[starts[1:] - 1]))
    right = np.concatenate((d[stops[:-1]], [np.inf]))
    fg = (left > near + cfg.snap_jump_m) & (right > near + cfg.snap_jump_m)
    c0, c1 = u0 / st, u1 / st
    overlap = np.minimum(stops, c1) - np.maximum(starts, c0)
    # a run reaching the image's edge may go on beyond it: what a blob lying on it is about is not known
    whole = (starts > 0) & (stops < n)
    hit = fg & ((overlap >= 0.5 * (stops - starts)) | (whole & (overlap > 0.5 * (c1 - c0))))
    if not hit.any():
        return u0, u1
    return float(starts[hit].min() * st), float(stops[hit].max() * st)


def _remove_global_error(
    ru: np.ndarray, rv: np.ndarray, pu: np.ndarray, pv: np.ndarray, usable: np.ndarray, cfg: FlowConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Odometry errors show up in the residual flow as a near-uniform shift (a heading error) plus a
    share of the predicted flow (a distance error). Fit residual = (a, b) + s * predicted robustly
    over the usable pixels and remove it. Two starts: all pixels (moving bodies a minority, trimmed
    away), and the pixels the uncorrected prediction already explains best (a body near the camera
    fills half the image: the fit over all pixels took its motion for the robot's, and the whole
    background then "moved"); the model leaving the most pixels below
    ``alpha_base_px`` wins, no correction at all included."""
    idx = np.flatnonzero(usable.ravel())
    if idx.size < 50:
        return ru, rv
    if idx.size > 1500:  # a deterministic subsample is plenty for three parameters
        idx = idx[:: int(math.ceil(idx.size / 1500))]
    r = np.stack([ru.ravel()[idx], rv.ravel()[idx]])
    p = np.stack([pu.ravel()[idx], pv.ravel()[idx]])
    a, b, sc = _best_global(r, p, _lower_quartile(np.hypot(r[0], r[1])), float(cfg.alpha_base_px),
                            float(cfg.global_shift_max_px), float(cfg.global_scale_max))
    return ru - a - sc * pu, rv - b - sc * pv


def _lower_quartile(x: np.ndarray) -> float:
    """``np.percentile(x, 25)`` (linear interpolation), from a partial sort instead of a full one."""
    pos = 0.25 * (x.size - 1)
    lo = int(math.floor(pos))
    hi = min(lo + 1, x.size - 1)
    part = np.partition(x, [lo, hi])
    a, b, t = float(part[lo]), float(part[hi]), pos - lo
    return b - (b - a) * (1.0 - t) if t >= 0.5 else a + (b - a) * t


def warm_up(config: FlowConfig | None = None) -> None:
    """Load the compiled fit of the odometry's image shift and scale (see :func:`vipsm.estimator.warm_up`)
    on a made-up residual field."""
    v_px, u_px = np.mgrid[0:12, 0:12].astype(np.float64)
    _remove_global_error(0.1 * u_px, 0.1 * v_px, u_px - 6.0, v_px - 6.0, np.ones(u_px.shape, bool),
                         config or FlowConfig())


@njit(cache=True, nogil=True)
def _best_global(r, p, q25, alpha_px, shift_max_px, scale_max):  # pragma: no cover - compiled
    """The model (a, b, s) of :func:`_remove_global_error` leaving the most of the samples ``r`` (2, n)
    below ``alpha_px``: no correction, or :func:`_fit_global` from all samples or from those the
    uncorrected prediction explains best (within 2x the lower quartile ``q25`` of their error)."""
    e0 = np.hypot(r[0], r[1])
    best_a, best_b, best_s = 0.0, 0.0, 0.0
    best_n = np.count_nonzero(e0 < alpha_px)
    for start in range(2):
        keep = np.ones(e0.size, np.bool_) if start == 0 else e0 <= max(2.0 * q25, alpha_px)
        ok, a, b, sc = _fit_global(r, p, keep, shift_max_px, scale_max)
        if ok:
            n = np.count_nonzero(np.hypot(r[0] - a - sc * p[0], r[1] - b - sc * p[1]) < alpha_px)
            if n > best_n:
                best_a, best_b, best_s, best_n = a, b, sc, n
    return best_a, best_b, best_s


@njit(cache=True, nogil=True)
def _fit_global(r, p, keep, shift_max_px, scale_max):  # pragma: no cover - compiled
    """Least squares of residual (2, n) = (a, b) + s * predicted (2, n) over ``keep``, twice, keeping
    for the second the samples within 3x the median error of the first's; clamped to the configured
    bounds. (False, ...): too few samples."""
    ok, a, b, sc = False, 0.0, 0.0, 0.0
    for _ in range(2):
        k = np.flatnonzero(keep)
        if k.size < 30:
            break
        # normal equations of [1 0 pu; 0 1 pv] [a b s]' = [ru; rv]
        n = float(k.size)
        spu = spv = spp = sru = srv = srp = 0.0
        for i in k:
            pu, pv, ru, rv = p[0, i], p[1, i], r[0, i], r[1, i]
            spu += pu
            spv += pv
            spp += pu * pu + pv * pv
            sru += ru
            srv += rv
            srp += pu * ru + pv * rv
        # the system [[n, 0, spu], [0, n, spv], [spu, spv, spp]] (+1e-6 I) solved by eliminating a and b
        d = n + 1e-6
        den = d * (spp + 1e-6) - spu * spu - spv * spv
        if den == 0.0 or not math.isfinite(den):
            break
        sc_ = (d * srp - spu * sru - spv * srv) / den
        a_, b_ = (sru - spu * sc_) / d, (srv - spv * sc_) / d
        ok = True
        a, b = min(max(a_, -shift_max_px), shift_max_px), min(max(b_, -shift_max_px), shift_max_px)
        sc = min(max(sc_, -scale_max), scale_max)
        e = np.hypot(r[0] - a - sc * p[0], r[1] - b - sc * p[1])
        keep = e < max(3.0 * np.median(e[k]), 0.3)
    return ok, a, b, sc


class FlowDetector:
    """Keeps recent frames; :meth:`detect` returns the moving-body bearing intervals of the newest.

    Flow is computed *backwards*, from the newest frame to the oldest kept frame at most
    ``baseline_s`` earlier (a longer baseline makes a slow body's residual flow stand out from the
    flow noise), so the pixel grid, the blobs and the bearings belong to the newest frame."""

    def __init__(self, config: FlowConfig | None = None, mount: CameraMount | None = None) -> None:
        self.config = config or FlowConfig()
        self.mount = mount or CameraMount()
        self._dis = cv2.DISOpticalFlow_create(DIS_PRESET)
        self._border_px = self.config.border_px
        self._history: list[tuple[np.ndarray, float, Frame, Pose2D]] = []
        self._last_result: FlowResult | None = None
        self._geo: _Geometry | None = None
        #: (residual flow px, threshold px, usable mask, grid step) of the last detection, for diagnostics
        self.last_residual: tuple[np.ndarray, np.ndarray, np.ndarray, int] | None = None

    def reset(self) -> None:
        self._history = []
        self._last_result = None

    def _pick_old(self, stamp_s: float, shape: tuple[int, ...]) -> tuple[np.ndarray, float, Frame, Pose2D] | None:
        cfg = self.config
        best = None
        for item in self._history:
            dt = stamp_s - item[2].stamp_s
            if item[0].shape != shape or not (0.0 < dt <= cfg.max_frame_gap_s):
                continue
            if dt <= cfg.baseline_s + 1e-6 and (best is None or item[2].stamp_s < best[2].stamp_s):
                best = item
        if best is None:  # nothing inside the baseline: the newest older frame within the gap
            older = [
                it
                for it in self._history
                if it[0].shape == shape and 0.0 < stamp_s - it[2].stamp_s <= cfg.max_frame_gap_s
            ]
            if older:
                best = max(older, key=lambda it: it[2].stamp_s)
        return best

    def detect(
        self,
        frame: Frame,
        odom_pose_at_frame: Pose2D,
        depth_points_robot: np.ndarray | None,
        speed_mps: float,
        turn_radps: float,
    ) -> FlowResult | None:
        """``depth_points_robot``: (k, 2) laser points in the robot frame *at this frame's stamp*
        (the scan nearest to the frame), giving the depth per viewing direction. Returns None when
        there is no usable earlier frame yet."""
        cfg = self.config
        if self._history and self._history[-1][2].stamp_s == frame.stamp_s:
            # the same frame again (a camera slower than the estimator's cycle): same answer
            return self._last_result
        grey, scale = _grey(frame, WORK_WIDTH_PX)
        old = self._pick_old(frame.stamp_s, grey.shape)
        self._history.append((grey, scale, frame, odom_pose_at_frame))
        self._history = [it for it in self._history if frame.stamp_s - it[2].stamp_s <= cfg.max_frame_gap_s + 1e-9][-8:]
        self._last_result = None
        if old is None:
            return None
        ogrey, oscale, oframe, opose = old
        geo = self._geometry(frame, grey.shape, scale)
        depth = _cell_depths(geo, depth_points_robot, self.mount)
        rel = between(opose, odom_pose_at_frame)  # newest robot pose in the older robot frame
        pred_u, pred_v, valid = _ego_flow(geo, depth, rel, oframe, oscale, self.mount)
        flow = self._dis.calc(grey, ogrey, None)  # newest -> older
        fl = flow[0 : geo.h : geo.st, 0 : geo.w : geo.st].astype(np.float64)
        ru, rv = fl[..., 0] - pred_u, fl[..., 1] - pred_v
        usable = valid & _textured(grey, geo.st, cfg)
        ru, rv = _remove_global_error(ru, rv, pred_u, pred_v, usable, cfg)
        alpha = _alpha_px(cfg, speed_mps, turn_radps, frame.stamp_s - oframe.stamp_s)
        res = np.hypot(ru, rv)
        thr = alpha + cfg.alpha_rel * np.hypot(pred_u, pred_v)
        moving = usable & (res > thr)
        self.last_residual = (res, thr, usable, geo.st)
        mask = _clean_mask(moving)
        spans = _merge_spans(_blob_spans(mask, moving, usable, ru, geo.st, cfg))
        if depth_points_robot is not None and depth_points_robot.shape[0] >= 2:
            col_depth = depth[depth.shape[0] // 2]  # laser depth per grid column (horizon row)
            for sp in spans:
                sp[0], sp[1] = _snap_to_depth(sp[0], sp[1], col_depth, geo.st, cfg)
        intervals = tuple(_bearing_interval(sp, geo, frame, self.mount) for sp in spans)
        self._last_result = FlowResult(
            intervals,
            float(alpha),
            int(np.count_nonzero(mask)),
            tuple((int(a), int(b_), int(c_), int(d)) for a, b_, c_, d in spans),
        )
        return self._last_result

    def _geometry(self, frame: Frame, shape: tuple[int, ...], scale: float) -> _Geometry:
        """The viewing ray of every grid cell of the newest frame (cached per camera state)."""
        m, k = self.mount, frame.intrinsics
        h, w = shape[:2]
        st = GRID_STEP_PX
        fx, fy, cx, cy = k.fx_px * scale, k.fy_px * scale, k.cx_px * scale, k.cy_px * scale
        key = (h, w, st, fx, fy, cx, cy, k.distortion, frame.pan_rad, frame.tilt_rad, m.z_m)
        if self._geo is None or self._geo.key != key:
            vs, us = np.mgrid[0:h:st, 0:w:st]
            us = us.astype(np.float64) + 0.5 * (st - 1)
            vs = vs.astype(np.float64) + 0.5 * (st - 1)
            rx, ry, rz = _rays(us, vs, fx, fy, cx, cy, frame.pan_rad, frame.tilt_rad, k.distortion)
            hn = np.hypot(rx, ry)
            slope = rz / np.maximum(hn, 1e-9)
            floor_d = np.where(slope < -1e-6, m.z_m / np.maximum(-slope, 1e-9), np.inf)
            bd = self._border_px
            inside = (us >= bd) & (us < w - bd) & (vs >= bd) & (vs < h - bd)
            self._geo = _Geometry(key, h, w, st, (fx, fy, cx, cy), us, vs, rx, ry, rz, hn, np.arctan2(ry, rx),
                                  floor_d, inside, bd)
        return self._geo


@dataclass(frozen=True, eq=False)
class _Geometry:
    """Per grid cell of the newest frame: pixel centre (us, vs), viewing ray (rx, ry, rz; hn its
    horizontal length, az its azimuth), distance to the floor along it, inside the border (``border_px``
    from each edge)."""

    key: tuple
    h: int
    w: int
    st: int
    intrinsics_px: tuple[float, float, float, float]  # fx, fy, cx, cy at the working scale
    us: np.ndarray
    vs: np.ndarray
    rx: np.ndarray
    ry: np.ndarray
    rz: np.ndarray
    hn: np.ndarray
    az: np.ndarray
    floor_d: np.ndarray
    inside: np.ndarray
    border_px: int


def _cell_depths(geo: _Geometry, depth_points_robot: np.ndarray | None, m: CameraMount) -> np.ndarray:
    """Horizontal distance to the laser's surface in each cell's viewing direction; inf outside the
    laser's points (no surface seen: far background, see :func:`_ego_flow`)."""
    depth = np.full(geo.az.shape, np.inf)
    if depth_points_robot is None or depth_points_robot.shape[0] < 2:
        return depth
    dx = depth_points_robot[:, 0] - m.x_m
    dy = depth_points_robot[:, 1] - m.y_m
    pb = np.arctan2(dy, dx)
    pd = np.hypot(dx, dy)
    order = np.argsort(pb)
    pb, pd = pb[order], pd[order]
    az = geo.az
    # the nearest laser point's depth, not an interpolation: across a depth edge (a body in front
    # of a wall) interpolated depths belong to neither surface and fake residual flow
    jj = np.clip(np.searchsorted(pb, az), 1, pb.size - 1)
    jj -= (np.abs(pb[jj - 1] - az) < np.abs(pb[jj] - az)).astype(np.intp)
    return np.where((az < pb[0] - 0.01) | (az > pb[-1] + 0.01), np.inf, pd[jj])


def _ego_flow(geo: _Geometry, depth: np.ndarray, rel: Pose2D, oframe: Frame, oscale: float, m: CameraMount
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The flow (newest -> older, px) a static scene would show in each cell, and where it is valid:
    each cell's 3-D point (laser depth or floor) moved by the robot's motion ``rel`` (newest pose in
    the older robot frame) and projected into the older frame. A cell with neither (no laser surface in
    its direction, above the horizon) looks at a point at infinity: its direction only turns with the
    robot, the translation moves it by nothing."""
    dist_h = np.minimum(depth, geo.floor_d)
    far = ~np.isfinite(dist_h)
    valid = dist_h > 0.0
    t = np.where(far, 1.0, dist_h / np.maximum(geo.hn, 1e-9))  # the far cells: the ray's direction
    c, s = math.cos(rel.theta_rad), math.sin(rel.theta_rad)
    # the point (camera + ray * t) moved by ``rel``, relative to the older camera; no translation at infinity
    shift_x = np.where(far, 0.0, rel.x_m + c * m.x_m - s * m.y_m - m.x_m)
    shift_y = np.where(far, 0.0, rel.y_m + s * m.x_m + c * m.y_m - m.y_m)
    qx = shift_x + (c * geo.rx - s * geo.ry) * t
    qy = shift_y + (s * geo.rx + c * geo.ry) * t
    pz = geo.rz * t
    ko = oframe.intrinsics
    ofx, ofy, ocx, ocy = ko.fx_px * oscale, ko.fy_px * oscale, ko.cx_px * oscale, ko.cy_px * oscale
    u2, v2, f2 = _project(qx, qy, pz, ofx, ofy, ocx, ocy, oframe.pan_rad, oframe.tilt_rad, ko.distortion)
    valid &= f2 > 1e-3
    bd = geo.border_px
    with np.errstate(invalid="ignore"):
        valid &= (u2 >= bd) & (u2 < geo.w - bd) & (v2 >= bd) & (v2 < geo.h - bd)
    valid &= geo.inside
    return np.where(valid, u2 - geo.us, 0.0), np.where(valid, v2 - geo.vs, 0.0), valid


def _alpha_px(cfg: FlowConfig, speed_mps: float, turn_radps: float, dt_s: float) -> float:
    """The paper's threshold (eq. 1): grows with the distance driven and the angle turned."""
    alpha = (
        cfg.alpha_base_px
        + cfg.alpha_v_px_per_m * abs(speed_mps) * dt_s
        + cfg.alpha_w_px_per_rad * abs(turn_radps) * dt_s
    )
    return min(alpha, cfg.alpha_max_px)


def _textured(grey: np.ndarray, st: int, cfg: FlowConfig) -> np.ndarray:
    """Cells with enough image gradient nearby for their flow to mean something."""
    gx = cv2.Sobel(grey, cv2.CV_16S, 1, 0, ksize=3)
    gy = cv2.Sobel(grey, cv2.CV_16S, 0, 1, ksize=3)
    mag = cv2.add(cv2.convertScaleAbs(gx, alpha=0.25), cv2.convertScaleAbs(gy, alpha=0.25))  # ~ |grad| (L1)
    h, w = grey.shape
    return cv2.dilate(mag, np.ones((3, 3), np.uint8))[0:h:st, 0:w:st] > cfg.min_texture


def _clean_mask(moving: np.ndarray) -> np.ndarray:
    """The moving cells opened (specks gone) and closed (one body's fragments joined), ``MORPH_CELLS``."""
    kernel = np.ones((MORPH_CELLS, MORPH_CELLS), np.uint8)
    mask = cv2.morphologyEx(moving.astype(np.uint8), cv2.MORPH_OPEN, kernel)
    return cv2.morphologyEx(mask, cv2.MORPH_CLOSE, kernel)


def _blob_spans(mask: np.ndarray, moving: np.ndarray, usable: np.ndarray, ru: np.ndarray, st: int,
                cfg: FlowConfig) -> list[list[float]]:
    """(u0, u1, v0, v1) pixels of each blob large enough: its columns where the moving cells are a
    real share of the usable ones (sparse fringes, e.g. from the closing, do not count), trimmed of
    the background uncovered on its trailing side."""
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    spans: list[list[float]] = []
    for i in range(1, n):
        x0, y0, ww, hh, area = (int(v) for v in stats[i])
        if area * st * st < cfg.min_blob_px:
            continue
        rows = slice(y0, y0 + hh)
        mcol = np.count_nonzero(moving[rows, x0 : x0 + ww], axis=0)
        ucol = np.count_nonzero(usable[rows, x0 : x0 + ww], axis=0)
        dense = np.flatnonzero(mcol >= cfg.column_share * np.maximum(ucol, 1))
        if dense.size == 0:
            continue
        u0, u1 = float((x0 + int(dense[0])) * st), float((x0 + int(dense[-1]) + 1) * st)
        u0, u1 = _trim_trailing(u0, u1, ru[(labels == i) & moving], st)
        spans.append([u0, u1, y0 * st, (y0 + hh) * st])
    return spans


def _trim_trailing(u0: float, u1: float, ru_blob: np.ndarray, st: int) -> tuple[float, float]:
    """The blob holds the body and the background it uncovered since the older frame, on the side
    its residual flow (newest -> older) points to: trim that side by the body's displacement."""
    if ru_blob.size < 3:
        return u0, u1
    du = float(np.median(ru_blob))
    if u1 - u0 - abs(du) < 2 * st:
        return u0, u1
    return (u0, u1 - du) if du > 0 else (u0 - du, u1)


def _merge_spans(spans: list[list[float]]) -> list[list[float]]:
    """Overlapping column spans joined (their row extents too), left to right."""
    merged: list[list[float]] = []
    for sp in sorted(spans):
        if merged and sp[0] <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], sp[1])
            merged[-1][2] = min(merged[-1][2], sp[2])
            merged[-1][3] = max(merged[-1][3], sp[3])
        else:
            merged.append(list(sp))
    return merged


def _bearing_interval(span: list[float], geo: _Geometry, frame: Frame, m: CameraMount) -> BearingInterval:
    """A span's edge columns as bearings in the robot frame (origin: the camera)."""
    u0, u1, v0, v1 = span
    vc = 0.5 * (v0 + v1)
    fx, fy, cx, cy = geo.intrinsics_px
    rxa, rya, _ = _rays(np.array([u0 - 0.5, u1 - 0.5]), np.array([vc, vc]), fx, fy, cx, cy, frame.pan_rad,
                        frame.tilt_rad, frame.intrinsics.distortion)
    b = np.arctan2(rya, rxa)
    return BearingInterval(float(b.min()), float(b.max()), m.x_m, m.y_m, "camera")

def interval_to_laser(iv: BearingInterval, robot_rel_frame_to_scan: Pose2D, laser_mount: Pose2D) -> BearingInterval:
    """Re-express a robot-frame interval seen at the frame's stamp (origin = camera) in the laser
    frame at the scan's stamp. ``robot_rel_frame_to_scan`` is the robot pose at the scan's stamp in
    the robot frame at the frame's stamp (from odometry)."""
    inv = inverse(robot_rel_frame_to_scan)
    ox, oy = transform_point(inv, iv.origin_x_m, iv.origin_y_m)  # camera (at frame time) in the scan-time robot frame
    lo = iv.bearing_min_rad - robot_rel_frame_to_scan.theta_rad
    hi = iv.bearing_max_rad - robot_rel_frame_to_scan.theta_rad
    lm_inv = inverse(laser_mount)
    lx, ly = transform_point(lm_inv, ox, oy)
    return BearingInterval(lo - laser_mount.theta_rad, hi - laser_mount.theta_rad, lx, ly, iv.source, iv.track_id)


__all__ = ["FlowConfig", "CameraMount", "FlowDetector", "FlowResult", "pose_at", "interval_to_laser"]
