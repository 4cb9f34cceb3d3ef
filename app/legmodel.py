"""The learned leg detector's model file (``vipsm/data/legs_model.npz``, written by ``tools/train_legs.py``)
read for the estimator, which does no I/O itself (:func:`vipsm.legs.model_from_arrays` checks it), and the
leg-candidate segments of a scan outside the estimator (training and checks; the labelled legs of a
recording: :func:`app.evaluation.real_data.labelled_leg_rows`), and a recorded segment re-seen from
farther (:func:`reseen_farther`: the training's model of how a leg, or anything else, looks from a
longer range) or before a wall with the UTM-30LX's depth edges (:func:`before_wall`: its model of the
other edges a scanner shows beside a segment), or as a URG-04LX-class scanner reports it (:class:`Reporting`:
held ranges, lost edge beams)."""

from __future__ import annotations

import functools
import math
import zipfile
import zlib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from vipsm.bodies import BodiesConfig, segments
from vipsm.legs import LegConfig, LegModel, ModelError, model_from_arrays, segment_features
from vipsm.prefilter import PULLED_SHARE, PrefilterConfig, ramp_masks, veiling_masks


def default_model_path() -> Path:
    return Path(str(resources.files("vipsm") / "data" / "legs_model.npz"))


def load_leg_model(path: str | Path | None = None) -> LegModel:
    """The forest stored at ``path`` (default: the packaged model), read without pickle;
    :class:`vipsm.legs.ModelError` when the file is missing or unusable."""
    path = Path(path) if path is not None else default_model_path()
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:  # absent, not a zip, damaged
        raise ModelError(f"cannot read the leg model {path}: {exc}") from exc
    return model_from_arrays(arrays, f"the leg model {path}")


@functools.lru_cache(maxsize=1)
def default_leg_model() -> LegModel:
    """The packaged model, read once per process (it is immutable)."""
    return load_leg_model()


def leg_candidates(r: np.ndarray, b: np.ndarray) -> tuple[list[tuple[int, int, np.ndarray]], np.ndarray]:
    """The leg-candidate segments of one scan (start, stop, points) and their features, pre-filtered and
    segmented as the estimator does."""
    rr, dropped = prefiltered(r, b)
    return segment_features(rr, b, segments(rr, b, BodiesConfig(), dropped), LegConfig())


def prefiltered(r: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The scan's ranges as the estimator's leg detector sees them, and the beams removed: the pre-filter's
    mixed pixels and lone returns set to NaN, then its ramps of mixed pixels."""
    cfg = PrefilterConfig()
    mixed, lone = veiling_masks(r, b, cfg, ramps=False)
    rr = np.where(mixed | lone, np.nan, r)
    ramps = ramp_masks(rr, b, cfg)
    return np.where(ramps, np.nan, rr), mixed | lone | ramps


# ---------------------------------------------------------------------------------------------
# a real segment re-seen from farther (the training script's augmentation; tests)

#: a re-seen segment is the original's when its centroid lies this close to the moved centroid (the
#: labels' own tolerance, ``app.evaluation.real_data.LABEL_M``)
LEG_MATCH_M = 0.12

#: the laser's range noise (docs/simulation.md: measured on the recorded UTM-30LX frame), 1 sigma
NOISE_NEAR_M = 0.0022
NOISE_PER_RANGE = 0.0007
#: beams of the moved scene the re-seen segment needs on each side: ``vipsm.legs.FRONT_BEAMS``: 4 beams
#: out, and the segmentation and pre-filter one or two beyond that
SIDE_BEAMS = 8


def range_sigma_m(range_m: np.ndarray | float) -> np.ndarray:
    return NOISE_NEAR_M + NOISE_PER_RANGE * np.asarray(range_m, dtype=float)


def moved_surfaces(r: np.ndarray, b: np.ndarray, lo: int, hi: int, shift: np.ndarray) -> list[np.ndarray]:
    """The surfaces the returns of beams [lo, hi) lie on, each a polyline (k x 2, laser frame) moved by
    ``shift`` (x, y). A surface is a segment of the scan (:func:`vipsm.bodies.segments`); each return
    stands for the surface across its beam's width, so a polyline runs half a beam beyond its first and last
    return (a surface of one return is a piece of that width, not a point)."""
    dphi = float(abs(b[-1] - b[0]) / max(b.size - 1, 1))
    rw, bw = r[lo:hi], b[lo:hi]
    out = []
    for a, z in segments(rw, bw, BodiesConfig(), ~np.isfinite(rw)):
        k = a + np.flatnonzero(np.isfinite(rw[a:z]))
        bear = np.concatenate([[bw[k[0]] - 0.5 * dphi], bw[k], [bw[k[-1]] + 0.5 * dphi]])
        rng = np.concatenate([[rw[k[0]]], rw[k], [rw[k[-1]]]])
        out.append(np.stack([rng * np.cos(bear), rng * np.sin(bear)], axis=1) + shift)
    return out


def cast(surfaces: list[np.ndarray], bearings: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Range of the nearest surface along each beam from the origin (NaN: no surface; the scene beyond
    the moved window is unknown, and a gap between two surfaces is where the recording had no echo or
    saw a surface the move now uncovers, which the segmentation treats alike), and where on its polyline
    edge the beam hit it (0-1 from one recorded return to the next)."""
    e = np.stack([np.cos(bearings), np.sin(bearings)], axis=1)[:, None, :]
    out, at = np.full(bearings.size, np.inf), np.zeros(bearings.size)
    for poly in surfaces:
        p, q = poly[:-1][None], poly[1:][None]
        d = q - p
        den = e[..., 0] * d[..., 1] - e[..., 1] * d[..., 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (p[..., 0] * d[..., 1] - p[..., 1] * d[..., 0]) / den
            s = (p[..., 0] * e[..., 1] - p[..., 1] * e[..., 0]) / den
        t = np.where((np.abs(den) > 1e-12) & (s >= 0.0) & (s <= 1.0) & (t > 0.0), t, np.inf)
        j = np.argmin(t, axis=1)
        tj = t[np.arange(bearings.size), j]
        nearer = tj < out
        out = np.where(nearer, tj, out)
        at = np.where(nearer, s[np.arange(bearings.size), j], at)
    return np.where(np.isfinite(out), out, np.nan), at


def reseen_farther(r: np.ndarray, b: np.ndarray, span: tuple[int, int], range_m: float, step_rad: float,
                   rng: np.random.Generator, wall: Wall | None = None, reporting: Reporting | None = None
                   ) -> np.ndarray | None:
    """The leg-candidate features of the segment ``span`` of the pre-filtered scan (r, b) seen from
    ``range_m`` (at least its own range) by a laser with beams every ``step_rad``: the segment and the
    scene beside it moved together away from the laser along the segment's bearing (so what lies behind or
    beside it stays where it was relative to it), the moved surfaces cast with beams at that step (a
    random phase: where the first beam falls on the segment is chance), and the range noise of a return
    from the new range added on top of the recorded one (the difference of variances); with ``wall``, the
    cast scene then stands before a wall (:func:`before_wall`); with ``reporting``, the returns are then
    reported as that scanner class reports them (:meth:`Reporting.apply`: its noise, held ranges, lost
    edge beams, range resolution). None when the re-seen returns are no leg
    candidate there (fewer than ``LegConfig.min_points``, or merged with what lies beside it)."""
    a, z = span
    k = a + np.flatnonzero(np.isfinite(r[a:z]))
    c = np.array([np.mean(r[k] * np.cos(b[k])), np.mean(r[k] * np.sin(b[k]))])
    r0 = float(np.hypot(*c))
    if not range_m >= r0 or step_rad <= 0.0:
        raise ValueError(f"need range_m >= the segment's range {r0:.3f} m and step_rad > 0")
    shift = c / r0 * (range_m - r0)
    dphi = float(abs(b[-1] - b[0]) / max(b.size - 1, 1))
    # enough recorded beams beside it that the moved scene still spans SIDE_BEAMS new beams on each side
    side = int(math.ceil(SIDE_BEAMS * step_rad * range_m / (dphi * r0))) + 2
    lo, hi = max(a - side, 0), min(z + side, r.size)
    surfaces = moved_surfaces(r, b, lo, hi, shift)
    ends = np.concatenate([s[[0, -1]] for s in surfaces])
    ang = np.arctan2(ends[:, 1], ends[:, 0])
    mid = math.atan2(c[1], c[0])
    rel = np.angle(np.exp(1j * (ang - mid)))
    if wall is not None:  # the wall stands beside the segment where the recording saw nothing too
        rel = np.concatenate([rel, [rel.min() - WALL_BEAMS * step_rad, rel.max() + WALL_BEAMS * step_rad]])
    first = mid + (math.floor(rel.min() / step_rad) + rng.uniform(0.0, 1.0)) * step_rad
    bearings = first + step_rad * np.arange(int((rel.max() - rel.min()) / step_rad) + 1)
    ranges, at = cast(surfaces, bearings)
    # a point between two recorded returns keeps (1-s)^2 + s^2 of their noise's variance
    kept_var = range_sigma_m(ranges - (range_m - r0)) ** 2 * ((1.0 - at) ** 2 + at**2)
    extra = np.sqrt(np.maximum(range_sigma_m(ranges) ** 2 - kept_var, 0.0))
    ranges = ranges + rng.standard_normal(ranges.size) * np.nan_to_num(extra)
    if reporting is not None:
        ranges = reporting.apply(ranges, rng)
    if wall is None:
        hit = matched_candidate(ranges, bearings, c + shift)
        return None if hit is None else hit[2]
    return walled_features(ranges, bearings, c + shift, wall, rng)


# ---------------------------------------------------------------------------------------------
# how a URG-04LX-class scanner reports what its beams hit (the training script's augmentation)
#
# The URG-04LX (Hokuyo's data sheet: 0.02-5.6 m, 1024 steps a turn = 0.3516 deg, 1 mm resolution, accuracy
# +-10 mm to 1 m and +-1 % of the range beyond) is an amplitude-modulated phase-shift scanner with a wide
# spot. Two things make its leg at 3-5 m look unlike the recordings' laser's leg there re-cast by
# :func:`reseen_farther` (a smooth arc of 4-6 returns, each with its own few mm of noise): (1) where its
# footprint lies on one surface, neighbouring steps report one and the same range (its phase measurement is
# smoothed over neighbouring steps: a leg's front at 3 m, whose true ranges differ by 1-12 mm, comes out as
# one range over 3-5 steps, with no curvature left); its error is therefore common to neighbouring steps (an
# offset of the surface, which changes a segment's range, not its shape), not a per-beam noise; (2) where
# its footprint straddles a depth edge it reports no echo (an error code) rather than a range, so a leg's
# outermost beams are lost (a 0.1 m leg at 4 m is 3 returns 0.045 m across, not 4-5 over 0.09 m). The
# draws below span the class, from none of it to all of it, not one recording's rates.

#: the URG-04LX's step (1024 a turn) and its longest range
URG04LX_STEP_RAD = 2.0 * math.pi / 1024.0
URG04LX_MAX_RANGE_M = 5.6
#: the data sheet's accuracy beyond 1 m, +-1 % of the range, taken as 2 sigma
URG04LX_SIGMA_PER_RANGE = 0.005
#: two neighbouring returns closer than this in range are one surface to the sensor's smoothing (about 3 sigma
#: of its error at 1.5 m; more than a leg's depth over its front at 3-5 m)
HOLD_TOL_M = 0.02
#: a return beside a jump bigger than this (or no return) is an edge beam (``vipsm.bodies``' jump is 0.15 m)
EDGE_JUMP_M = 0.10
#: the drawn share of same-surface steps that repeat their neighbour's range, and of edge beams lost: the
#: class from none (the recordings' laser) to every one
HOLD_SHARE = (0.0, 1.0)
EDGE_LOSS_SHARE = (0.0, 1.0)


@dataclass(frozen=True)
class Reporting:
    """How a URG-04LX-class scanner reports the ranges its beams hit: one range error common to the
    neighbouring steps (``sigma_per_range`` x range, 1 sigma, drawn once per call), each return on the same
    surface as the one before (within ``HOLD_TOL_M``) repeating that one's reported range with probability
    ``hold_share``, each edge beam (beside a jump over ``EDGE_JUMP_M`` or no return) lost with probability
    ``edge_loss_share``, and ranges rounded to ``resolution_m``."""

    sigma_per_range: float = URG04LX_SIGMA_PER_RANGE
    hold_share: float = 0.5
    edge_loss_share: float = 0.5
    resolution_m: float = 0.001

    def __post_init__(self) -> None:
        if not (self.sigma_per_range >= 0.0 and 0.0 <= self.hold_share <= 1.0 and 0.0 <= self.edge_loss_share <= 1.0
                and self.resolution_m > 0.0):
            raise ValueError(f"need sigma_per_range >= 0, shares in [0, 1] and resolution_m > 0, got {self}")

    @staticmethod
    def drawn(rng: np.random.Generator) -> Reporting:
        """One scanner of the class: its error up to the data sheet's, its holds and edge losses drawn
        uniformly over ``HOLD_SHARE`` / ``EDGE_LOSS_SHARE``."""
        return Reporting(float(rng.uniform(0.0, URG04LX_SIGMA_PER_RANGE)), float(rng.uniform(*HOLD_SHARE)),
                         float(rng.uniform(*EDGE_LOSS_SHARE)))

    def apply(self, ranges: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The cast ``ranges`` (NaN: no return) as this scanner reports them (a new array)."""
        r = np.asarray(ranges, dtype=float)
        fin = np.isfinite(r)
        offset = rng.standard_normal() * self.sigma_per_range * (float(np.median(r[fin])) if fin.any() else 0.0)
        out = r + offset
        for i in range(1, out.size):
            if abs(r[i] - r[i - 1]) < HOLD_TOL_M and rng.uniform() < self.hold_share:  # NaN compares False
                out[i] = out[i - 1]
        prev, nxt = np.concatenate([[np.nan], r[:-1]]), np.concatenate([r[1:], [np.nan]])
        with np.errstate(invalid="ignore"):
            edge = fin & ~((np.abs(r - prev) <= EDGE_JUMP_M) & (np.abs(r - nxt) <= EDGE_JUMP_M))
        out[edge & (rng.uniform(size=r.size) < self.edge_loss_share)] = np.nan
        return np.round(out / self.resolution_m) * self.resolution_m


def matched_candidate(r: np.ndarray, b: np.ndarray, target: np.ndarray) -> tuple[int, int, np.ndarray] | None:
    """The leg candidate of the scan (r, b) whose centroid lies within ``LEG_MATCH_M`` of ``target`` (laser
    frame): (start, stop, features), or None."""
    kept, x = leg_candidates(r, b)
    if not kept:
        return None
    dist = [float(np.hypot(*(pts.mean(axis=0) - target))) for _, _, pts in kept]
    i = int(np.argmin(dist))
    return (kept[i][0], kept[i][1], x[i]) if dist[i] <= LEG_MATCH_M else None


# ---------------------------------------------------------------------------------------------
# a real segment before a wall, with the UTM-30LX's depth edges (the training script's augmentation)
#
# The recordings' laser saw most legs before open space (no return beside them); the UTM-30LX in a room
# sees them before a wall, and at such a depth edge returns a mixed pixel, or the near surface's echo
# pulled towards the far one, at rates measured on the recorded UTM-30LX (``psm_diosi_examples``, 25
# scans, 678 edges: ``PYTHONPATH=. python tools/laser_edges.py --only utm30lx_diosi --fine``; the runs'
# lengths and positions with ``hil_fakes.world.edges.classify_edges`` on the same scans). This is this
# module's own model of those edges (the simulated world's is another), stated in :func:`before_wall`.

#: per depth gap (upper bound, m): the share of edges with a mixed run, and with a pulled return
UTM30LX_EDGE_RATES = ((0.15, 0.62, 0.0), (0.3, 0.83, 0.0), (0.6, 0.80, 0.11), (1.0, 0.69, 0.08),
                      (1.5, 0.19, 0.40), (2.5, 0.02, 0.44), (math.inf, 0.04, 0.36))
#: a mixed run's length, 1 / 2 / 3 beams (118 / 92 / 52 of the recorded runs at edges under 1 m)
MIXED_RUN_SHARES = (0.45, 0.35, 0.20)
#: a mixed return's place in the gap (0: the near surface): the recorded quantiles q10 / q50 / q90 are
#: 0.1-0.3 / 0.33-0.49 / 0.64-0.87 per gap bin, about uniform over the middle 80 %
MIXED_T = (0.1, 0.9)
#: a pulled return is the near surface's echo 2-10 cm behind it (recorded median 4 cm) at 0.54-0.85 of the
#: pulled edges, else the far surface's 3-22 cm before it (median 7 cm)
PULLED_NEAR_SHARE = 0.7
PULLED_NEAR_M = (0.02, 0.10)
PULLED_FAR_M = (0.03, 0.22)
#: beams on each side of the segment the wall fills (``vipsm.legs.FRONT_BEAMS``: 4 out, the pre-filter
#: and the segmentation 2-3 beyond)
WALL_BEAMS = 8


@dataclass(frozen=True)
class Wall:
    """A flat wall ``depth_m`` behind a segment's nearest return (along its bearing), turned by
    ``slant_rad`` (0: square to the beam, |slant| < pi/2)."""

    depth_m: float
    slant_rad: float = 0.0

    def __post_init__(self) -> None:
        if not (self.depth_m > 0.0 and abs(self.slant_rad) < 0.5 * math.pi):
            raise ValueError(f"need depth_m > 0 and |slant_rad| < pi/2, got {self.depth_m}, {self.slant_rad}")


def _edge_rates(gap_m: float) -> tuple[float, float]:
    for upper, mixed, pulled in UTM30LX_EDGE_RATES:
        if gap_m < upper:
            return mixed, pulled
    return UTM30LX_EDGE_RATES[-1][1:]


def before_wall(r: np.ndarray, b: np.ndarray, span: tuple[int, int], wall: Wall, rng: np.random.Generator
                ) -> np.ndarray:
    """The ranges ``r`` (bearings ``b``) with the segment ``span`` standing before ``wall``: on up to
    ``WALL_BEAMS`` beams each side of it, a beam with no return or one beyond the wall returns the wall
    (with the range noise of its range); a nearer return stays (it hides the wall). Then each end of the
    segment that now meets the wall (not a nearer thing) becomes a UTM-30LX depth edge, drawn at the
    recorded rates for its gap g (``UTM30LX_EDGE_RATES``): a *mixed* run of 1-3 beams (``MIXED_RUN_SHARES``)
    at the near range + t g, t uniform over ``MIXED_T`` and rising away from the segment, on the beams
    beyond the segment or, half the time, starting on the segment's own last beam (the beam the footprint
    straddled, which the recordings' laser returned on the leg before open space); or a *pulled* return
    on the first beam beyond (the near echo ``PULLED_NEAR_M`` behind the segment's end, or the wall's
    ``PULLED_FAR_M`` before it); or a clean edge. The segment's inside is not changed."""
    a, z = span
    out = np.array(r, dtype=float)
    k = a + np.flatnonzero(np.isfinite(out[a:z]))
    if k.size == 0:
        return out
    near = float(np.min(out[k]))
    mid = float(np.mean(b[k]))
    foot = (near + wall.depth_m) * math.cos(wall.slant_rad)  # the wall's distance from the laser
    for ends, end in ((np.arange(a - 1, max(a - WALL_BEAMS, 0) - 1, -1), k[0]),
                      (np.arange(z, min(z + WALL_BEAMS, out.size)), k[-1])):
        cos = np.cos(b[ends] - mid - wall.slant_rad)
        wall_m = np.where(cos > 0.05, foot / np.maximum(cos, 0.05), np.inf)
        behind = ~(out[ends] < wall_m)  # no return, or one beyond the wall
        noisy = wall_m + rng.standard_normal(ends.size) * range_sigma_m(np.where(np.isfinite(wall_m), wall_m, 0.0))
        out[ends] = np.where(behind & np.isfinite(wall_m), noisy, out[ends])
        if ends.size and behind[0] and np.isfinite(wall_m[0]):
            _edge(out, end, ends, float(out[end]), float(wall_m[0]), rng)
    return out


def _edge(out: np.ndarray, end: int, ends: np.ndarray, near_m: float, far_m: float, rng: np.random.Generator) -> None:
    """One UTM-30LX depth edge between the segment's last beam ``end`` (range ``near_m``) and the wall
    (``far_m`` on the first beam beyond, ``ends[0]``), drawn at the recorded rates (in place)."""
    gap = far_m - near_m
    if gap <= 0.0:
        return
    p_mixed, p_pulled = _edge_rates(gap)
    u = rng.uniform()
    if u < p_mixed:
        n = int(rng.choice(len(MIXED_RUN_SHARES), p=MIXED_RUN_SHARES)) + 1
        beams = np.concatenate([[end], ends]) if rng.uniform() < 0.5 else ends
        beams = beams[:n]
        out[beams] = near_m + np.sort(rng.uniform(*MIXED_T, size=beams.size)) * gap
    elif u < p_mixed + p_pulled:
        if rng.uniform() < PULLED_NEAR_SHARE:
            out[ends[0]] = near_m + min(rng.uniform(*PULLED_NEAR_M), PULLED_SHARE * gap)
        else:
            out[ends[0]] = far_m - min(rng.uniform(*PULLED_FAR_M), PULLED_SHARE * gap)


def walled_features(r: np.ndarray, b: np.ndarray, target: np.ndarray, wall: Wall, rng: np.random.Generator
                    ) -> np.ndarray | None:
    """The leg-candidate features of the candidate of (r, b) at ``target`` (laser frame) once it stands
    before ``wall`` (:func:`before_wall`); None when it is no candidate before or after (too few returns
    left, or merged with the wall: the estimator would not see it as a leg candidate either)."""
    hit = matched_candidate(r, b, target)
    if hit is None:
        return None
    again = matched_candidate(before_wall(r, b, hit[:2], wall, rng), b, target)
    return None if again is None else again[2]
