"""Scan matching against a keyframe (the paper's step 3), with the product's fallbacks.

The current (restored) scan is matched by PSM (:mod:`vipsm.psm`) against a keyframe, not against the
previous scan, so small per-match errors do not accumulate every cycle. The keyframe is replaced by
the current scan when the robot has moved more than ``keyframe_dist_m`` or turned more than
``keyframe_angle_rad`` from it, when the match used fewer than ``keyframe_min_overlap`` of the beams
the keyframe offers, or after a refused match once the keyframe is ``keyframe_stale_dist_m`` behind.
A keyframe is never taken from a scan whose restoration was refused (obstacle too large).

A match is refused (the pose is dead-reckoned from odometry, flag ``ODOMETRY_FALLBACK``) when PSM
refuses, when the restoration covered most of the view, or when the match corrects the odometry's
prediction by more than ``max_correction_m`` / ``max_correction_rad``. Along directions the scene does
not constrain (a corridor, or the only cross wall hidden by a masked body) the odometry's translation
is kept: there PSM's range residuals creep instead of measuring.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .geometry import between, compose, inverse
from .psm import PreparedScan, PsmResult, match_prepared
from .types import EstimateFlag, MatchQuality, Pose2D


@dataclass
class Keyframe:
    prep: PreparedScan
    pose: Pose2D  # robot pose (world)
    cov: np.ndarray
    n_good_weighted: int
    #: the ranges the laser measured (before restoration bridged any cut): what the keyframe saw
    seen_m: np.ndarray | None = None


@dataclass(frozen=True)
class MatchOutcome:
    pose: Pose2D
    cov: np.ndarray
    quality: MatchQuality
    flags: EstimateFlag
    result: PsmResult | None
    keyframe_replaced: bool


class KeyframeMatcher:
    """Holds the keyframe; ``match`` turns one prepared scan into a pose (``cfg``: EstimatorConfig)."""

    def __init__(self, cfg: object) -> None:
        self.cfg = cfg
        self.keyframe: Keyframe | None = None

    def match(self, cur: PreparedScan, n_good_w: int, predicted: Pose2D, last_pose: Pose2D | None,
              last_cov: np.ndarray, usable: bool, refuse: bool, seen_m: np.ndarray | None = None) -> MatchOutcome:
        """``usable``: the scan can become a keyframe; ``refuse``: do not match (restoration too large,
        bad bearings); ``seen_m``: the measured ranges of ``cur`` before restoration (kept with it)."""
        cfg = self.cfg
        if last_pose is None or self.keyframe is None:
            first = last_pose is None
            flags = EstimateFlag.FIRST_SCAN if first else EstimateFlag.ODOMETRY_FALLBACK
            cov = np.zeros((3, 3)) if first else last_cov.copy()
            psm = cfg.psm.for_scan(cur.ranges_m.size, cur.dphi_rad)  # type: ignore[attr-defined]
            replaced = usable and n_good_w >= psm.min_valid_beams
            if replaced:
                self.keyframe = Keyframe(cur, predicted, cov, n_good_w, seen_m)
            return MatchOutcome(predicted, cov, MatchQuality(0, 0, float("nan"), False), flags, None, replaced)
        res, cand = (None, None) if refuse else self._psm(cur, predicted)
        if cand is None:
            return self._fallback(cur, n_good_w, predicted, last_pose, last_cov, usable, res, seen_m)
        kf = self.keyframe
        th = kf.pose.theta_rad + cfg.laser_theta_rad  # type: ignore[attr-defined]
        c, s = math.cos(th), math.sin(th)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        cov = kf.cov + rot @ res.covariance @ rot.T
        quality = MatchQuality(res.beams_used, res.iterations, res.residual_m, res.converged)
        since = between(kf.pose, cand)
        replaced = (
            math.hypot(since.x_m, since.y_m) > cfg.keyframe_dist_m  # type: ignore[attr-defined]
            or abs(since.theta_rad) > cfg.keyframe_angle_rad  # type: ignore[attr-defined]
            or res.beams_used < cfg.keyframe_min_overlap * max(kf.n_good_weighted, 1)  # type: ignore[attr-defined]
        )
        if replaced:
            self.keyframe = Keyframe(cur, cand, cov, n_good_w, seen_m)
        return MatchOutcome(cand, cov, quality, EstimateFlag.NONE, res, replaced)

    def _psm(self, cur: PreparedScan, predicted: Pose2D) -> tuple[PsmResult | None, Pose2D | None]:
        cfg = self.cfg
        kf = self.keyframe
        assert kf is not None
        mount = cfg.laser_mount  # type: ignore[attr-defined]
        guess = compose(compose(inverse(mount), between(kf.pose, predicted)), mount)
        res = match_prepared(kf.prep, cur, guess, cfg.psm)  # type: ignore[attr-defined]
        if res.refused:
            return res, None
        matched = self._constrain_weak_directions(res, guess)
        cand = compose(kf.pose, compose(compose(mount, matched), inverse(mount)))
        corr = between(predicted, cand)
        if (math.hypot(corr.x_m, corr.y_m) > cfg.max_correction_m  # type: ignore[attr-defined]
                or abs(corr.theta_rad) > cfg.max_correction_rad):  # type: ignore[attr-defined]
            return res, None
        return res, cand

    def _fallback(self, cur: PreparedScan, n_good_w: int, predicted: Pose2D, last_pose: Pose2D,
                  last_cov: np.ndarray, usable: bool, res: PsmResult | None,
                  seen_m: np.ndarray | None) -> MatchOutcome:
        cfg = self.cfg
        step = between(last_pose, predicted)
        dist = math.hypot(step.x_m, step.y_m)
        g = np.diag([(cfg.odom_sigma_per_m * dist) ** 2] * 2  # type: ignore[attr-defined]
                    + [(cfg.odom_sigma_rad_per_rad * abs(step.theta_rad)) ** 2])  # type: ignore[attr-defined]
        cov = last_cov + g
        quality = MatchQuality(res.beams_used if res else 0, res.iterations if res else 0, float("nan"), False)
        assert self.keyframe is not None
        since = between(self.keyframe.pose, predicted)
        replaced = math.hypot(since.x_m, since.y_m) > cfg.keyframe_stale_dist_m and usable  # type: ignore[attr-defined]
        if replaced:
            self.keyframe = Keyframe(cur, predicted, cov, n_good_w, seen_m)
        return MatchOutcome(predicted, cov, quality, EstimateFlag.ODOMETRY_FALLBACK, res, replaced)

    def _constrain_weak_directions(self, res: PsmResult, guess: Pose2D) -> Pose2D:
        info = res.info_xy
        if not res.converged:
            # still creeping after max_iterations: keep the odometry's translation, take the rotation
            return Pose2D(guess.x_m, guess.y_m, res.dtheta_rad)
        if info is None:
            return res.pose
        lam, vec = np.linalg.eigh(info)
        dx, dy = res.dx_m - guess.x_m, res.dy_m - guess.y_m
        lo, hi = self.cfg.weak_info_min, self.cfg.weak_info  # type: ignore[attr-defined]
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
