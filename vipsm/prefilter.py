"""Laser pre-filter: drop mixed ("veiling") pixels and lone spurious returns before anything else.

A pulsed time-of-flight scanner whose beam footprint straddles a depth edge returns a range between
the two surfaces (Ye & Borenstein 2002; the UTM-30LX does it too): one to three points floating in free
space beside every edge of a foreground object. They are the classic source of phantom obstacles,
because they stand where the laser saw free space a moment ago, and beside a leg they either stick to it
(a tail that is no part of its shape) or join it to the surface behind (one segment too wide for a leg).
The same filter drops lone returns (dust, a reflection) with no neighbour on their surface.

Two rules, per short run of the scan; a beam either rule marks is a mixed pixel:

* *An island between two surfaces*: a run of at most ``max_island_beams`` consecutive returns that is
  separated by a range jump from both neighbours and lies strictly between the two neighbouring
  surfaces; or a single return (nothing real at the laser's ranges is narrower than one 0.25 deg step and
  a range jump on both sides), which is a lone return.
* *A ramp between two surfaces* (the physics of the echo, where the jump is too small for the first rule:
  a leg 0.1-0.6 m before a wall): a run of 1 to ``MAX_RAMP_BEAMS`` returns between two surfaces of
  ``SURFACE_RETURNS`` returns each continuing within ``surface_tol_m`` (or a beam spacing at that range:
  a wall at 45 deg), at least the first rule's jump and at most ``MIXED_GAP_M`` apart in range (and not
  explained by the surfaces' own slopes); every return of the run lies farther than that tolerance from
  both surfaces (from the surface's last return and along its slope) and in the middle 80 % of the gap
  (a footprint on both surfaces: the receiver merges the two echoes into one range between them); a run
  of 2-3 returns rises from one surface towards the other (the footprint slides across the edge). The
  recorded UTM-30LX (``psm_diosi_examples``, 25 scans, ``tools/laser_edges.py``) returns such points at
  0.62-0.83 of its edges 0.05-1 m deep, in runs of 1, 2 and 3 beams (118 / 92 / 52 at its 347 edges under
  1 m; 131 of 143 runs of 2-3 are ramps); of those points (in the middle 80 % of the gap) the first rule
  alone dropped 0 / 0.05 / 0.36 / 0.72 at edges 0.05-0.15 / 0.15-0.3 / 0.3-0.6 / 0.6-1 m deep, both rules
  0.09 / 0.49 / 0.75 / 0.79. A return within 10 % of the gap from one surface is that surface's echo
  pulled by the other's (the recorded edges' "pulled"), kept.

A thin real object at long range can be lost too; it is never a body the tracker could follow anyway.

Where each rule applies (``Estimator``): the island rule to the whole scan (matching, bodies, static map);
the ramp rule to the leg detector's view only (``ramp_masks``, after the island rule). A ramp is also the
mixed pixels along a real body's own edge: dropped from the scan the body stage sees, it splits that body in
two (measured with the ramp rule on the whole scan: a cart detected in fewer cycles, walkers reported moving
while standing; docs/estimator_evidence.md, stage 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

#: the longest run of mixed pixels the ramp rule drops: the recorded UTM-30LX's mixed runs are 1-3 beams
#: long (its footprint straddles an edge for up to three 0.25 deg steps)
MAX_RAMP_BEAMS = 3
#: two surfaces farther apart in range than this give no mixed pixel (a pulsed receiver's two echoes no
#: longer merge): the recorded UTM-30LX mixes at 0.69-0.83 of its edges 0.15-1 m deep, 0.20 at 1-1.5 m and
#: 0.02-0.04 beyond 1.5 m (the recordings' Hokuyo 0.04 beyond 1 m)
MIXED_GAP_M = 1.5
#: a surface beside a ramp is this many returns continuing one another (two could be a sloping wall's
#: noisy or repeated ranges)
SURFACE_RETURNS = 3
#: a ramp's returns lie in the middle of the gap: within this share of it from one surface, a return is
#: that surface's echo pulled towards the other (kept)
PULLED_SHARE = 0.1


@dataclass(frozen=True)
class PrefilterConfig:
    enabled: bool = True
    #: neighbours further apart than this (or ``jump_range_factor`` x the beam spacing at that range)
    #: are different surfaces
    jump_m: float = 0.10
    jump_range_factor: float = 3.0
    max_island_beams: int = 2
    #: two neighbouring returns this close continue one surface; a return farther than this from a
    #: surface is off it (about 4 sigma of the UTM-30LX's range noise at 3 m, 2.2 mm + 0.7 mm/m measured;
    #: 3 sigma of two neighbours' difference at 5 m)
    surface_tol_m: float = 0.02

    def __post_init__(self) -> None:
        if self.jump_m <= 0.0 or self.jump_range_factor < 0.0 or self.max_island_beams < 1:
            raise ValueError(f"PrefilterConfig: need jump_m > 0, jump_range_factor >= 0, max_island_beams >= 1, "
                             f"got {self.jump_m}, {self.jump_range_factor}, {self.max_island_beams}")
        if not self.surface_tol_m > 0.0:
            raise ValueError(f"PrefilterConfig: surface_tol_m must be > 0, got {self.surface_tol_m}")


def drop_veiling(ranges_m: np.ndarray, bearings_rad: np.ndarray, cfg: PrefilterConfig) -> np.ndarray:
    """A copy of ``ranges_m`` with mixed pixels and lone returns set to NaN."""
    mixed, lone = veiling_masks(ranges_m, bearings_rad, cfg)
    return np.where(mixed | lone, np.nan, np.asarray(ranges_m, dtype=float))


def veiling_masks(ranges_m: np.ndarray, bearings_rad: np.ndarray, cfg: PrefilterConfig, ramps: bool = True
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Per beam: a mixed pixel (an island, or with ``ramps`` a ramp, between two surfaces), a lone return
    (any other single-beam island). Both are dropped before segmentation; a lone return in front of its
    neighbours can be a thin real thing (a chair leg at a few metres), which the static map still needs to
    see."""
    r = np.asarray(ranges_m, dtype=float)
    n = r.size
    mixed = np.zeros(n, dtype=bool)
    lone = np.zeros(n, dtype=bool)
    if not cfg.enabled or n < 3:
        return mixed, lone
    mixed, lone = _island_masks(r, _jump_m(r, bearings_rad, cfg), cfg.max_island_beams)
    if ramps:
        mixed |= ramp_masks(r, bearings_rad, cfg)
    return mixed, lone & ~mixed


def _jump_m(r: np.ndarray, bearings_rad: np.ndarray, cfg: PrefilterConfig) -> np.ndarray:
    """The range jump between two different surfaces, per beam."""
    return np.maximum(cfg.jump_m, cfg.jump_range_factor * np.where(np.isfinite(r), r, 0.0) * _step(bearings_rad))


def _step(bearings_rad: np.ndarray) -> float:
    return float(abs(bearings_rad[-1] - bearings_rad[0]) / max(bearings_rad.size - 1, 1))


def ramp_masks(ranges_m: np.ndarray, bearings_rad: np.ndarray, cfg: PrefilterConfig) -> np.ndarray:
    """Per beam: a mixed pixel by the ramp rule (none when the stage is off)."""
    r = np.asarray(ranges_m, dtype=float)
    if not cfg.enabled or r.size < 3:
        return np.zeros(r.size, dtype=bool)
    # a surface continues within the noise, or along a slope of a beam spacing (a wall at 45 deg)
    tol = np.maximum(cfg.surface_tol_m, np.where(np.isfinite(r), r, 0.0) * _step(bearings_rad))
    return ramp_mask(r, tol, _jump_m(r, bearings_rad, cfg))


def _island_masks(r: np.ndarray, thr: np.ndarray, max_island_beams: int) -> tuple[np.ndarray, np.ndarray]:
    """The first rule: islands separated by range jumps of at least ``thr`` (per beam) from both neighbours
    (mixed when strictly between, else lone when single)."""
    own = ("C", "W")  # one compiled signature for every caller
    return _islands_marked(np.require(r, np.float64, own), np.require(thr, np.float64, own), max_island_beams)


@njit(cache=True, nogil=True)
def _islands_marked(r, thr, max_island_beams):  # pragma: no cover - compiled
    """:func:`_island_masks`: walks the runs of returns with no jump of ``thr`` between neighbours."""
    n = r.size
    mixed = np.zeros(n, np.bool_)
    lone = np.zeros(n, np.bool_)
    i = 0
    while i < n:
        if not math.isfinite(r[i]):
            i += 1
            continue
        i0 = i
        i += 1
        while i < n and math.isfinite(r[i]) and not abs(r[i] - r[i - 1]) >= thr[i]:
            i += 1
        i1 = i - 1
        if i - i0 > max_island_beams:
            continue
        left = r[i0 - 1] if i0 > 0 else np.nan
        right = r[i1 + 1] if i1 + 1 < n else np.nan
        if not (math.isfinite(left) or math.isfinite(right)):
            continue  # alone in open space: nothing to compare with
        between = math.isfinite(left) and math.isfinite(right)
        if between:
            lo, hi = min(left, right), max(left, right)
            for k in range(i0, i1 + 1):
                if not (r[k] > lo + thr[i0] and r[k] < hi - thr[i0]):
                    between = False
        if between:
            mixed[i0 : i1 + 1] = True
        elif i0 == i1:
            lone[i0] = True
    return mixed, lone


def ramp_mask(ranges_m: np.ndarray, tol_m: np.ndarray | float, min_gap_m: np.ndarray | float) -> np.ndarray:
    """The second rule: per beam, whether it belongs to a run of 1 to ``MAX_RAMP_BEAMS`` returns between
    two surfaces of ``SURFACE_RETURNS`` returns each, at least ``min_gap_m`` apart in range; neighbouring
    returns within ``tol_m`` continue one surface (both per beam, or one value; see the module's docstring;
    NaN is no return, and breaks a surface)."""
    r = np.asarray(ranges_m, dtype=float)
    n = r.size
    tol = np.broadcast_to(np.asarray(tol_m, dtype=float), r.shape)
    gaps = np.broadcast_to(np.asarray(min_gap_m, dtype=float), r.shape)
    out = np.zeros(n, dtype=bool)
    m = SURFACE_RETURNS - 1  # steps within a surface
    if n < 2 * SURFACE_RETURNS + 1:
        return out
    with np.errstate(invalid="ignore"):
        cont = np.abs(np.diff(r)) <= tol[1:]  # cont[i]: returns i and i+1 continue one surface
    # surf[i]: returns i .. i + m continue one surface
    surf = np.ones(n - m, dtype=bool)
    for j in range(m):
        surf &= cont[j : j + n - m]
    # a run may start at i0 where a surface ends at i0 - 1 and i0 leaves it
    starts = np.flatnonzero(surf[: n - m - 1] & ~cont[m : n - 1]) + SURFACE_RETURNS
    own = ("C", "W")  # one compiled signature for every caller (read-only scans, broadcast values)
    _mark_ramps(np.require(r, np.float64, own), np.require(tol, np.float64, own), np.require(gaps, np.float64, own),
                surf, starts, out)
    return out


@njit(cache=True, nogil=True)
def _mark_ramps(r, tol, gaps, surf, starts, out):  # pragma: no cover - compiled
    """Marks in ``out`` the shortest ramp (1 to ``MAX_RAMP_BEAMS`` beams) starting at each of ``starts``
    that reaches a surface (``surf``) and passes :func:`_is_ramp`."""
    n = r.size
    for i0 in starts:
        for k in range(1, MAX_RAMP_BEAMS + 1):
            i1 = i0 + k - 1  # the run's last beam; the far surface starts at i1 + 1
            if i1 + SURFACE_RETURNS >= n or not surf[i1 + 1]:
                continue
            if _is_ramp(r, i0, i1 + 1, tol[i0], gaps[i0]):
                out[i0 : i1 + 1] = True
                break


@njit(cache=True, nogil=True)
def _is_ramp(r, i0, i1, tol_m, min_gap_m):  # pragma: no cover - compiled
    """The run ``r[i0:i1]`` lies between the two surfaces (the two returns before it, the two after it),
    off both by more than ``tol_m`` (from the surface's nearest return and from its line through its two
    returns: a sloping surface is followed along its slope), within the gap's middle (``PULLED_SHARE``
    to 1 - it), in order from one surface to the other."""
    far_l, near_l, near_r, far_r = r[i0 - 2], r[i0 - 1], r[i1], r[i1 + 1]
    size = i1 - i0
    lo, hi = min(near_l, near_r), max(near_l, near_r)
    gap = hi - lo
    # the step the two surfaces' own slopes do not explain (a sloping wall's noisy steps are none)
    slope = 0.5 * ((near_l - far_l) + (far_r - near_r))
    step = abs(near_r - near_l - (size + 1) * slope)
    if not np.all(np.isfinite(r[i0:i1])) or min(gap, step) < max(min_gap_m, 2.0 * tol_m) or gap > MIXED_GAP_M:
        return False
    rising = np.sign(near_r - near_l)
    for j in range(size):
        x = r[i0 + j]
        on_left = abs(x - (near_l + (j + 1) * (near_l - far_l))) <= tol_m
        on_right = abs(x - (near_r - (size - j) * (far_r - near_r))) <= tol_m
        t = (x - lo) / gap
        inside = x > lo + tol_m and x < hi - tol_m and t > PULLED_SHARE and t < 1.0 - PULLED_SHARE
        if not inside or on_left or on_right or (j > 0 and not (x - r[i0 + j - 1]) * rising > 0.0):
            return False
    return True
