"""What a scan shows at its depth edges: the same measure for recorded scans and the world's sweeps.

A *surface* is a run of at least ``min_run`` neighbouring returns whose ranges continue one another (the
next range within ``max(k_join * sigma, join_floor_m)`` of the last one, or of the straight line through
the last two: a wall seen obliquely keeps its slope). A *depth edge* is where one surface ends and the
next begins, at most ``max_between`` beams later, with ranges ``gap_m`` >= ``min_gap_m`` apart (a few
noise sigmas at least). The beams between say what the sensor did there:

* ``clean``: none (the next beam is already on the other surface);
* ``mixed``: a return strictly between the two surfaces, more than ``k_mid`` sigma from both and in the
  middle 80 % of the gap (a point floating where nothing is: the mixed pixel);
* ``pulled``: a return between the surfaces but within 10 % of the gap of one of them (one surface's
  echo pulled towards the other's);
* ``no_echo``: no return at all;
* ``other``: returns outside the two surfaces' interval (something small, a spurious return).

Only numpy: the recorded scans (``tools/laser_edges.py``) and the world's sweeps
(``tests/hil_fakes/test_world_realism.py``) go through the same code.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

KINDS = ("mixed", "pulled", "no_echo", "clean", "other")
#: the depth gap bins (m) and the foreground range bins (m) the tables use
GAP_BINS_M = ((0.05, 0.3), (0.3, 1.0), (1.0, float("inf")))
FINE_GAP_BINS_M = ((0.05, 0.15), (0.15, 0.3), (0.3, 0.6), (0.6, 1.0), (1.0, 1.5), (1.5, 2.5), (2.5, float("inf")))
RANGE_BINS_M = ((0.0, 2.0), (2.0, 4.0), (4.0, 8.0), (8.0, float("inf")))


@dataclass(frozen=True)
class EdgeCriteria:
    min_run: int = 3
    max_between: int = 2
    k_join: float = 6.0
    join_floor_m: float = 0.02
    k_mid: float = 3.0
    min_gap_m: float = 0.05

    def __post_init__(self) -> None:
        if self.min_run < 2 or self.max_between < 0:
            raise ValueError(f"EdgeCriteria: min_run must be >= 2 and max_between >= 0, got {self.min_run}, "
                             f"{self.max_between}")
        if min(self.k_join, self.join_floor_m, self.k_mid, self.min_gap_m) < 0.0:
            raise ValueError("EdgeCriteria: thresholds must be >= 0")


@dataclass(frozen=True)
class Edge:
    """One depth edge: the last beam of one surface, the first of the next, their ranges (near, far), the
    kind (one of ``KINDS``) and the between returns' positions as a fraction of the gap (near = 0)."""

    first: int
    last: int
    near_m: float
    far_m: float
    kind: str
    between_t: tuple[float, ...] = ()

    @property
    def gap_m(self) -> float:
        return self.far_m - self.near_m


def surface_runs(ranges_m: np.ndarray, join_m: np.ndarray) -> np.ndarray:
    """Per beam the index of its surface run (-1: no return)."""
    r = np.asarray(ranges_m, float)
    lab = np.full(r.size, -1, dtype=np.int64)
    cur = -1
    for i in range(r.size):
        if not np.isfinite(r[i]):
            continue
        if i > 0 and lab[i - 1] >= 0:
            if abs(r[i] - r[i - 1]) <= join_m[i] or (
                i > 1 and lab[i - 2] == lab[i - 1] and abs(r[i] - 2.0 * r[i - 1] + r[i - 2]) <= join_m[i]
            ):
                lab[i] = lab[i - 1]
                continue
        cur += 1
        lab[i] = cur
    return lab


def _long_runs(lab: np.ndarray, min_run: int) -> list[tuple[int, int]]:
    """(first, last) beam of every run of at least ``min_run`` beams, in scan order."""
    out = []
    i = 0
    while i < lab.size:
        j = i
        while j + 1 < lab.size and lab[j + 1] == lab[i]:
            j += 1
        if lab[i] >= 0 and j - i + 1 >= min_run:
            out.append((i, j))
        i = j + 1
    return out


def classify_edges(ranges_m: np.ndarray, sigma_m: np.ndarray, crit: EdgeCriteria = EdgeCriteria()) -> list[Edge]:
    """The depth edges of one scan (ranges in beam order, NaN = no return; ``sigma_m`` the range noise
    per beam, any value where there is no return)."""
    r = np.asarray(ranges_m, float)
    sig = np.broadcast_to(np.asarray(sigma_m, float), r.shape)
    lab = surface_runs(r, np.maximum(crit.k_join * sig, crit.join_floor_m))
    runs = _long_runs(lab, crit.min_run)
    edges = []
    for (_, a), (b, _) in zip(runs[:-1], runs[1:], strict=True):
        if b - a - 1 > crit.max_between:
            continue
        near, far = sorted((float(r[a]), float(r[b])))
        if far - near < crit.min_gap_m:
            continue
        mid = r[a + 1 : b]
        ret = mid[np.isfinite(mid)]
        t = (ret - near) / (far - near)
        margin = crit.k_mid * max(float(sig[a]), float(sig[b]))
        inside = (ret > near + margin) & (ret < far - margin)
        if mid.size == 0:
            kind = "clean"
        elif ret.size == 0:
            kind = "no_echo"
        elif np.any(inside & (t > 0.1) & (t < 0.9)):
            kind = "mixed"
        elif np.any(inside):
            kind = "pulled"
        else:
            kind = "other"
        edges.append(Edge(a, b, near, far, kind, tuple(round(float(v), 4) for v in t)))
    return edges


def scan_edges(scans: Iterable[np.ndarray], sigma_of: Callable[[np.ndarray], np.ndarray],
               crit: EdgeCriteria = EdgeCriteria()) -> list[Edge]:
    """The depth edges of every scan; ``sigma_of(ranges)`` gives the sensor's noise per beam."""
    out: list[Edge] = []
    for r in scans:
        r = np.asarray(r, float)
        out += classify_edges(r, sigma_of(np.nan_to_num(r, nan=1.0)), crit)
    return out


def rates(edges: list[Edge], gap_bins: Iterable[tuple[float, float]] = GAP_BINS_M,
          range_bins: Iterable[tuple[float, float]] = RANGE_BINS_M) -> dict[str, dict[str, dict[str, float | int]]]:
    """Per gap bin and per foreground range bin: the number of edges and the share of each kind."""
    def one(sel: list[Edge]) -> dict[str, float | int]:
        n = len(sel)
        fig: dict[str, float | int] = {"edges": n}
        for k in KINDS:
            fig[k] = round(sum(e.kind == k for e in sel) / n, 3) if n else 0.0
        return fig

    def key(lo: float, hi: float) -> str:
        return f"{lo:g}-{hi:g}m" if np.isfinite(hi) else f">{lo:g}m"

    return {"by_gap": {key(lo, hi): one([e for e in edges if lo <= e.gap_m < hi]) for lo, hi in gap_bins},
            "by_range": {key(lo, hi): one([e for e in edges if lo <= e.near_m < hi]) for lo, hi in range_bins}}
