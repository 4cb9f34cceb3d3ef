"""Laser pre-filter: drop mixed ("veiling") pixels and lone spurious returns before anything else.

A pulsed time-of-flight scanner whose beam footprint straddles a depth edge returns a range between
the two surfaces (Ye & Borenstein 2002; the UTM-30LX does it too): one or two points floating in free
space beside every edge of a foreground object. They are the classic source of phantom obstacles,
because they stand where the laser saw free space a moment ago. The same filter drops lone returns
(dust, a reflection) with no neighbour on their surface.

The rule (per small island of the scan): a run of at most ``max_island_beams`` consecutive returns
that is separated by a range jump from both neighbours is dropped when it lies strictly between the
two neighbouring surfaces (a mixed pixel), or when it is a single return (nothing real at the
laser's ranges is narrower than one 0.25 deg step and a range jump on both sides). A thin real object
at long range can be lost too; it is never a body the tracker could follow anyway.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PrefilterConfig:
    enabled: bool = True
    #: neighbours further apart than this (or ``jump_range_factor`` x the beam spacing at that range)
    #: are different surfaces
    jump_m: float = 0.10
    jump_range_factor: float = 3.0
    max_island_beams: int = 2


def _islands(valid: np.ndarray, breaks: np.ndarray) -> np.ndarray:
    """Segment id per beam (0 for invalid), a new segment at every break or gap."""
    starts = valid & (breaks | np.concatenate([[True], ~valid[:-1]]))
    ids = np.cumsum(starts)
    return np.where(valid, ids, 0)


def drop_veiling(ranges_m: np.ndarray, bearings_rad: np.ndarray, cfg: PrefilterConfig) -> np.ndarray:
    """A copy of ``ranges_m`` with mixed pixels and lone returns set to NaN."""
    mixed, lone = veiling_masks(ranges_m, bearings_rad, cfg)
    return np.where(mixed | lone, np.nan, np.asarray(ranges_m, dtype=float))


def veiling_masks(ranges_m: np.ndarray, bearings_rad: np.ndarray, cfg: PrefilterConfig
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Per beam: a mixed pixel (an island between two surfaces), a lone return (any other single-beam
    island). Both are dropped before segmentation; a lone return in front of its neighbours can be
    a thin real thing (a chair leg at a few metres), which the static map still needs to see."""
    r = np.asarray(ranges_m, dtype=float)
    n = r.size
    mixed = np.zeros(n, dtype=bool)
    lone = np.zeros(n, dtype=bool)
    if not cfg.enabled or n < 3:
        return mixed, lone
    valid = np.isfinite(r)
    dphi = float(abs(bearings_rad[-1] - bearings_rad[0]) / max(n - 1, 1))
    rr = np.where(valid, r, 0.0)
    thr = np.maximum(cfg.jump_m, cfg.jump_range_factor * rr * dphi)
    breaks = np.zeros(n, dtype=bool)
    breaks[1:] = np.abs(rr[1:] - rr[:-1]) >= thr[1:]
    seg = _islands(valid, breaks)
    ids, first, counts = np.unique(seg, return_index=True, return_counts=True)
    small = (ids > 0) & (counts <= cfg.max_island_beams)
    for i0, cnt in zip(first[small], counts[small], strict=True):
        i1 = i0 + cnt - 1
        left = r[i0 - 1] if i0 > 0 else np.nan
        right = r[i1 + 1] if i1 + 1 < n else np.nan
        if not (np.isfinite(left) or np.isfinite(right)):
            continue  # alone in open space: nothing to compare with
        island = r[i0 : i1 + 1]
        if np.isfinite(left) and np.isfinite(right):
            lo, hi = min(left, right), max(left, right)
            between = bool(np.all((island > lo + thr[i0]) & (island < hi - thr[i0])))
        else:
            between = False
        if between:
            mixed[i0 : i1 + 1] = True
        elif cnt == 1:
            lone[i0] = True
    return mixed, lone
