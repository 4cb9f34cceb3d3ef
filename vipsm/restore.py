"""Scan restoration (the paper's step 2): cut the scan segments that lie in a visually estimated
obstacle direction and bridge them, so the matcher sees the static scene only.

Pitfalls handled (``shared/protocols/psm.md`` §9.8): the cut works on the *raw* ranges (the
median filter runs afterwards), the bridged beams get weight 0 so they never pull either matching
step, a bridge between two different background surfaces is not drawn (those beams are marked
invalid instead), and a cut covering most of the field of view is refused.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class BearingInterval:
    """A direction interval in which something moves, seen from ``origin`` (a point in the laser
    frame, e.g. the camera's position), bearings in the laser frame (x forward, CCW positive)."""

    bearing_min_rad: float
    bearing_max_rad: float
    origin_x_m: float = 0.0
    origin_y_m: float = 0.0
    source: str = "camera"  # "camera" or "track" (predicted from a tracked obstacle)
    track_id: int = -1
    #: the ranges (from the laser) the moving thing can occupy: a track knows where its body is, so
    #: the wall seen beside or behind it in the same directions is not cut; a camera interval has no range
    range_min_m: float = 0.0
    range_max_m: float = math.inf

    def __post_init__(self) -> None:
        if not self.bearing_min_rad <= self.bearing_max_rad:
            raise ValueError("bearing_min_rad must be <= bearing_max_rad")
        if not 0.0 <= self.range_min_m <= self.range_max_m:
            raise ValueError("need 0 <= range_min_m <= range_max_m")


@dataclass(frozen=True)
class RestoreConfig:
    margin_min_rad: float = math.radians(2.0)  # margin each side of a camera interval
    margin_width_m: float = 0.30  # ... at least the angular half-width of this at the obstacle range
    seg_jump_m: float = 0.20  # segmentation of the raw scan for the obstacle pick
    seg_jump_range_factor: float = 3.0
    min_inside_frac: float = 0.60  # a segment is the obstacle when this share lies in the interval
    min_obstacle_beams: int = 3
    tight_cut: bool = True  # with a body segment found, cut only it (+edge_beams), not the whole interval
    edge_beams: int = 3  # beams either side of a body segment cut with it (mixed edge returns)
    max_body_chord_m: float = 1.5  # a segment wider than this is background, not a body
    bump_m: float = 0.15  # a body merged with a wall segment must stand this much in front of it
    max_cut_fraction: float = 0.50  # refuse when the cut covers more of the valid beams than this
    same_surface_tol_m: float = 0.10  # bridge endpoints must lie on one line within this ...
    same_surface_slope: float = 0.10  # ... plus this share of the gap
    fit_beams: int = 12  # beams each side used to test the background surface


@dataclass(frozen=True)
class ObstacleSegment:
    """Beams [start, stop) of one scan judged to belong to a moving body."""

    start: int
    stop: int
    interval: BearingInterval


@dataclass(frozen=True)
class Restoration:
    ranges_m: np.ndarray  # restored raw ranges (bridged, or NaN where a bridge was refused)
    weights: np.ndarray  # 0 on every cut beam, 1 elsewhere
    cut: tuple[tuple[int, int], ...]  # [start, stop) ranges cut
    obstacles: tuple[ObstacleSegment, ...]
    too_large: bool  # refused: the cut covers most of the view (nothing restored)
    bridge_invalid: bool  # at least one cut was invalidated instead of bridged
    cut_fraction: float


def _segments_raw(r: np.ndarray, valid: np.ndarray, dphi: float, jump: float, k: float) -> np.ndarray:
    n = r.size
    seg = np.zeros(n, dtype=np.int32)
    if n == 0:
        return seg
    rr = np.where(valid, r, 0.0)
    thr = np.maximum(jump, k * rr * dphi)
    brk = np.ones(n, dtype=bool)
    brk[1:] = ~valid[:-1] | (np.abs(rr[1:] - rr[:-1]) >= thr[1:])
    pred = np.zeros(n, dtype=bool)
    pred[2:] = valid[:-2] & valid[1:-1] & (np.abs(rr[2:] - (2 * rr[1:-1] - rr[:-2])) < thr[2:])
    brk &= ~(pred & valid)
    brk[0] = True
    brk &= valid
    ids = np.cumsum(brk).astype(np.int32)
    seg[valid] = ids[valid]
    return seg


def _seen_bearings(interval: BearingInterval, r: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Bearing of each beam's point seen from the interval's origin (beams without a return keep
    their own bearing: parallax unknown)."""
    if interval.origin_x_m == 0.0 and interval.origin_y_m == 0.0:
        return b
    x = r * np.cos(b) - interval.origin_x_m
    y = r * np.sin(b) - interval.origin_y_m
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(r), np.arctan2(y, x), b)


def _beams_in(
    interval: BearingInterval, r: np.ndarray, b: np.ndarray, margin: float, seen: np.ndarray | None = None
) -> np.ndarray:
    """Beams whose point, seen from the interval's origin, lies inside the interval +- margin (and, for
    an interval with a range window, whose return lies in it)."""
    if seen is None:
        seen = _seen_bearings(interval, r, b)
    inside = (seen >= interval.bearing_min_rad - margin) & (seen <= interval.bearing_max_rad + margin)
    if interval.range_min_m > 0.0 or math.isfinite(interval.range_max_m):
        with np.errstate(invalid="ignore"):
            inside &= (r >= interval.range_min_m) & (r <= interval.range_max_m)
    return inside


def _compact_foreground(r: np.ndarray, b: np.ndarray, seg: np.ndarray, s: int, cfg: RestoreConfig) -> bool:
    """A segment no wider than a body that stands in front of what lies beside it."""
    beams = np.flatnonzero(seg == s)
    if beams.size < cfg.min_obstacle_beams:
        return False
    i0, i1 = int(beams[0]), int(beams[-1])
    p0 = (r[i0] * math.cos(b[i0]), r[i0] * math.sin(b[i0]))
    p1 = (r[i1] * math.cos(b[i1]), r[i1] * math.sin(b[i1]))
    if math.hypot(p1[0] - p0[0], p1[1] - p0[1]) > cfg.max_body_chord_m:
        return False
    near = float(np.min(r[beams]))
    for j in (i0 - 1, i1 + 1):
        if 0 <= j < r.size and np.isfinite(r[j]) and r[j] < near + cfg.bump_m:
            return False
    return True


def _same_surface(r: np.ndarray, b: np.ndarray, valid: np.ndarray, lo: int, hi: int, cfg: RestoreConfig) -> bool:
    """Whether the beams just left of ``lo`` and just right of ``hi`` (exclusive) lie on one straight
    surface: the line fitted to each side must pass near the other side's nearest point, within
    ``same_surface_tol_m`` plus ``same_surface_slope`` times the gap (the fitted direction is noisy)."""
    n = r.size
    left = np.arange(max(0, lo - cfg.fit_beams), lo)
    right = np.arange(hi, min(n, hi + cfg.fit_beams))
    left = left[valid[left]]
    right = right[valid[right]]
    if left.size == 0 or right.size == 0:
        return False
    pts = np.stack([r * np.cos(b), r * np.sin(b)], axis=1)
    pl, pr = pts[left], pts[right]
    gap = float(np.hypot(*(pr[0] - pl[-1])))
    tol = cfg.same_surface_tol_m + cfg.same_surface_slope * gap
    if left.size < 3 or right.size < 3:
        return bool(abs(r[left[-1]] - r[right[0]]) < tol)

    def off_line(side: np.ndarray, other: np.ndarray) -> float:
        c = side.mean(axis=0)
        _, _, vt = np.linalg.svd(side - c, full_matrices=False)
        return float(abs((other - c) @ vt[-1]))

    return off_line(pl, pr[0]) < tol and off_line(pr, pl[-1]) < tol


def restore(
    ranges_m: np.ndarray,
    bearings_rad: np.ndarray,
    intervals: list[BearingInterval] | tuple[BearingInterval, ...],
    config: RestoreConfig | None = None,
    min_range_m: float = 0.10,
) -> Restoration:
    """Select, cut and bridge the segments in the given bearing intervals of a raw scan."""
    cfg = config or RestoreConfig()
    r = np.asarray(ranges_m, dtype=np.float64)
    b = np.asarray(bearings_rad, dtype=np.float64)
    n = r.size
    weights = np.ones(n)
    valid = np.isfinite(r) & (r >= min_range_m)
    if n == 0 or not intervals:
        return Restoration(r.copy(), weights, (), (), False, False, 0.0)
    dphi = float(abs(b[-1] - b[0]) / max(n - 1, 1))
    seg = _segments_raw(r, valid, dphi, cfg.seg_jump_m, cfg.seg_jump_range_factor)
    cut_mask = np.zeros(n, dtype=bool)
    obstacles: list[ObstacleSegment] = []
    for iv in intervals:
        obstacles += _cut_interval(iv, r, b, valid, seg, cut_mask, cfg)
    cut_fraction = float(np.count_nonzero(cut_mask & valid)) / max(int(np.count_nonzero(valid)), 1)
    merged = tuple(_merge_obstacles(obstacles))
    if cut_fraction > cfg.max_cut_fraction:
        return Restoration(r.copy(), weights, (), merged, True, False, cut_fraction)
    weights[cut_mask] = 0.0
    out, cuts, bridge_invalid = _bridge(r, b, valid, cut_mask, cfg)
    return Restoration(out, weights, cuts, merged, False, bridge_invalid, cut_fraction)


def _cut_interval(iv: BearingInterval, r: np.ndarray, b: np.ndarray, valid: np.ndarray, seg: np.ndarray,
                  cut_mask: np.ndarray, cfg: RestoreConfig) -> list[ObstacleSegment]:
    """The body segments one interval picks (the segments it touches that lie mostly inside it or
    stand compact in front), marked in ``cut_mask`` with their edge beams; with none identified the
    whole interval plus its margin is cut (the camera bearing is only an estimate)."""
    nseg = int(seg.max()) + 1
    seg_len = np.bincount(seg, minlength=nseg)
    seen = _seen_bearings(iv, r, b)
    core = _beams_in(iv, r, b, 0.0, seen)
    # margin: max(min margin, half-width of margin_width_m at the nearest range in the core)
    near = np.nanmin(np.where(core & valid, r, np.inf)) if np.any(core & valid) else np.inf
    margin = cfg.margin_min_rad
    if math.isfinite(near) and near > 0:
        margin = max(margin, math.atan2(0.5 * cfg.margin_width_m, near))
    wide = _beams_in(iv, r, b, margin, seen)
    inside = np.bincount(seg[wide & valid], minlength=nseg)
    touched = np.flatnonzero(np.bincount(seg[core & valid], minlength=nseg))
    touched = touched[touched > 0]
    chosen = [
        s for s in touched if inside[s] >= cfg.min_inside_frac * seg_len[s] or _compact_foreground(r, b, seg, s, cfg)
    ]
    if not chosen and touched.size and iv.source == "camera":
        cut_mask |= wide
        return _bump_in_core(iv, r, seg, touched, core, wide, cfg)
    out = []
    for s in chosen:
        beams = np.flatnonzero(seg == s)
        if beams.size >= cfg.min_obstacle_beams:
            out.append(ObstacleSegment(int(beams[0]), int(beams[-1]) + 1, iv))
        lo_b = max(int(beams[0]) - cfg.edge_beams, 0)
        hi_b = min(int(beams[-1]) + 1 + cfg.edge_beams, r.size)
        cut_mask[lo_b:hi_b] = True
    if not (out and cfg.tight_cut):
        cut_mask |= wide
    return out


def _bump_in_core(iv: BearingInterval, r: np.ndarray, seg: np.ndarray, touched: np.ndarray, core: np.ndarray,
                  wide: np.ndarray, cfg: RestoreConfig) -> list[ObstacleSegment]:
    """A body merged with a background segment in range: the nearest segment seen in the core
    interval, only its beams inside the core, and only if they stand out in front of that segment's
    beams outside the interval (a bump, not a wall)."""
    rng_of = [float(np.min(r[(seg == s) & core])) for s in touched]
    s_near = int(touched[int(np.argmin(rng_of))])
    beams = np.flatnonzero((seg == s_near) & core)
    outside = (seg == s_near) & ~wide
    bump = outside.any() and float(np.median(r[beams])) < float(np.min(r[outside])) - cfg.bump_m
    if beams.size >= cfg.min_obstacle_beams and bump:
        return [ObstacleSegment(int(beams[0]), int(beams[-1]) + 1, iv)]
    return []


def _merge_obstacles(obstacles: list[ObstacleSegment]) -> list[ObstacleSegment]:
    """One body seen through several intervals (camera and track) is one obstacle: overlaps merged,
    a camera interval preferred as the source."""
    merged: list[ObstacleSegment] = []
    for ob in sorted(obstacles, key=lambda o: (o.start, o.stop)):
        if merged and ob.start < merged[-1].stop:
            last = merged[-1]
            src = last.interval if last.interval.source == "camera" else ob.interval
            merged[-1] = ObstacleSegment(min(last.start, ob.start), max(last.stop, ob.stop), src)
        else:
            merged.append(ob)
    return merged


def _bridge(r: np.ndarray, b: np.ndarray, valid: np.ndarray, cut_mask: np.ndarray,
            cfg: RestoreConfig) -> tuple[np.ndarray, tuple[tuple[int, int], ...], bool]:
    """Each contiguous cut bridged between its two neighbours when they lie on one surface; no return
    (NaN) at the scan's edge, next to no return, or across two surfaces (then ``bridge_invalid``)."""
    out = r.copy()
    n = r.size
    d = np.diff(np.concatenate(([0], cut_mask.astype(np.int8), [0])))
    cuts = tuple((int(lo), int(hi)) for lo, hi in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))
    bridge_invalid = False
    for lo, hi in cuts:
        if lo - 1 < 0 or hi >= n or not valid[lo - 1] or not valid[hi]:
            out[lo:hi] = np.nan  # at the scan edge or next to no return: nothing to bridge from
        elif not _same_surface(r, b, valid, lo, hi, cfg):
            out[lo:hi] = np.nan
            bridge_invalid = True
        else:
            out[lo:hi] = _chord_ranges(r, b, lo - 1, hi, b[lo:hi])
    return out, cuts, bridge_invalid


def _chord_ranges(r: np.ndarray, b: np.ndarray, left: int, right: int, bb: np.ndarray) -> np.ndarray:
    """Linear interpolation between two returns along the straight chord joining them: the range
    where each bearing's ray meets the chord (exact for the flat wall behind)."""
    xl, yl = r[left] * math.cos(b[left]), r[left] * math.sin(b[left])
    xr, yr = r[right] * math.cos(b[right]), r[right] * math.sin(b[right])
    ex, ey = xr - xl, yr - yl
    den = np.cos(bb) * ey - np.sin(bb) * ex
    num = xl * ey - yl * ex
    t = (bb - b[left]) / (b[right] - b[left])
    lin = r[left] + t * (r[right] - r[left])
    with np.errstate(divide="ignore", invalid="ignore"):
        chord = np.where(np.abs(den) > 1e-12, num / den, lin)
    return np.where(np.isfinite(chord) & (chord > 0), chord, lin)
