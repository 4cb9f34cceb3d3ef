"""Scan matching against a keyframe (the paper's step 3), with the product's fallbacks.

The current (restored) scan is matched by PSM (:mod:`vipsm.psm`) against a keyframe, not against the
previous scan, so small per-match errors do not accumulate every cycle. The keyframe is replaced by
the current scan when the robot has moved more than ``keyframe_dist_m`` or turned more than
``keyframe_angle_rad`` from it, when the match used fewer than ``keyframe_min_overlap`` of the beams
the keyframe offers, or after a refused match once the keyframe is ``keyframe_stale_dist_m`` behind.
A keyframe is never taken from a scan whose restoration was refused (obstacle too large).

A refused match (PSM refuses, or the match corrects the prediction by more than ``max_correction_m`` /
``max_correction_rad``) is retried against the keyframe with a widened search, then against the previous
keyframe and the last scan (``recovery_*``); the first accepted retry re-anchors the keyframe. When all
are refused, or the restoration covered most of the view, the pose is the prediction (odometry, or
constant velocity without it), flag ``ODOMETRY_FALLBACK``. Along directions the scene does
not constrain (a corridor, or the only cross wall hidden by a masked body) the odometry's translation
is kept: there PSM's range residuals creep instead of measuring.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .geometry import between, compose, inverse
from .psm import PreparedScan, PsmResult, match_prepared, prepare_scan
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
        #: the keyframe before the current one, and the last scan (with its estimated pose): the references
        #: a refused match is retried against
        self.previous: Keyframe | None = None
        self.last: Keyframe | None = None
        #: matches accepted only by a retry (diagnostics: a prediction that keeps missing shows here)
        self.recoveries = 0
        #: the ranges the current scan was prepared from (``match``'s ``restored_m``)
        self._restored_m: np.ndarray | None = None
        psm = cfg.psm  # type: ignore[attr-defined]
        recovery = dataclasses.replace(
            psm, search_window_first_rad=max(cfg.recovery_window_rad, psm.search_window_first_rad),  # type: ignore[attr-defined]
            max_error_first_m=max(cfg.recovery_max_error_m, psm.max_error_m))  # type: ignore[attr-defined]
        steps = cfg.no_odometry_refine_iterations  # type: ignore[attr-defined]
        #: (normal, retry) matcher settings with odometry (False) and without (True)
        self._configs = {False: (psm, recovery),
                         True: (dataclasses.replace(psm, refine_iterations=steps),
                                dataclasses.replace(recovery, refine_iterations=steps))}
        self._no_odometry = False

    def _set_keyframe(self, kf: Keyframe) -> None:
        if self.keyframe is not None and self.keyframe is not kf:
            self.previous = self.keyframe
        self.keyframe = kf

    def _new_keyframe(self, cur: PreparedScan, pose: Pose2D, cov: np.ndarray, n_good_w: int,
                      seen_m: np.ndarray | None) -> None:
        """The current scan becomes the keyframe, its cut beams filled from the old keyframe's view."""
        old, restored = self.keyframe, self._restored_m
        if old is not None and seen_m is not None and restored is not None:
            cfg = self.cfg
            rc = cfg.restore  # type: ignore[attr-defined]
            cur = fill_hidden(cur, pose, seen_m, restored, old, cfg.laser_mount,  # type: ignore[attr-defined]
                              rc.bump_m, rc.max_body_chord_m, cfg.psm)  # type: ignore[attr-defined]
        self._set_keyframe(Keyframe(cur, pose, cov, n_good_w, seen_m))

    def match(self, cur: PreparedScan, n_good_w: int, predicted: Pose2D, last_pose: Pose2D | None,
              last_cov: np.ndarray, usable: bool, refuse: bool, seen_m: np.ndarray | None = None,
              no_odometry: bool = False, restored_m: np.ndarray | None = None) -> MatchOutcome:
        """``usable``: the scan can become a keyframe; ``refuse``: do not match (restoration too large,
        bad bearings); ``seen_m``: the measured ranges of ``cur`` before restoration (kept with it);
        ``no_odometry``: the prediction is constant velocity (``no_odometry_refine_iterations`` apply);
        ``restored_m``: the ranges ``cur`` was prepared from (a new keyframe's cut beams are filled from
        the old keyframe's view where it saw behind them, :func:`fill_hidden`)."""
        cfg = self.cfg
        self._no_odometry = no_odometry
        self._restored_m = restored_m
        if last_pose is None or self.keyframe is None:
            first = last_pose is None
            flags = EstimateFlag.FIRST_SCAN if first else EstimateFlag.ODOMETRY_FALLBACK
            cov = np.zeros((3, 3)) if first else last_cov.copy()
            replaced = usable and n_good_w >= cfg.psm.required_beams(0)  # type: ignore[attr-defined]
            if replaced:
                self._new_keyframe(cur, predicted, cov, n_good_w, seen_m)
            self._remember(cur, predicted, cov, n_good_w, seen_m, usable)
            return MatchOutcome(predicted, cov, MatchQuality(0, 0, float("nan"), False), flags, None, replaced)
        out = self._match_or_recover(cur, n_good_w, predicted, last_pose, last_cov, usable, refuse, seen_m)
        self._remember(cur, out.pose, out.cov, n_good_w, seen_m, usable)
        return out

    def _remember(self, cur: PreparedScan, pose: Pose2D, cov: np.ndarray, n_good_w: int, seen_m: np.ndarray | None,
                  usable: bool) -> None:
        self.last = Keyframe(cur, pose, cov, n_good_w, seen_m) if usable else None

    def _match_or_recover(self, cur: PreparedScan, n_good_w: int, predicted: Pose2D, last_pose: Pose2D,
                          last_cov: np.ndarray, usable: bool, refuse: bool, seen_m: np.ndarray | None
                          ) -> MatchOutcome:
        """The match against the keyframe; refused, the retries (:meth:`_recover`); all refused, the
        prediction (:meth:`_fallback`)."""
        res, cand = (None, None) if refuse else self._psm(cur, predicted)
        if cand is None and not refuse:
            rec = self._recover(cur, predicted)
            if rec is not None:
                res, cand, kf = rec
                self.recoveries += 1
                if kf is not self.keyframe:
                    self._set_keyframe(kf)  # re-anchored: the reference that matched is the keyframe now
        if cand is None:
            return self._fallback(cur, n_good_w, predicted, last_pose, last_cov, usable, res, seen_m)
        assert res is not None
        return self._accept(cur, n_good_w, res, cand, seen_m)

    def _accept(self, cur: PreparedScan, n_good_w: int, res: PsmResult, cand: Pose2D, seen_m: np.ndarray | None
                ) -> MatchOutcome:
        """An accepted match against the keyframe: its covariance, and the keyframe replaced when the robot
        has moved on or the overlap has shrunk."""
        cfg = self.cfg
        kf = self.keyframe
        assert kf is not None
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
            self._new_keyframe(cur, cand, cov, n_good_w, seen_m)
        return MatchOutcome(cand, cov, quality, EstimateFlag.NONE, res, replaced)

    def _psm(self, cur: PreparedScan, predicted: Pose2D, kf: Keyframe | None = None, recovery: bool = False
             ) -> tuple[PsmResult | None, Pose2D | None]:
        """Match against ``kf`` (default: the keyframe) from the prediction; ``recovery``: with the widened
        search and correction limits. (result, pose) or (result, None) when refused."""
        cfg = self.cfg
        kf = kf or self.keyframe
        assert kf is not None
        mount = cfg.laser_mount  # type: ignore[attr-defined]
        guess = compose(compose(inverse(mount), between(kf.pose, predicted)), mount)
        res = match_prepared(kf.prep, cur, guess, self._configs[self._no_odometry][1 if recovery else 0])
        if res.refused:
            return res, None
        matched = self._constrain_weak_directions(res, guess)
        cand = compose(kf.pose, compose(compose(mount, matched), inverse(mount)))
        corr = between(predicted, cand)
        lim_m = cfg.recovery_max_correction_m if recovery else cfg.max_correction_m  # type: ignore[attr-defined]
        lim_rad = cfg.recovery_max_correction_rad if recovery else cfg.max_correction_rad  # type: ignore[attr-defined]
        if math.hypot(corr.x_m, corr.y_m) > lim_m or abs(corr.theta_rad) > lim_rad:
            return res, None
        return res, cand

    def _recover(self, cur: PreparedScan, predicted: Pose2D) -> tuple[PsmResult, Pose2D, Keyframe] | None:
        """After a refusal: the keyframe again with the search widened (a prediction off by more than the
        normal window), then the previous keyframe and the last scan (the keyframe's view may no longer
        overlap, the last scan's always does unless the scanner was blinded). The first accepted wins."""
        for kf in (self.keyframe, self.previous, self.last):
            if kf is None or (kf is not self.keyframe and kf.prep is self.keyframe.prep):  # type: ignore[union-attr]
                continue
            res, cand = self._psm(cur, predicted, kf, recovery=True)
            if cand is not None and res is not None:
                return res, cand, kf
        return None

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
            self._new_keyframe(cur, predicted, cov, n_good_w, seen_m)
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


def fill_hidden(cur: PreparedScan, pose: Pose2D, seen_m: np.ndarray, restored_m: np.ndarray, old: Keyframe,
                mount: Pose2D, behind_m: float, min_chord_m: float, psm_config: object) -> PreparedScan:
    """A new keyframe ``cur`` (robot at ``pose``) whose restoration cut beams (weight 0: a moving body stood
    there) with those beams filled from the old keyframe ``old``: where ``old`` saw background (a surface
    the matcher may use, of a segment wider than ``min_chord_m``: no body) at least ``behind_m`` beyond what
    this scan returned on that beam (``seen_m``), that background is what the body hides now (the nearest,
    where several lie on one beam). Without it, a
    body that hides the only wall constraining one direction (a crowd before a corridor's end wall) leaves
    the keyframe blind along it, and every later match there is pulled by whatever else moves. Other beams
    as prepared from ``restored_m``."""
    cut = cur.weights <= 0.0
    if not cut.any() or cur.bearings_rad.size < 2:
        return cur
    fill = _cast_keyframe(old, between(compose(old.pose, mount), compose(pose, mount)), cur.bearings_rad,
                          min_chord_m)
    seen = np.where(np.isfinite(seen_m), seen_m, 0.0)
    use = cut & np.isfinite(fill) & (fill >= seen + behind_m)
    if not use.any():
        return cur
    return prepare_scan(np.where(use, fill, restored_m), cur.bearings_rad, psm_config,  # type: ignore[arg-type]
                        np.where(use, 1.0, cur.weights))


def _cast_keyframe(kf: Keyframe, rel: Pose2D, bearings_rad: np.ndarray, min_chord_m: float) -> np.ndarray:
    """Per beam of ``bearings_rad`` (ascending) of a laser at ``rel`` from ``kf``'s laser,
    the range to the nearest surface ``kf`` saw on a segment wider than ``min_chord_m``: each pair of
    neighbouring usable returns of such a segment is a piece of surface (inf where none)."""
    p = kf.prep
    ok = p.good & (p.weights > 0.0) & (_chords(p) > min_chord_m)
    c, s = math.cos(rel.theta_rad), math.sin(rel.theta_rad)
    # kf's points in the new laser's frame (rel is the new laser's pose in kf's laser frame)
    dx, dy = p.x_m - rel.x_m, p.y_m - rel.y_m
    x, y = c * dx + s * dy, -s * dx + c * dy
    a = p.pair_a[ok[p.pair_a] & ok[p.pair_b]]
    b = a + 1
    pa, pb = np.arctan2(y[a], x[a]), np.arctan2(y[b], x[b])
    keep = np.abs(pa - pb) < math.pi / 2  # a piece across the new laser's back is no piece of its view
    a, b, pa, pb = a[keep], b[keep], pa[keep], pb[keep]
    n = bearings_rad.size
    k_lo = np.searchsorted(bearings_rad, np.minimum(pa, pb), side="left")
    k_hi = np.searchsorted(bearings_rad, np.maximum(pa, pb), side="right") - 1
    count = np.maximum(k_hi - k_lo + 1, 0)
    out = np.full(n, np.inf)
    if not count.any():
        return out
    piece = np.repeat(np.arange(a.size), count)
    k = k_lo[piece] + (np.arange(piece.size) - np.repeat(np.cumsum(count) - count, count))
    ux, uy = np.cos(bearings_rad[k]), np.sin(bearings_rad[k])
    xa, ya, ex, ey = x[a][piece], y[a][piece], (x[b] - x[a])[piece], (y[b] - y[a])[piece]
    den = ux * ey - uy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        rng = (xa * ey - ya * ex) / den
    hit = np.isfinite(rng) & (rng > 0.0)
    np.minimum.at(out, k[hit], rng[hit])
    return out


def _chords(p: PreparedScan) -> np.ndarray:
    """Per beam, the distance between the first and the last return of its segment (0 outside segments)."""
    n = p.segments.size
    ids = p.segments.astype(np.int64)
    first = np.full(int(ids.max(initial=0)) + 1, n)
    last = np.full(first.size, -1)
    order = np.arange(n)
    np.minimum.at(first, ids, order)
    np.maximum.at(last, ids, order)
    f, z = first[ids], last[ids]
    ok = (ids > 0) & (z >= f)
    chord = np.zeros(n)
    chord[ok] = np.hypot(p.x_m[z[ok]] - p.x_m[f[ok]], p.y_m[z[ok]] - p.y_m[f[ok]])
    return chord
