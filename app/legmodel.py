"""The learned leg detector's model file (``vipsm/data/legs_model.npz``, written by ``tools/train_legs.py``)
read for the estimator, which does no I/O itself (:func:`vipsm.legs.model_from_arrays` checks it), and the
leg-candidate segments of a scan outside the estimator (training and checks; the labelled legs of a
recording: :func:`app.evaluation.real_data.labelled_leg_rows`), and a recorded segment re-seen from
farther (:func:`reseen_farther`: the training's model of how a leg, or anything else, looks from a
longer range)."""

from __future__ import annotations

import functools
import math
import zipfile
import zlib
from importlib import resources
from pathlib import Path

import numpy as np

from vipsm.bodies import BodiesConfig, segments
from vipsm.legs import LegConfig, LegModel, ModelError, model_from_arrays, segment_features
from vipsm.prefilter import PrefilterConfig, veiling_masks


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
    """The scan's ranges with the pre-filter's mixed pixels and lone returns set to NaN, and those beams."""
    mixed, lone = veiling_masks(r, b, PrefilterConfig())
    dropped = mixed | lone
    return np.where(dropped, np.nan, r), dropped


# ---------------------------------------------------------------------------------------------
# a real segment re-seen from farther (the training script's augmentation; tests)

#: a re-seen segment is the original's when its centroid lies this close to the moved centroid (the
#: labels' own tolerance, ``app.evaluation.real_data.LABEL_M``)
LEG_MATCH_M = 0.12

#: the laser's range noise (docs/simulation.md: measured on the recorded UTM-30LX frame), 1 sigma
NOISE_NEAR_M = 0.0022
NOISE_PER_RANGE = 0.0007
#: beams of the moved scene the re-seen segment needs on each side: ``vipsm.legs.front_of`` looks 4 beams
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
                   rng: np.random.Generator) -> np.ndarray | None:
    """The leg-candidate features of the segment ``span`` of the pre-filtered scan (r, b) seen from
    ``range_m`` (at least its own range) by a laser with beams every ``step_rad``: the segment and the
    scene beside it moved together away from the laser along the segment's bearing (so what lies behind or
    beside it stays where it was relative to it), the moved surfaces cast with beams at that step (a
    random phase: where the first beam falls on the segment is chance), and the range noise of a return
    from the new range added on top of the recorded one (the difference of variances). None when the
    re-seen returns are no leg candidate there (fewer than ``LegConfig.min_points``, or merged with what
    lies beside it)."""
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
    first = mid + (math.floor(rel.min() / step_rad) + rng.uniform(0.0, 1.0)) * step_rad
    bearings = first + step_rad * np.arange(int((rel.max() - rel.min()) / step_rad) + 1)
    ranges, at = cast(surfaces, bearings)
    # a point between two recorded returns keeps (1-s)^2 + s^2 of their noise's variance
    kept_var = range_sigma_m(ranges - (range_m - r0)) ** 2 * ((1.0 - at) ** 2 + at**2)
    extra = np.sqrt(np.maximum(range_sigma_m(ranges) ** 2 - kept_var, 0.0))
    ranges = ranges + rng.standard_normal(ranges.size) * np.nan_to_num(extra)
    kept, x = leg_candidates(ranges, bearings)
    if not kept:
        return None
    target = c + shift
    dist = [float(np.hypot(*(pts.mean(axis=0) - target))) for _, _, pts in kept]
    i = int(np.argmin(dist))
    return x[i] if dist[i] <= LEG_MATCH_M else None
