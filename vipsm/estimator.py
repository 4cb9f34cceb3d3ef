"""The VIPSM estimator: one object with explicit state, ``step(scan, odometry, frame) -> Estimate``.

Per cycle (the paper's Fig. 5 flow, with the product's additions):

1. Visual obstacle directions: optical flow between this frame and the previous one, ego-motion
   removed (:mod:`vipsm.flow`), blobs turned into bearing intervals in the laser frame at the scan's
   stamp. Tracks confirmed by the camera recently also contribute their predicted interval (so a body
   leaving the camera's view, or a missed frame, keeps being masked for ``track_mask_s``).
2. Restoration (:mod:`vipsm.restore`): segments in those directions are cut and bridged, with
   weight 0 for both matching steps. ``plain_psm=True`` (the baseline) matches the raw scan instead;
   the camera-selected segments are still used to locate obstacles.
3. PSM (:mod:`vipsm.psm`) of the current scan against the reference keyframe, seeded by odometry.
   Refused matches fall back to odometry (flag ``ODOMETRY_FALLBACK``).
4. Laser motion cue (beyond the paper): body-sized foreground segments standing clearly in front of
   what the keyframe (or the one before) saw are obstacles too, which catches bodies whose image
   motion is too small for the camera (e.g. coming head-on); they are masked from the next cycle on.
5. Obstacles: the cut points placed with the matched pose, the body centre corrected for seeing
   only its front (:mod:`vipsm.tracker`), a constant-velocity Kalman tracker for velocity and ids.

Reference-scan policy (keyframes): the current scan is matched against a keyframe, not against the
previous scan, so small per-match errors do not accumulate every cycle. The keyframe is replaced by
the current (restored) scan when the robot has moved more than ``keyframe_dist_m`` or turned more
than ``keyframe_angle_rad`` from it, when the match used fewer than ``keyframe_min_overlap`` of the
beams the keyframe offers, or after a refused match once the keyframe is ``keyframe_stale_dist_m``
behind. A keyframe is never taken from a scan whose restoration was refused (obstacle too large).

Frames: ``Estimate.pose`` is the robot pose in the odometry frame (the first estimate equals the
first odometry pose); obstacle positions/velocities are in that frame too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from .flow import CameraMount, FlowConfig, FlowDetector, interval_to_laser, pose_at
from .geometry import between, compose, inverse, wrap_angle
from .psm import PreparedScan, PsmConfig, PsmResult, match_prepared, prepare_scan
from .restore import (
    BearingInterval,
    ObstacleSegment,
    Restoration,
    RestoreConfig,
    _compact_foreground,
    _segments_raw,
    restore,
)
from .tracker import Detection, Tracker, TrackerConfig, locate_body
from .types import Estimate, EstimateFlag, Frame, MatchQuality, Obstacle, Odometry, Pose2D, Scan


def _estimator_psm() -> PsmConfig:
    # Odometry-seeded scan-to-keyframe matching at 10 Hz: a +-7.5 deg first orientation search and
    # +-2.5 deg later ones are ample (the keyframe is at most ~10 deg away and the odometry's heading
    # error is far smaller) and cut the cost; two small steps in a row end the iterations.
    return PsmConfig(search_window_first_beams=30, search_window_beams=10, stop_count=2)


@dataclass(frozen=True)
class EstimatorConfig:
    # Mount poses on the robot (robot frame: x forward, y left, z up).
    laser_x_m: float = 0.0
    laser_y_m: float = 0.0
    laser_theta_rad: float = 0.0
    camera_x_m: float = 0.0
    camera_y_m: float = 0.0
    camera_z_m: float = 1.0
    psm: PsmConfig = field(default_factory=_estimator_psm)
    restore: RestoreConfig = field(default_factory=RestoreConfig)
    flow: FlowConfig = field(default_factory=FlowConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    keyframe_dist_m: float = 0.30
    keyframe_angle_rad: float = math.radians(10.0)
    keyframe_min_overlap: float = 0.60
    keyframe_stale_dist_m: float = 0.60
    max_frame_age_s: float = 0.25  # a frame further than this from the scan's stamp is not used
    track_mask_s: float = 1.0  # tracks confirmed by the camera within this long are masked too
    track_sustain_speed_mps: float = 0.05  # ... and moving tracks the laser keeps detecting, indefinitely
    track_mask_margin_m: float = 0.15  # added to a track's radius for its predicted interval
    laser_motion_cue: bool = True  # also detect bodies that moved in front of the keyframe's surfaces
    laser_motion_min_m: float = 0.05  # ... by at least this much
    laser_motion_min_share: float = 0.6  # ... over this share of a body-sized foreground segment
    max_correction_m: float = 0.5  # a match further than this from the odometry prediction is refused
    max_correction_rad: float = math.radians(20.0)
    weak_info: float = 0.08  # normalised translation information below which odometry is blended in
    weak_info_min: float = 0.03  # ... and below which the odometry's translation is kept entirely
    odom_sigma_per_m: float = 0.05  # covariance growth on odometry fallback
    odom_sigma_rad_per_rad: float = 0.05

    @property
    def laser_mount(self) -> Pose2D:
        return Pose2D(self.laser_x_m, self.laser_y_m, self.laser_theta_rad)

    @property
    def camera_mount(self) -> CameraMount:
        return CameraMount(self.camera_x_m, self.camera_y_m, self.camera_z_m)


@dataclass
class _Keyframe:
    prep: PreparedScan
    pose: Pose2D  # robot pose (world)
    cov: np.ndarray
    n_good_weighted: int


@dataclass(frozen=True)
class StepDebug:
    """What the last step saw (for plots and diagnostics; not part of the Estimate contract)."""

    intervals: tuple[BearingInterval, ...]
    restoration: Restoration | None
    match: PsmResult | None
    keyframe_replaced: bool
    obstacle_points_world: tuple[np.ndarray, ...]


class Estimator:
    """VIPSM (``plain_psm=False``) or the plain-PSM baseline (``plain_psm=True``) on the same code."""

    def __init__(self, config: EstimatorConfig | None = None, plain_psm: bool = False) -> None:
        self.config = config or EstimatorConfig()
        self.plain_psm = plain_psm
        self._flow = FlowDetector(self.config.flow, self.config.camera_mount)
        self._tracker = Tracker(self.config.tracker)
        self._kf: _Keyframe | None = None
        self._older_kf: _Keyframe | None = None  # the keyframe before the current one
        self._last_pose: Pose2D | None = None
        self._last_odo: Pose2D | None = None
        self._last_cov = np.zeros((3, 3))
        self.last_debug: StepDebug | None = None

    # ------------------------------------------------------------------ helpers
    def _laser_to_robot_points(self, ranges: np.ndarray, bearings: np.ndarray) -> np.ndarray:
        ok = np.isfinite(ranges) & (ranges >= self.config.psm.min_range_m)
        r, b = ranges[ok], bearings[ok]
        m = self.config.laser_mount
        xl, yl = r * np.cos(b), r * np.sin(b)
        c, s = math.cos(m.theta_rad), math.sin(m.theta_rad)
        return np.stack([m.x_m + c * xl - s * yl, m.y_m + s * xl + c * yl], axis=1)

    def _track_intervals(
        self, stamp_s: float, predicted: Pose2D, camera: list[BearingInterval]
    ) -> list[BearingInterval]:
        out = []
        laser_world = compose(predicted, self.config.laser_mount)
        for t in self._tracker.tracks:
            speed = math.hypot(float(t.state[2]), float(t.state[3]))
            recent_camera = stamp_s - t.camera_stamp_s <= self.config.track_mask_s
            # a body the camera confirmed once and the laser keeps following while it moves stays
            # masked after it leaves the camera's view (a track latched on a wall stops "moving")
            sustained = (
                t.camera_stamp_s > -math.inf
                and t.radius_known
                and t.hits >= 5
                and t.missed <= 1
                and speed >= self.config.track_sustain_speed_mps
            )
            if not (recent_camera or sustained):
                continue
            wx, wy = self._tracker.predict_position(t, stamp_s)
            rel = between(laser_world, Pose2D(wx, wy, 0.0))
            d = math.hypot(rel.x_m, rel.y_m)
            half_w = t.radius_m + self.config.track_mask_margin_m
            if d <= half_w:
                continue
            b = math.atan2(rel.y_m, rel.x_m)
            half = math.asin(min(half_w / d, 1.0))
            out.append(BearingInterval(b - half, b + half, 0.0, 0.0, "track", t.track_id))
        return out

    def _constrain_weak_directions(self, res: PsmResult, guess: Pose2D) -> Pose2D:
        """Keep the odometry's translation along directions the scene does not constrain (e.g. along
        a corridor, or when the masked obstacle hides the only cross wall): there PSM's range
        residuals creep instead of measuring, so its correction is dropped."""
        info = res.info_xy
        if not res.converged:
            # still creeping after max_iterations: PSM's slow divergence where the scene barely
            # constrains the translation; keep the odometry's translation, take the rotation
            return Pose2D(guess.x_m, guess.y_m, res.dtheta_rad)
        if info is None:
            return res.pose
        lam, vec = np.linalg.eigh(info)
        dx, dy = res.dx_m - guess.x_m, res.dy_m - guess.y_m
        lo, hi = self.config.weak_info_min, self.config.weak_info
        for k in range(2):
            if lam[k] < hi:
                # below weak_info_min the scan's correction along v is dropped; up to weak_info it is
                # blended in linearly
                keep = min(max((lam[k] - lo) / max(hi - lo, 1e-9), 0.0), 1.0)
                v = vec[:, k]
                along = dx * v[0] + dy * v[1]
                dx -= (1.0 - keep) * along * v[0]
                dy -= (1.0 - keep) * along * v[1]
        return Pose2D(guess.x_m + dx, guess.y_m + dy, res.dtheta_rad)

    def _laser_motion_segments(self, scan: Scan, kf: PreparedScan, rel_laser: Pose2D) -> list[tuple[int, int]]:
        """Body-sized foreground segments of this scan that stand clearly in front of the surface
        the keyframe saw in the same direction (after matching): something moved into view there.
        A static scene cannot produce this (a new viewpoint only reveals surfaces *behind* what the
        keyframe saw), so it catches bodies the camera misses, e.g. one approaching head-on."""
        cfg = self.config
        r = scan.ranges_m
        b = scan.bearings_rad
        n = r.size
        if n < 3 or kf.ranges_m.size < 3:
            return []
        valid = np.isfinite(r) & (r >= cfg.psm.min_range_m) & (r <= cfg.psm.max_range_m)
        c, s = math.cos(rel_laser.theta_rad), math.sin(rel_laser.theta_rad)
        rr = np.where(valid, r, 0.0)
        x = rel_laser.x_m + c * rr * np.cos(b) - s * rr * np.sin(b)
        y = rel_laser.y_m + s * rr * np.cos(b) + c * rr * np.sin(b)
        phi = np.arctan2(y, x)
        rho = np.hypot(x, y)
        kb = kf.bearings_rad
        j = np.clip(np.searchsorted(kb, phi), 1, kb.size - 1)
        j -= (np.abs(kb[j - 1] - phi) < np.abs(kb[j] - phi)).astype(np.intp)
        inside = (phi >= kb[0]) & (phi <= kb[-1])
        kr = np.where(kf.good, kf.ranges_m, np.nan)[j]
        with np.errstate(invalid="ignore"):
            evidence = valid & inside & np.isfinite(kr) & (rho < kr - cfg.laser_motion_min_m)
        if np.count_nonzero(evidence) < cfg.restore.min_obstacle_beams:
            return []
        dphi = float(abs(b[-1] - b[0]) / max(n - 1, 1))
        seg = _segments_raw(r, valid, dphi, cfg.restore.seg_jump_m, cfg.restore.seg_jump_range_factor)
        out = []
        for sid in np.unique(seg[evidence]):
            if sid == 0:
                continue
            beams = np.flatnonzero(seg == sid)
            if np.count_nonzero(evidence[beams]) < cfg.laser_motion_min_share * beams.size:
                continue
            if not _compact_foreground(r, b, seg, int(sid), cfg.restore):
                continue
            out.append((int(beams[0]), int(beams[-1]) + 1))
        return out

    # ------------------------------------------------------------------ step
    def step(self, scan: Scan, odometry: Odometry, frame: Frame | None = None) -> Estimate:
        cfg = self.config
        flags = EstimateFlag.NONE
        if self.plain_psm:
            flags |= EstimateFlag.PLAIN_PSM
        odo = odometry.pose
        b = scan.bearings_rad
        scan_ok = bool(b.size < 2 or (np.all(np.isfinite(b)) and np.all(np.diff(b) > 0)))
        if not scan_ok:  # bearings must be finite and ascending: match nothing, fall back
            scan = Scan(np.full(b.size, np.nan), np.linspace(-1.0, 1.0, b.size), scan.stamp_s, scan.seq)
        first = self._last_pose is None
        if self._last_pose is None or self._last_odo is None:
            predicted = odo
        else:
            predicted = compose(self._last_pose, between(self._last_odo, odo))

        # 1. visual directions ------------------------------------------------------------
        camera_ivs: list[BearingInterval] = []
        if frame is None:
            flags |= EstimateFlag.NO_FRAME
        elif abs(frame.stamp_s - scan.stamp_s) > cfg.max_frame_age_s:
            flags |= EstimateFlag.STALE_FRAME
            self._flow.reset()
        else:
            pose_f = pose_at(odometry, frame.stamp_s)
            # depth for the frame's pixels: this scan, moved into the robot frame at the frame's stamp
            pts = self._laser_to_robot_points(scan.ranges_m, scan.bearings_rad)
            rel_sf = between(pose_f, pose_at(odometry, scan.stamp_s))
            cs, sn = math.cos(rel_sf.theta_rad), math.sin(rel_sf.theta_rad)
            depth_pts = np.stack(
                [rel_sf.x_m + cs * pts[:, 0] - sn * pts[:, 1], rel_sf.y_m + sn * pts[:, 0] + cs * pts[:, 1]], axis=1
            )
            try:
                fres = self._flow.detect(frame, pose_f, depth_pts, odometry.v_mps, odometry.w_radps)
            except (cv2.error, ValueError) as exc:  # e.g. an image of the wrong dtype or shape
                del exc
                fres = None
                flags |= EstimateFlag.FRAME_ERROR
                self._flow.reset()
            if fres is not None:
                camera_ivs = [interval_to_laser(iv, rel_sf, cfg.laser_mount) for iv in fres.intervals]
        intervals = camera_ivs + self._track_intervals(scan.stamp_s, predicted, camera_ivs)

        # 2. restoration ------------------------------------------------------------------
        rest = restore(scan.ranges_m, scan.bearings_rad, intervals, cfg.restore, cfg.psm.min_range_m)
        if rest.too_large:
            flags |= EstimateFlag.OBSTACLE_TOO_LARGE
        if rest.bridge_invalid and not self.plain_psm:
            flags |= EstimateFlag.BRIDGE_INVALID
        if self.plain_psm:
            cur = prepare_scan(scan.ranges_m, scan.bearings_rad, cfg.psm)
        else:
            cur = prepare_scan(rest.ranges_m, scan.bearings_rad, cfg.psm, rest.weights)
        n_good_w = int(np.count_nonzero(cur.good & (cur.weights > 0)))

        # 3. matching ---------------------------------------------------------------------
        res: PsmResult | None = None
        kf_replaced = False
        kf_used: _Keyframe | None = None
        if first or self._kf is None:
            if first:
                flags |= EstimateFlag.FIRST_SCAN
                pose = odo
                cov = np.zeros((3, 3))
            else:  # no usable keyframe yet (the earlier scans were unusable): dead-reckon
                flags |= EstimateFlag.ODOMETRY_FALLBACK
                pose = predicted
                cov = self._last_cov.copy()
            quality = MatchQuality(0, 0, float("nan"), False)
            if (not rest.too_large or self.plain_psm) and n_good_w >= cfg.psm.min_valid_beams:
                self._kf = _Keyframe(cur, pose, cov, n_good_w)
                kf_replaced = True
        else:
            kf = self._kf
            kf_used = kf
            refused = False
            if rest.too_large and not self.plain_psm:
                refused = True
            else:
                mount = cfg.laser_mount
                guess_robot = between(kf.pose, predicted)
                guess = compose(compose(inverse(mount), guess_robot), mount)
                if scan_ok:
                    res = match_prepared(kf.prep, cur, guess, cfg.psm)
                    refused = res.refused
                else:
                    refused = True
                if not refused:
                    matched = self._constrain_weak_directions(res, guess)
                    rel_robot = compose(compose(mount, matched), inverse(mount))
                    cand = compose(kf.pose, rel_robot)
                    corr = between(predicted, cand)
                    if (
                        math.hypot(corr.x_m, corr.y_m) > cfg.max_correction_m
                        or abs(corr.theta_rad) > cfg.max_correction_rad
                    ):
                        refused = True
            if refused:
                flags |= EstimateFlag.ODOMETRY_FALLBACK
                pose = predicted
                step_rel = between(self._last_pose, predicted) if self._last_pose else Pose2D(0, 0, 0)
                dist = math.hypot(step_rel.x_m, step_rel.y_m)
                g = np.diag(
                    [
                        (cfg.odom_sigma_per_m * dist) ** 2,
                        (cfg.odom_sigma_per_m * dist) ** 2,
                        (cfg.odom_sigma_rad_per_rad * abs(step_rel.theta_rad)) ** 2,
                    ]
                )
                cov = self._last_cov + g
                quality = MatchQuality(
                    res.beams_used if res else 0, res.iterations if res else 0, float("nan"), False
                )
                since_kf = between(kf.pose, pose)
                if math.hypot(since_kf.x_m, since_kf.y_m) > cfg.keyframe_stale_dist_m and not rest.too_large:
                    self._older_kf = self._kf
                    self._kf = _Keyframe(cur, pose, cov, n_good_w)
                    kf_replaced = True
            else:
                assert res is not None
                pose = cand
                th = kf.pose.theta_rad + cfg.laser_theta_rad
                c, s = math.cos(th), math.sin(th)
                rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
                cov = kf.cov + rot @ res.covariance @ rot.T
                quality = MatchQuality(res.beams_used, res.iterations, res.residual_m, res.converged)
                since_kf = between(kf.pose, pose)
                if (
                    math.hypot(since_kf.x_m, since_kf.y_m) > cfg.keyframe_dist_m
                    or abs(since_kf.theta_rad) > cfg.keyframe_angle_rad
                    or res.beams_used < cfg.keyframe_min_overlap * max(kf.n_good_weighted, 1)
                ):
                    self._older_kf = self._kf
                    self._kf = _Keyframe(cur, pose, cov, n_good_w)
                    kf_replaced = True

        # 4. obstacles --------------------------------------------------------------------
        segments = list(rest.obstacles)
        if cfg.laser_motion_cue and kf_used is not None and not (flags & EstimateFlag.ODOMETRY_FALLBACK):
            found: list[tuple[int, int]] = []
            # against the keyframe and the one before it (a longer time base shows slower motion)
            for ref_kf in (kf_used, self._older_kf):
                if ref_kf is None:
                    continue
                rel_laser = compose(compose(inverse(cfg.laser_mount), between(ref_kf.pose, pose)), cfg.laser_mount)
                found += self._laser_motion_segments(scan, ref_kf.prep, rel_laser)
            for a, b in sorted(set(found)):
                if not any(a < o.stop and o.start < b for o in segments):
                    bb = scan.bearings_rad
                    iv = BearingInterval(float(bb[a]), float(bb[b - 1]), source="laser")
                    segments.append(ObstacleSegment(a, b, iv))
        laser_world = compose(pose, cfg.laser_mount)
        c, s = math.cos(laser_world.theta_rad), math.sin(laser_world.theta_rad)
        detections: list[Detection] = []
        det_sources: list[BearingInterval] = []
        pts_out: list[np.ndarray] = []
        for ob in segments:
            rr = scan.ranges_m[ob.start : ob.stop]
            bb = scan.bearings_rad[ob.start : ob.stop]
            ok = np.isfinite(rr) & (rr >= cfg.psm.min_range_m)
            if np.count_nonzero(ok) < cfg.restore.min_obstacle_beams:
                continue
            xl, yl = rr[ok] * np.cos(bb[ok]), rr[ok] * np.sin(bb[ok])
            pts = np.stack([laser_world.x_m + c * xl - s * yl, laser_world.y_m + s * xl + c * yl], axis=1)
            hint = None
            for t in self._tracker.tracks:
                if t.radius_known:
                    px, py = self._tracker.predict_position(t, scan.stamp_s)
                    if math.hypot(px - pts[:, 0].mean(), py - pts[:, 1].mean()) < cfg.tracker.gate_m + t.radius_m:
                        hint = t.radius_m
                        break
            cx, cy, rad, fitted = locate_body(pts, (laser_world.x_m, laser_world.y_m), hint, cfg.tracker)
            detections.append(
                Detection(cx, cy, rad, fitted, ob.start, ob.stop, float(bb[0]), float(bb[-1]))
            )
            det_sources.append(ob.interval)
            pts_out.append(pts)
        tracked = self._tracker.step(scan.stamp_s, detections)
        obstacles: list[Obstacle] = []
        for t, det in tracked:
            if det is not None:
                k = detections.index(det)
                if det_sources[k].source in ("camera", "laser"):
                    t.camera_stamp_s = scan.stamp_s
            if det is None and (t.missed > cfg.tracker.report_missed or t.hits < 2):
                continue
            if det is not None:
                bmin, bmax, i0, i1 = det.bearing_min_rad, det.bearing_max_rad, det.scan_index_start, det.scan_index_stop
            else:
                rel = between(laser_world, Pose2D(float(t.state[0]), float(t.state[1]), 0.0))
                d = max(math.hypot(rel.x_m, rel.y_m), 1e-6)
                b = math.atan2(rel.y_m, rel.x_m)
                half = math.asin(min(t.radius_m / d, 1.0))
                bmin, bmax, i0, i1 = b - half, b + half, -1, -1
            obstacles.append(
                Obstacle(
                    track_id=t.track_id,
                    x_m=float(t.state[0]),
                    y_m=float(t.state[1]),
                    vx_mps=float(t.state[2]),
                    vy_mps=float(t.state[3]),
                    radius_m=float(t.radius_m),
                    bearing_min_rad=float(bmin),
                    bearing_max_rad=float(bmax),
                    scan_index_start=int(i0),
                    scan_index_stop=int(i1),
                    age_cycles=int(t.age_cycles),
                )
            )

        # bookkeeping -----------------------------------------------------------------------
        self._last_pose = Pose2D(pose.x_m, pose.y_m, wrap_angle(pose.theta_rad))
        self._last_odo = odo
        self._last_cov = cov
        self.last_debug = StepDebug(tuple(intervals), rest, res, kf_replaced, tuple(pts_out))
        return Estimate(
            stamp_s=scan.stamp_s,
            pose=self._last_pose,
            covariance=cov,
            obstacles=tuple(obstacles),
            quality=quality,
            flags=flags,
            restored_indices=() if self.plain_psm else rest.cut,
        )
