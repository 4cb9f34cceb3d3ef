"""Polar Scan Matching (Diosi & Kleeman), vectorised NumPy, SI units, x forward / y left.

The algorithm follows the published method and the authors' reference code (polar_matching v0.3)
with the fixes listed in ``shared/protocols/psm.md`` §5/§9:

* bearings come from the scan (no FOV/(N+1) spacing quirk); the frame has x forward, so the atan2
  branch cut lies in the UTM-30LX's blind rear sector (no +2 pi hack, no lost pairs);
* invalid returns are tagged *before* the window-5 median filter (and do not leak "far" values);
* segmentation uses a range-scaled jump threshold max(seg_jump_m, k * r * dphi) together with the
  extrapolation test, and drops segments shorter than ``min_segment_beams``;
* the orientation search gates residuals with ``max_error_m`` and needs a minimum overlap per shift;
* the translation step solves the 2x2 weighted normal equations exactly (no dropped off-diagonal);
* the stopping test checks translation (m) and rotation (rad) separately;
* per-beam weights in [0, 1] multiply the robust weights in *both* steps, so beams bridged by the
  VIPSM restoration (weight 0) never pull the estimate;
* a covariance from the weighted normal equations and the orientation-cost curvature, raised to the
  original's heuristic floor (with its corridor ellipse);
* failures never raise: :func:`match` returns a :class:`PsmResult` with ``refused=True`` and a
  :class:`PsmRefusal` reason, carrying the initial guess so the caller can fall back to odometry.

Result convention: ``(dx_m, dy_m, dtheta_rad)`` is the pose of the *current* scan's laser frame in
the *reference* scan's laser frame (x forward, y left), like the original's ``rx, ry, th``.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import math
from dataclasses import dataclass

import numpy as np

from .types import Pose2D, Scan

# Preprocessing tag bits (the original's PM_* flags; PM_MOVING is the slot VIPSM fills).
TAG_INVALID = 1  # no return / error code / below min range (the original's sensor errors)
TAG_RANGE = 2  # beyond max_range_m (PM_RANGE)
TAG_MOVING = 4  # cut out by the visual restoration (PM_MOVING)
TAG_SEGMENT = 8  # isolated point / segment shorter than min_segment_beams


@dataclass(frozen=True)
class PsmConfig:
    """PSM parameters, SI units; defaults for a Hokuyo UTM-30LX matched scan-to-scan at 10-40 Hz
    (``shared/protocols/psm.md`` §10). :meth:`diosi_v03_utm` gives the original v0.3 UTM values."""

    min_range_m: float = 0.10  # below: invalid (the UTM's minimum; also removes its error codes)
    max_range_m: float = 10.0  # beyond: tagged far/bad (range gating)
    median_window: int = 5  # odd; 1 disables the median filter
    seg_jump_m: float = 0.20  # segmentation: minimum range jump that starts a new segment
    seg_jump_range_factor: float = 3.0  # ... raised to k * r * dphi at long range
    min_segment_beams: int = 3  # shorter segments are dropped
    max_error_m: float = 0.30  # residual gate in both steps (PM_MAX_ERROR)
    max_error_first_m: float | None = None  # gate before change_weight_iter (None: max_error_m)
    weight_c_m2: float = 0.30**2  # C of w = C / (C + e^2) (PM_WEIGHTING_FACTOR)
    change_weight_iter: int = 10  # at this iteration C becomes C / weight_c_divisor
    weight_c_divisor: float = 50.0
    search_window_first_beams: int = 80  # half-window of the first orientation search
    search_window_beams: int = 20  # half-window of later orientation searches
    #: > 0: the half-windows as angles, turned into beams with the scan's own step (:meth:`for_scan`), so
    #: the search covers the same angle on any scanner; 0: the beam counts above as they are
    search_window_first_rad: float = 0.0
    search_window_rad: float = 0.0
    min_overlap_frac: float = 0.30  # share of the usable beams a shift must compare
    orientation_gain: float = 1.0  # b in phi = phi_p + b * d_phi (paper eq. 4); 1 = plain PSM
    max_iterations: int = 30
    stop_translation_m: float = 0.001
    stop_rotation_rad: float = math.radians(0.01)
    stop_count: int = 3  # consecutive small iterations to stop
    #: refuse below this many beams compared in a translation step; 0: derived per pair from what the two
    #: scans offer (:meth:`required_beams`): a range-limited or narrow scanner sees fewer beams, not worse ones
    min_valid_beams: int = 0
    #: the match must compare this share of the beams both scans offer (the smaller of the two scans' usable
    #: beam counts): the overlap the evidence needs, whatever the scanner's beam count or range (on the
    #: UTM-30LX in a room, ~300 of ~1000 usable, the count this was tuned at)
    min_valid_share: float = 0.30
    #: ... and never fewer than this many: a 3-parameter fit on a handful of beams measures their noise
    min_valid_floor_beams: int = 20
    max_pair_gap_rad: float = 0.25  # do not interpolate a projected pair across a wider bearing gap
    line_interpolation: bool = True  # True: ray/chord intersection; False: range linear in bearing (original)
    degenerate_eig: float = 1e-3  # refuse if min eig of H'WH / sum(w) is below this
    damping: float = 1e-6  # Tikhonov term (relative to sum w) toward the current guess
    cov_floor_sigma_xy_m: float = 0.20  # heuristic floor (PM_MIN_STD_XY)
    cov_floor_sigma_theta_rad: float = math.radians(4.0)  # (PM_MIN_STD_ORIENTATION)
    cov_error_offset_m: float = 0.05  # (PM_MATCH_ERROR_OFFSET)
    cov_floor_scale_m: float = 0.01  # the error index is counted in these units (the original: cm)
    corridor_info_ratio: float = 0.05  # corridor: weak/strong translation information below this
    corridor_direction_test: bool = False  # also run the original's direction-spread test (noisy at short range)
    corridor_threshold_rad: float = math.radians(25.0)
    corridor_sigma_along_m: float = 4.0
    corridor_sigma_across_m: float = 0.30
    use_cov_floor: bool = True
    #: point-to-line iterations that finish PSM's pose (:mod:`vipsm.plicp`); 0: PSM alone
    refine_iterations: int = 0
    refine_window_rad: float = math.radians(1.5)  # nearest reference point searched this far in bearing
    refine_max_dist_m: float = 0.30  # pairs further from their line are left out
    refine_robust_scale: float = 3.0  # Cauchy scale: this times the median |residual| ...
    refine_min_scale_m: float = 0.01  # ... and at least this (the range noise)
    refine_damping: float = 1e-4  # towards no change, relative to the information (unconstrained directions)
    #: a pair PSM refuses is refined from the initial guess instead (accepted when the refinement is)
    refine_refused: bool = False
    #: the refinement's cost in both directions: the current points against the reference's lines and the
    #: reference's points against the current's lines (a one-sided fit leans on one scan's sampling)
    refine_symmetric: bool = False

    def __post_init__(self) -> None:
        if self.median_window < 1 or self.median_window % 2 == 0:
            raise ValueError(f"median_window must be odd and >= 1, got {self.median_window}")
        if not 0.0 < self.min_range_m < self.max_range_m:
            raise ValueError("need 0 < min_range_m < max_range_m")
        if self.max_error_m <= 0 or self.weight_c_m2 <= 0 or self.weight_c_divisor <= 0:
            raise ValueError("max_error_m, weight_c_m2 and weight_c_divisor must be positive")
        if self.search_window_first_beams < 1 or self.search_window_beams < 1:
            raise ValueError("search windows must be >= 1 beam")
        if self.max_iterations < 1 or self.stop_count < 1 or self.min_segment_beams < 1:
            raise ValueError("max_iterations, stop_count and min_segment_beams must be >= 1")
        if self.min_valid_beams < 0 or self.min_valid_floor_beams < 3 or not 0.0 < self.min_valid_share <= 1.0:
            raise ValueError("need min_valid_beams >= 0, min_valid_floor_beams >= 3 and 0 < min_valid_share <= 1")
        if self.search_window_first_rad < 0.0 or self.search_window_rad < 0.0:
            raise ValueError("search window angles must be >= 0 (0: the beam counts)")
        if self.refine_iterations < 0 or not (self.refine_window_rad > 0.0 and self.refine_max_dist_m > 0.0
                                              and self.refine_robust_scale > 0.0 and self.refine_min_scale_m > 0.0
                                              and self.refine_damping >= 0.0):
            raise ValueError("need refine_iterations >= 0, positive refine_* lengths and scales, refine_damping >= 0")

    def for_scan(self, n_beams: int, dphi_rad: float) -> PsmConfig:
        """The configuration with its per-sensor counts resolved for a scan of ``n_beams`` beams
        ``dphi_rad`` apart: the search windows from the angles."""
        return _for_scan(self, int(n_beams), round(abs(float(dphi_rad)), 12))

    def required_beams(self, n_available: int) -> int:
        """Beams a match must compare when the two scans offer ``n_available`` usable beams (the smaller
        scan's count): ``min_valid_beams`` when set, else ``min_valid_share`` of them and at least
        ``min_valid_floor_beams``."""
        if self.min_valid_beams > 0:
            return self.min_valid_beams
        return max(self.min_valid_floor_beams, math.ceil(self.min_valid_share * max(n_available, 0) - 1e-9))

    @classmethod
    def diosi_v03_utm(cls) -> PsmConfig:
        """The original v0.3 parameters for the UTM-30LX (PM_MAX_RANGE 7 m, MAX_ERROR 1 m, C = 0.7^2,
        window +-200 beams), with this port's fixes kept (exact bearings, stopping units)."""
        return cls(
            max_range_m=7.0,
            max_error_m=1.0,
            weight_c_m2=0.70**2,
            search_window_first_beams=200,
            search_window_beams=200,
            min_segment_beams=2,
            # v0.3 reduces C only when iteration 10 is a translation step, and iteration 10 is an
            # orientation step: C is never reduced. Reproduced here to agree with its results.
            change_weight_iter=10**9,
            line_interpolation=False,
        )

    @classmethod
    def preset(cls, name: str) -> PsmConfig:
        """The settings of one scanner class of :data:`SCANNER_PRESETS` (ValueError for another name)."""
        return _preset(name)

    @classmethod
    def for_geometry(cls, step_rad: float, max_range_m: float = math.inf) -> PsmConfig:
        """The preset of the scanner class a scan's geometry belongs to (:func:`preset_name_for`)."""
        return _preset(preset_name_for(step_rad, max_range_m))

    @classmethod
    def sick_1deg(cls) -> PsmConfig:
        """A 180-beam, 1-degree scanner (the Intel Research Lab log): the original's SICK LMS200 block
        (min 40 valid beams, +-20 beam window) with scan-to-scan settings."""
        return cls(
            max_range_m=10.0,
            min_valid_beams=20,
            search_window_first_beams=20,
            search_window_beams=10,
            max_error_m=0.5,
            weight_c_m2=0.10**2,  # Intel pairs: C in 0.01..0.0625 m^2 tried, smaller was better throughout
            seg_jump_range_factor=2.0,
        )


#: the scanner classes of the shared data (``docs/psm.md``, "Presets"); :meth:`PsmConfig.for_geometry` picks one
SCANNER_PRESETS = ("utm30lx", "hokuyo_0.35deg", "urg04lx", "half_degree", "one_degree")


def _preset(name: str) -> PsmConfig:
    """Scan-to-scan settings per scanner class, PSM then point-to-line refinement. Fine Hokuyo scans
    (0.25-0.35 deg): the defaults with the search windows as angles (+-20 deg first, +-5 deg later) and
    5 refinement steps. Coarse SICK scans (0.5 and 1 deg): the original's SICK block (segments broken at
    2 r dphi, C = 0.1^2, +-20 / +-10 deg windows), a 3-beam median at 0.5 deg (5 beams of 1 deg round a
    corner off by 2 deg), the two-way refinement (at 0.5-1 deg one scan's chords are coarse: a one-sided
    fit leans on them) run to convergence (at most 30 steps; the stop test ends most within 15), and a pair
    PSM refuses refined from the guess."""
    fine = dict(search_window_first_rad=math.radians(20.0), search_window_rad=math.radians(5.0), refine_iterations=5)
    coarse = dict(max_range_m=10.0, min_valid_beams=20, search_window_first_rad=math.radians(20.0),
                  search_window_rad=math.radians(10.0), max_error_m=0.5, weight_c_m2=0.10**2,
                  seg_jump_range_factor=2.0, median_window=3, refine_iterations=30, refine_refused=True,
                  refine_symmetric=True)
    table: dict[str, dict[str, object]] = {
        "utm30lx": fine,
        "hokuyo_0.35deg": fine,
        "urg04lx": {**fine, "max_range_m": 5.6},  # its range limit: nothing beyond is a return
        "half_degree": coarse,
        # at 1 deg even a 3-beam median rounds corners: the refinement reads the raw points, with a wider
        # Cauchy scale (chosen on the Intel pairs, so that figure is not an independent test of it)
        "one_degree": {**coarse, "median_window": 1, "refine_robust_scale": 5.0},
    }
    if name not in table:
        raise ValueError(f"unknown scanner preset {name!r}; known: {', '.join(SCANNER_PRESETS)}")
    return PsmConfig(**table[name])  # type: ignore[arg-type]


def preset_name_for(step_rad: float, max_range_m: float = math.inf) -> str:
    """The scanner class of a scan with bearing step ``step_rad`` whose returns end at ``max_range_m``
    (a LaserScan's ``range_max``): 0.25 deg UTM-30LX; 0.35 deg Hokuyo (the URG-04LX when its range ends
    by 6 m); 0.5 deg and 1 deg SICK-class scans. The class boundaries lie midway between the steps."""
    deg = math.degrees(abs(step_rad))
    if not deg > 0.0:
        raise ValueError(f"the bearing step must be > 0, got {step_rad}")
    if deg < 0.30:
        return "utm30lx"
    if deg < 0.425:
        return "urg04lx" if max_range_m <= 6.0 else "hokuyo_0.35deg"
    if deg < 0.75:
        return "half_degree"
    return "one_degree"


@functools.lru_cache(maxsize=64)
def _for_scan(c: PsmConfig, n_beams: int, dphi_rad: float) -> PsmConfig:
    changes: dict[str, int] = {}
    if dphi_rad > 0.0 and c.search_window_first_rad > 0.0:
        changes["search_window_first_beams"] = max(1, round(c.search_window_first_rad / dphi_rad))
    if dphi_rad > 0.0 and c.search_window_rad > 0.0:
        changes["search_window_beams"] = max(1, round(c.search_window_rad / dphi_rad))
    return dataclasses.replace(c, **changes) if changes else c


class PsmRefusal(enum.Enum):
    NONE = "none"
    EMPTY_SCAN = "empty_scan"  # a scan with no usable beam after preprocessing
    TOO_FEW_BEAMS = "too_few_beams"  # fewer compared in a translation step than required_beams()
    NO_VALID_SHIFT = "no_valid_shift"  # the orientation search found no shift with enough overlap
    DEGENERATE = "degenerate"  # the translation normal equations are (nearly) singular
    BAD_INPUT = "bad_input"  # shapes/bearings unusable (e.g. mismatched lengths, non-ascending)


@dataclass(frozen=True)
class PsmResult:
    """Pose of the current laser frame in the reference laser frame, and how the match went.

    When ``refused`` is true the pose is the initial guess unchanged and ``reason`` says why; the
    caller falls back to odometry."""

    dx_m: float
    dy_m: float
    dtheta_rad: float
    covariance: np.ndarray  # 3x3 over (x_m, y_m, theta_rad)
    iterations: int
    beams_used: int
    residual_m: float
    converged: bool
    refused: bool
    reason: PsmRefusal = PsmRefusal.NONE
    corridor: bool = False
    #: 2x2 translation information per used beam from the surface normals (point-to-line model):
    #: its small eigenvalues show directions the scene does not constrain (corridors), which the
    #: range-residual Jacobian (cos, sin) of PSM does not reveal
    info_xy: np.ndarray | None = None
    #: the heading's standard deviation the match itself measured (the orientation cost's curvature against
    #: its noise), before the heuristic floor of ``covariance``; NaN when refused
    heading_sigma_rad: float = math.nan

    @property
    def pose(self) -> Pose2D:
        return Pose2D(self.dx_m, self.dy_m, self.dtheta_rad)


#: normals come from the points this many beams either side within the same segment (clipped at the
#: segment's ends): a wide stencil keeps range noise from tilting the normals of distant, grazing walls
_NORMAL_HALF_BEAMS = 3


@dataclass(frozen=True)
class PreparedScan:
    """A preprocessed scan: filtered ranges, tags, segments and weights, ready for matching."""

    ranges_m: np.ndarray  # median-filtered ranges; meaningless where ``good`` is false
    bearings_rad: np.ndarray
    tags: np.ndarray  # uint8 TAG_* bits, 0 = good
    segments: np.ndarray  # int32 segment id per beam, 0 = none
    weights: np.ndarray  # float64 per-beam weight in [0, 1] (0 = bridged / masked)
    good: np.ndarray  # bool: usable for matching (tags == 0)
    pair_a: np.ndarray  # indices of consecutive good beams in the same segment (pose independent)
    pair_b: np.ndarray
    x_m: np.ndarray  # Cartesian points of the filtered ranges (laser frame)
    y_m: np.ndarray
    dphi_rad: float  # mean bearing step
    pair_ok: np.ndarray  # (n-1,) bool: beams i, i+1 form a pair
    pair_w: np.ndarray  # (n-1,) weight of the pair (min of its two beams)
    normal_x: np.ndarray  # unit surface normal per beam (0 where unknown)
    normal_y: np.ndarray

    @property
    def n_good(self) -> int:
        return int(np.count_nonzero(self.good))

    @functools.cached_property
    def n_usable(self) -> int:
        """Beams a match can compare: good and with a weight above 0."""
        return int(np.count_nonzero(self.good & (self.weights > 0.0)))


def median_filter_valid(ranges_m: np.ndarray, valid: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Window-``window`` median with edges clamped; invalid beams count as +inf (far), so an invalid
    beam never pulls a real one toward a made-up value, and a valid beam whose window is mostly
    invalid becomes invalid. Returns (filtered, still_valid)."""
    from .psm_kernel import median_filter

    r = np.where(valid, ranges_m, np.inf)
    if window <= 1 or r.size == 0:
        return r, valid & np.isfinite(r)
    med = median_filter(r, window)
    return med, valid & np.isfinite(med)


def segment_scan(
    ranges_m: np.ndarray, good: np.ndarray, dphi_rad: float, jump_m: float, range_factor: float
) -> np.ndarray:
    """Segment ids (1..) per beam, 0 for bad beams. A segment breaks at a bad beam, or where the
    range jump exceeds max(jump_m, range_factor * r * dphi) and the straight-line extrapolation from
    the two previous beams misses by as much (the extrapolation test of the original, which keeps
    grazing walls in one piece). The extrapolation is used whenever the two previous beams are good
    (the original also joins three aligned points that straddle a jump). Compiled
    (:func:`vipsm.psm_kernel.segment`)."""
    from .psm_kernel import segment

    return segment(np.asarray(ranges_m, dtype=np.float64), np.asarray(good, dtype=bool), float(dphi_rad),
                   float(jump_m), float(range_factor))


def prepare_scan(
    ranges_m: np.ndarray,
    bearings_rad: np.ndarray,
    config: PsmConfig,
    weights: np.ndarray | None = None,
) -> PreparedScan:
    """Preprocess one scan: invalid first, median filter, range gating, segmentation, short segments
    dropped. ``weights`` (default 1) are per-beam; beams with weight 0 stay in the geometry (they keep
    segments contiguous for projection) but never count in a matching step. The work is one compiled
    call (:func:`vipsm.psm_kernel.preprocess`). ValueError: bearings not finite and strictly
    ascending, or weights or bearings of another shape than the ranges."""
    from .psm_kernel import preprocess

    # contiguous, writable float64 (a copy only where needed): one compiled signature for every caller
    r_raw = np.require(ranges_m, np.float64, ("C", "W"))
    b = np.require(bearings_rad, np.float64, ("C", "W"))
    n = r_raw.size
    w = np.ones(n) if weights is None else np.clip(np.asarray(weights, dtype=np.float64), 0.0, 1.0)
    if w.shape != r_raw.shape or b.shape != r_raw.shape:
        raise ValueError(f"weights {w.shape} and bearings {b.shape} must have the ranges' shape {r_raw.shape}")
    dphi = float((b[-1] - b[0]) / (n - 1)) if n > 1 else 1.0
    cos_b, sin_b = cur_cos_sin(b) if n else (b, b)
    rf, tags, seg, good, x, y, pair_ok, pair_w, nx, ny = preprocess(
        r_raw, b, cos_b, sin_b, w, abs(dphi), config.min_range_m, config.max_range_m, config.median_window,
        config.seg_jump_m, config.seg_jump_range_factor, config.min_segment_beams, _NORMAL_HALF_BEAMS,
        TAG_INVALID, TAG_RANGE, TAG_SEGMENT)
    pa = np.flatnonzero(pair_ok)
    return PreparedScan(
        ranges_m=rf,
        bearings_rad=b,
        tags=tags,
        segments=seg,
        weights=w,
        good=good,
        pair_a=pa,
        pair_b=pa + 1,
        x_m=x,
        y_m=y,
        dphi_rad=dphi,
        pair_ok=pair_ok,
        pair_w=pair_w,
        normal_x=nx,
        normal_y=ny,
    )


def prepare(scan: Scan, config: PsmConfig, weights: np.ndarray | None = None) -> PreparedScan:
    return prepare_scan(scan.ranges_m, scan.bearings_rad, config, weights)


@dataclass
class _Projection:
    ranges_m: np.ndarray
    good: np.ndarray
    weights: np.ndarray


def project(cur: PreparedScan, ref_bearings_rad: np.ndarray, pose: Pose2D, config: PsmConfig) -> _Projection:
    """Project the current scan, placed at ``pose`` in the reference frame, onto the reference
    bearings: interpolation between consecutive beams of one segment (the ray/chord intersection,
    or the original's range linear in bearing), a z-buffer keeping the nearest range, back-facing
    pairs flagged occluded (they hide what is behind but are not used). Bearings that receive
    nothing are empty (not good). The loop is compiled (:func:`vipsm.psm_kernel.project_into`)."""
    from .psm_kernel import project_into

    n_ref = ref_bearings_rad.size
    out, wout, good = np.empty(n_ref), np.empty(n_ref), np.empty(n_ref, dtype=bool)
    if cur.pair_a.size == 0 or n_ref == 0:
        return _Projection(np.full(n_ref, np.inf), np.zeros(n_ref, dtype=bool), np.zeros(n_ref))
    cos_b, sin_b = cur_cos_sin(ref_bearings_rad)
    project_into(cur.x_m, cur.y_m, cur.pair_ok, cur.pair_w, ref_bearings_rad, cos_b, sin_b,
                 _uniform(ref_bearings_rad), pose.x_m, pose.y_m, pose.theta_rad, config.max_pair_gap_rad,
                 config.line_interpolation, config.min_range_m, config.max_range_m, out, wout, good,
                 np.empty(cur.x_m.size), np.empty(cur.x_m.size), np.empty(cur.x_m.size))
    return _Projection(out, good, wout)


_TRIG_CACHE: dict[tuple[int, float, float], tuple[np.ndarray, np.ndarray]] = {}


def cur_cos_sin(b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin of a bearing table (cached per table)."""
    key = (b.size, float(b[0]), float(b[-1]) if b.size else 0.0)
    hit = _TRIG_CACHE.get(key)
    if hit is None or hit[0].size != b.size:
        if len(_TRIG_CACHE) > 64:
            _TRIG_CACHE.clear()
        hit = (np.cos(b), np.sin(b))
        _TRIG_CACHE[key] = hit
    return hit


_UNIFORM_CACHE: dict[tuple[int, float, float], bool] = {}


def _uniform(b: np.ndarray) -> bool:
    """Whether the bearings are evenly spaced (then projection indexes by arithmetic)."""
    n = b.size
    key = (n, float(b[0]), float(b[-1]))
    hit = _UNIFORM_CACHE.get(key)
    if hit is None:
        if n < 2:
            hit = False
        else:
            lin = np.linspace(b[0], b[-1], n)
            hit = bool(np.max(np.abs(b - lin)) < 1e-6 * abs(b[-1] - b[0]) / n)
        if len(_UNIFORM_CACHE) > 64:
            _UNIFORM_CACHE.clear()
        _UNIFORM_CACHE[key] = hit
    return hit


def _is_corridor(scan: PreparedScan, threshold_rad: float) -> tuple[bool, float]:
    """The original's corridor test: directions between neighbouring points of one segment, folded
    into [0, pi), median-filtered over 3; a corridor when their spread (computed twice, once rotated
    to dodge the wrap) is below the threshold. Returns (is_corridor, corridor_angle_rad)."""
    pa, pb = scan.pair_a, scan.pair_b
    if pa.size < 10:
        return False, 0.0
    ang = np.mod(np.arctan2(scan.y_m[pb] - scan.y_m[pa], scan.x_m[pb] - scan.x_m[pa]), math.pi)
    if ang.size >= 3:
        a0 = np.concatenate((ang[:1], ang[:-1]))
        a2 = np.concatenate((ang[1:], ang[-1:]))
        ang = np.maximum(np.minimum(a0, ang), np.minimum(np.maximum(a0, ang), a2))  # median of 3
    sd1 = float(np.std(ang))
    rot = np.mod(ang + math.radians(36.0), math.pi)
    sd2 = float(np.std(rot))
    if min(sd1, sd2) >= threshold_rad:
        return False, 0.0
    bins = np.minimum((ang * (90.0 / math.pi)).astype(np.intp), 89)
    k = int(np.argmax(np.bincount(bins, minlength=90)))
    return True, float((k + 0.5) * math.pi / 90.0)


def _corridor_from_information(info: Sym2, ratio: float) -> tuple[bool, float]:
    """A corridor when the normal-based translation information along one direction is below
    ``ratio`` times the other; the corridor's axis (reference frame) is that weak direction."""
    lo, hi, vx, vy = _sym2_eig(info)
    if hi <= 0.0:
        return False, 0.0
    if lo < ratio * hi:
        return True, math.atan2(vy, vx)
    return False, 0.0


def _refused(guess: Pose2D, reason: PsmRefusal, iterations: int, beams: int, config: PsmConfig) -> PsmResult:
    cov = np.diag(
        [config.cov_floor_sigma_xy_m**2, config.cov_floor_sigma_xy_m**2, config.cov_floor_sigma_theta_rad**2]
    )
    return PsmResult(
        guess.x_m, guess.y_m, guess.theta_rad, cov, iterations, beams, float("nan"), False, True, reason
    )


@functools.lru_cache(maxsize=32)
def _kernel_params(c: PsmConfig) -> tuple[tuple[float, ...], tuple[int, ...], tuple[bool]]:
    """The configuration as the compiled loop takes it (float, int and bool tuples)."""
    first_gate = c.max_error_first_m if c.max_error_first_m is not None else c.max_error_m
    floats = (c.weight_c_m2, c.max_error_m, first_gate, c.weight_c_divisor, c.max_pair_gap_rad, c.min_range_m,
              c.max_range_m, c.min_overlap_frac, c.orientation_gain, c.stop_translation_m, c.stop_rotation_rad,
              c.degenerate_eig, c.damping)
    ints = (c.change_weight_iter, c.max_iterations, c.stop_count, c.search_window_first_beams,
            c.search_window_beams)
    return tuple(float(v) for v in floats), tuple(int(v) for v in ints), (bool(c.line_interpolation),)


def match_prepared(
    ref: PreparedScan, cur: PreparedScan, initial_guess: Pose2D, config: PsmConfig
) -> PsmResult:
    """Match two prepared scans; never raises for bad data (refusals are typed results)."""
    config = config.for_scan(ref.ranges_m.size, ref.dphi_rad)
    if ref.n_good < max(3, config.min_segment_beams) or cur.n_good < max(3, config.min_segment_beams):
        return _refused(initial_guess, PsmRefusal.EMPTY_SCAN, 0, 0, config)
    from .psm_kernel import DEGENERATE, NO_VALID_SHIFT, TOO_FEW_BEAMS, iterate, match_statistics

    cos_b, sin_b = cur_cos_sin(ref.bearings_rad)
    min_valid = config.required_beams(min(ref.n_usable, cur.n_usable))
    fc, ic, bc = _kernel_params(config)
    x, y, th, it, converged, code, beams, curv_th, c_m2 = iterate(
        ref.ranges_m, ref.good, ref.weights, ref.bearings_rad, cos_b, sin_b, _uniform(ref.bearings_rad),
        ref.dphi_rad, cur.x_m, cur.y_m, cur.pair_ok, cur.pair_w, initial_guess.x_m, initial_guess.y_m,
        initial_guess.theta_rad, fc, ic + (min_valid,), bc)
    if code and not (config.refine_refused and config.refine_iterations > 0):
        reason = {NO_VALID_SHIFT: PsmRefusal.NO_VALID_SHIFT, TOO_FEW_BEAMS: PsmRefusal.TOO_FEW_BEAMS,
                  DEGENERATE: PsmRefusal.DEGENERATE}[code]
        return _refused(initial_guess, reason, it, beams, config)
    if code:  # refused by PSM: refined from the guess instead, accepted if the refinement is
        x, y, th = initial_guess.x_m, initial_guess.y_m, initial_guess.theta_rad
        converged = False
    if config.refine_iterations > 0:
        ok, x, y, th = _refine(ref, cur, x, y, th, min_valid, config)
        if code and not ok:
            return _refused(initial_guess, PsmRefusal.NO_VALID_SHIFT if code == NO_VALID_SHIFT else
                            PsmRefusal.TOO_FEW_BEAMS if code == TOO_FEW_BEAMS else PsmRefusal.DEGENERATE,
                            it, beams, config)
        converged = converged or (ok and bool(code))
    pose = Pose2D(x, y, th)
    proj = project(cur, ref.bearings_rad, pose, config)
    n_used, residual, sw, sigma2, i11, i12, i22 = match_statistics(
        ref.ranges_m, ref.good & (ref.weights > 0.0), ref.weights, cos_b, sin_b, ref.normal_x, ref.normal_y,
        proj.ranges_m, proj.good, proj.weights, c_m2, config.max_error_m)
    if n_used < min_valid:
        return _refused(initial_guess, PsmRefusal.TOO_FEW_BEAMS, it, n_used, config)
    info = (i11, i12, i22)
    var_th = _orientation_variance(curv_th, sigma2, n_used, ref.dphi_rad)
    corridor, corr_angle = _corridor_from_information(info, config.corridor_info_ratio)
    if not corridor and config.corridor_direction_test:
        corridor, corr_angle = _is_corridor(cur, config.corridor_threshold_rad)
    cov = _covariance(info, sw, sigma2, var_th, residual, corridor, corr_angle, config)
    return PsmResult(x, y, th, cov, it, n_used, residual, converged, False, PsmRefusal.NONE, corridor,
                     np.array([[i11, i12], [i12, i22]]), math.sqrt(var_th))


def _refine(ref: PreparedScan, cur: PreparedScan, x: float, y: float, th: float, min_pairs: int, c: PsmConfig
            ) -> tuple[bool, float, float, float]:
    """(accepted, pose) of the point-to-line refinement from (x, y, th); not accepted: the pose given."""
    from .plicp import OK, refine

    window = max(1, math.ceil(c.refine_window_rad / max(abs(ref.dphi_rad), 1e-9)))
    r_ok, c_ok = ref.good & (ref.weights > 0.0), cur.good & (cur.weights > 0.0)
    rx, ry, th2, code, _pairs, _rms, _it = refine(
        ref.x_m, ref.y_m, ref.bearings_rad, _uniform(ref.bearings_rad), r_ok, ref.segments, cur.x_m, cur.y_m,
        c_ok, cur.weights, x, y, th, c.refine_iterations, window, c.refine_max_dist_m,
        c.refine_robust_scale, c.refine_min_scale_m, min_pairs, c.refine_damping, c.degenerate_eig,
        c.stop_translation_m * 0.1, c.stop_rotation_rad * 0.1, c.refine_symmetric, ref.weights, cur.bearings_rad,
        _uniform(cur.bearings_rad), cur.segments)
    if code != OK:
        return False, x, y, th
    return True, rx, ry, th2


def _orientation_variance(curv_th: float, sigma2: float, n_used: int, dphi_rad: float) -> float:
    """The mean-|dr| cost near its minimum is J0 + 0.5 k (dtheta)^2; its noise is about
    sigma / sqrt(n); a cost rise of that size bounds the angle's uncertainty. No curvature: 4 steps."""
    if curv_th > 0.0:
        k_rad = curv_th / (dphi_rad * dphi_rad)
        return 2.0 * math.sqrt(sigma2) / math.sqrt(max(n_used, 1)) / k_rad
    return (4.0 * dphi_rad) ** 2


# 2x2 symmetric matrices as (a11, a12, a22): a few scalar operations, where numpy's small-matrix calls
# would cost more than the whole match of a small scan.
Sym2 = tuple[float, float, float]


def _covariance(info: Sym2, sw: float, sigma2: float, var_th: float, residual_m: float, corridor: bool,
                corridor_angle_rad: float, config: PsmConfig) -> np.ndarray:
    """3x3 covariance, block diagonal: translation from the weighted normal equations
    (sigma^2 (info sw + damping sw I)^-1), orientation from the cost curvature; then
    (``use_cov_floor``) raised to the original's heuristic floor scaled by the residual, stretched
    along a corridor."""
    s = max(sw, 1e-9)
    lam = config.damping * s
    xy = _sym2_scale(_sym2_inv((info[0] * s + lam, info[1] * s, info[2] * s + lam)), sigma2)
    if not (math.isfinite(xy[0]) and math.isfinite(xy[2])):  # singular: no information, the floor's size
        xy = (config.cov_floor_sigma_xy_m**2, 0.0, config.cov_floor_sigma_xy_m**2)
    if config.use_cov_floor:
        factor = max((residual_m - config.cov_error_offset_m) / config.cov_floor_scale_m, 1.0)
        if corridor:
            floor = _sym2_rotated(corridor_angle_rad, config.corridor_sigma_along_m**2,
                                  config.corridor_sigma_across_m**2)
        else:
            floor = (config.cov_floor_sigma_xy_m**2, 0.0, config.cov_floor_sigma_xy_m**2)
        xy = _sym2_loewner_max(_sym2_scale(floor, factor), xy)
        var_th = max(var_th, factor * config.cov_floor_sigma_theta_rad**2)
    return np.array([[xy[0], xy[1], 0.0], [xy[1], xy[2], 0.0], [0.0, 0.0, var_th]])


def _sym2_eig(m: Sym2) -> tuple[float, float, float, float]:
    """(smaller eigenvalue, larger, unit eigenvector (x, y) of the smaller)."""
    a, b, c = m
    mean, half = 0.5 * (a + c), math.hypot(0.5 * (a - c), b)
    lo = mean - half
    if b == 0.0:
        return (a, c, 1.0, 0.0) if a <= c else (c, a, 0.0, 1.0)
    # (A - lo I) v = 0: v is orthogonal to either row; take the longer row for accuracy
    r1, r2 = (a - lo, b), (b, c - lo)
    rx, ry = r1 if math.hypot(*r1) >= math.hypot(*r2) else r2
    n = math.hypot(rx, ry)
    return lo, mean + half, -ry / n, rx / n


def _sym2_inv(m: Sym2) -> Sym2:
    """The inverse; infinite variances when singular."""
    a, b, c = m
    det = a * c - b * b
    if not (det > 0.0 and math.isfinite(det)):
        return (math.inf, 0.0, math.inf)
    return (c / det, -b / det, a / det)


def _sym2_scale(m: Sym2, k: float) -> Sym2:
    return (m[0] * k, m[1] * k, m[2] * k)


def _sym2_rotated(angle_rad: float, along: float, across: float) -> Sym2:
    """R diag(along, across) R^T, R the rotation by ``angle_rad``."""
    ca, sa = math.cos(angle_rad), math.sin(angle_rad)
    return (along * ca * ca + across * sa * sa, (along - across) * ca * sa, along * sa * sa + across * ca * ca)


def _sym2_congruence(v: tuple[float, float], m: Sym2, transpose: bool) -> Sym2:
    """V^T m V (``transpose``) or V m V^T, V = [[vx, -vy], [vy, vx]] (a rotation)."""
    vx, vy = v
    if not transpose:
        vy = -vy
    a, b, c = m
    return (vx * vx * a + 2 * vx * vy * b + vy * vy * c,
            -vx * vy * a + (vx * vx - vy * vy) * b + vx * vy * c,
            vy * vy * a - 2 * vx * vy * b + vx * vx * c)


def _sym2_loewner_max(floor: Sym2, cov: Sym2) -> Sym2:
    """A covariance at least as large as both ``floor`` (positive definite) and ``cov``: whitened by
    the floor, eigenvalues below 1 raised to 1, coloured back."""
    f0, f1, ux, uy = _sym2_eig(floor)
    p = _sym2_congruence((ux, uy), cov, transpose=True)  # cov in the floor's eigenbasis
    m = (p[0] / f0, p[1] / math.sqrt(f0 * f1), p[2] / f1)  # ... whitened
    l0, l1, vx, vy = _sym2_eig(m)
    raised = _sym2_congruence((vx, vy), (max(l0, 1.0), 0.0, max(l1, 1.0)), transpose=False)
    q = (raised[0] * f0, raised[1] * math.sqrt(f0 * f1), raised[2] * f1)
    return _sym2_congruence((ux, uy), q, transpose=False)


def match(
    ref_scan: Scan,
    cur_scan: Scan,
    initial_guess: Pose2D,
    config: PsmConfig | None = None,
    ref_weights: np.ndarray | None = None,
    cur_weights: np.ndarray | None = None,
) -> PsmResult:
    """Match ``cur_scan`` against ``ref_scan`` from ``initial_guess`` (the current laser pose in the
    reference laser frame, e.g. from odometry). Never raises for bad data: a refused result carries
    the guess and the reason."""
    cfg = config or PsmConfig()
    try:  # a bad bearing table or weights of the wrong shape: ValueError from the preprocessing
        ref = prepare(ref_scan, cfg, ref_weights)
        cur = prepare(cur_scan, cfg, cur_weights)
    except ValueError:
        return _refused(initial_guess, PsmRefusal.BAD_INPUT, 0, 0, cfg)
    return match_prepared(ref, cur, initial_guess, cfg)


def warm_up(config: PsmConfig | None = None) -> None:
    """Run one match on a made-up scan, so the compiled kernels are loaded (or, the first time on a
    machine, compiled and cached) before a control loop needs them."""
    b = np.linspace(-2.0, 2.0, 181)
    r = 3.0 + 0.5 * np.sin(3.0 * b)
    scan = Scan(r, b, 0.0)
    cfg = dataclasses.replace(config or PsmConfig(), min_valid_beams=10)  # a whole match on 181 beams
    res = match(scan, scan, Pose2D(0.01, 0.0, 0.0), cfg)
    if res.refused:
        raise RuntimeError(f"the scan matcher's warm-up match was refused ({res.reason.value})")


__all__ = [
    "SCANNER_PRESETS",
    "preset_name_for",
    "PsmConfig",
    "PsmRefusal",
    "PsmResult",
    "PreparedScan",
    "prepare",
    "prepare_scan",
    "project",
    "match",
    "match_prepared",
    "warm_up",
    "median_filter_valid",
    "segment_scan",
    "TAG_INVALID",
    "TAG_RANGE",
    "TAG_MOVING",
    "TAG_SEGMENT",
]
