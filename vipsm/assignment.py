"""Optimal assignment (minimum total cost), for global-nearest-neighbour association.

The Hungarian method with potentials and shortest augmenting paths (Kuhn-Munkres as in Jonker and
Volgenant), O(n^2 m) for n rows and m >= n columns: one row at a time is added, growing a
shortest-path tree over the reduced costs until a free column is reached, then the matching is
flipped along that path. :func:`assign_gated` takes forbidden pairs (outside a gate) as ``inf``: they
are given a cost above every allowed one and dropped from the result (scipy's ``linear_sum_assignment``
gives the same matchings; it is not a dependency of the estimator).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit

#: the cost a forbidden pair is given in :func:`assign_gated`: above every allowed one (the callers' costs
#: are distances in metres)
FORBIDDEN_COST = 1e6


def assign(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of a minimum-cost assignment of ``cost`` (n x m, finite): min(n, m) pairs,
    rows ascending."""
    cost = np.asarray(cost, dtype=np.float64)
    if cost.ndim != 2 or not np.all(np.isfinite(cost)):
        raise ValueError(f"need a finite 2-D cost matrix, got shape {cost.shape}")
    if cost.shape[0] > cost.shape[1]:
        cols, rows = assign(cost.T)
        order = np.argsort(rows)
        return rows[order], cols[order]
    p = _matching(np.ascontiguousarray(cost))
    cols = np.flatnonzero(p[1:])
    rows = p[1:][cols] - 1
    order = np.argsort(rows)
    return rows[order], cols[order]


@njit(cache=True, nogil=True)
def _matching(cost):  # pragma: no cover - compiled
    """Per column (1-based; entry 0 unused) the row (1-based) matched to it, 0 for a free column, of a
    minimum-cost assignment of ``cost`` (n x m, n <= m, finite)."""
    n, m = cost.shape
    u, v = np.zeros(n + 1), np.zeros(m + 1)
    p = np.zeros(m + 1, np.intp)
    way = np.zeros(m + 1, np.intp)
    for i in range(1, n + 1):
        p[0], j0 = i, 0
        minv = np.full(m + 1, np.inf)
        used = np.zeros(m + 1, np.bool_)
        while True:
            used[j0] = True
            i0 = p[j0]
            j1, best = 1, np.inf  # the free column nearest the tree (the first of equals)
            for j in range(1, m + 1):
                if used[j]:
                    continue
                cur = cost[i0 - 1, j - 1] - u[i0] - v[j]
                if cur < minv[j]:
                    minv[j], way[j] = cur, j0
                if minv[j] < best:
                    j1, best = j, minv[j]
            delta = minv[j1]
            for j in range(m + 1):
                if used[j]:
                    u[p[j]] += delta
                    v[j] -= delta
                elif j > 0:
                    minv[j] -= delta
            j0 = j1
            if p[j0] == 0:
                break
        while j0:
            j1 = way[j0]
            p[j0] = p[j1]
            j0 = j1
    return p


def assign_gated(cost: np.ndarray) -> dict[int, int]:
    """Row -> column of a minimum-cost assignment over the allowed pairs of ``cost`` (n x m; ``inf``: not
    allowed, e.g. outside the gate); a row left with no allowed column is not in the result."""
    c = np.where(np.isfinite(cost), cost, FORBIDDEN_COST)
    if c.size == 0:
        return {}
    rows, cols = assign(c)
    return {int(r): int(k) for r, k in zip(rows, cols, strict=True) if c[r, k] < FORBIDDEN_COST}


def greedy_pairs(d: np.ndarray, max_cost: float = np.inf, fits: Callable[[int, int], bool] | None = None,
                 one_set: bool = False) -> list[tuple[int, int]]:
    """Pairs (row, column) of the cost matrix ``d`` taken greedily, cheapest first (ties row by row), each within
    ``max_cost`` and, where given, ``fits(row, column)`` (asked only of a pair whose row and column are both
    free); each row and each column in one pair at most. ``one_set``: rows and columns index the same things
    (each in one pair at most, as a row or a column); a pair not to be made is ``inf`` in ``d``. Unlike
    :func:`assign` not optimal: nearest first, as a tracker's or an evaluation's "nearest pair first"."""
    d = np.asarray(d, dtype=np.float64)
    out: list[tuple[int, int]] = []
    if d.size == 0:
        return out
    used_rows: set[int] = set()
    used_cols = used_rows if one_set else set()
    for flat in np.argsort(d, axis=None, kind="stable"):
        i, j = divmod(int(flat), d.shape[1])
        if not d[i, j] <= max_cost or d[i, j] == np.inf:
            break
        if i not in used_rows and j not in used_cols and (fits is None or fits(i, j)):
            out.append((i, j))
            used_rows.add(i)
            used_cols.add(j)
    return out
