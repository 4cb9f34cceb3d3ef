"""Identity on the labelled real recordings: how often the track that stands for a labelled person changes.

The labels place legs, not people, and carry no identity. So:

* **labelled people** per scan (:func:`labelled_people`): the labelled legs paired nearest first while two lie
  within ``pair_m`` of each other (a stride: one person's two legs), each pair's midpoint a person; a leg left
  over is a person seen by one leg (its other leg hidden), placed at that leg;
* **labelled trajectories** (:func:`trajectories`): each labelled person continued from the scan before by the
  nearest person there within ``LINK_M`` (one to one, nearest pair first), else a new trajectory; a gap in the
  labels longer than ``GAP_S`` ends every trajectory (who is who across it is not labelled);
* **identity switches** (:func:`identity_metrics`): each scan, the labelled people and the reports (track id,
  x, y) assigned one to one, nearest pair first, within ``gate_m``; along a trajectory, how often the assigned
  report has another track id than the one before it (the CLEAR MOT metrics' ID switches, Bernardin and
  Stiefelhagen 2008, as the simulated scenes count them: ``person_metrics``). A scan with no report in the gate
  counts nothing: a person lost and found again under the same id is no switch.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from vipsm.assignment import greedy_pairs

#: a labelled person's centre moves less than this between two labelled scans: a walker at 1.5 m/s over two
#: scans at 7.5 Hz (0.2 m) plus the half stride the centre jumps when one leg hides or shows again
LINK_M = 0.5
#: labelled scans further apart than this break every trajectory
GAP_S = 0.5


def _distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1])


def _nearest_pairs(a: np.ndarray, b: np.ndarray, max_m: float) -> list[tuple[int, int]]:
    """One-to-one pairs (i of ``a``, j of ``b``), nearest first, each within ``max_m``."""
    return greedy_pairs(_distances(a, b), max_m)


def labelled_people(legs: np.ndarray, pair_m: float) -> np.ndarray:
    """(k, 2) people from one scan's labelled ``legs``: pairs within ``pair_m`` (nearest first) at their
    midpoints, then each leg left over."""
    legs = np.asarray(legs, float).reshape(-1, 2)
    d = _distances(legs, legs)
    d[np.tril_indices(len(legs))] = np.inf
    pairs = greedy_pairs(d, pair_m, one_set=True)
    paired = {k for pair in pairs for k in pair}
    people = [(legs[i] + legs[j]) / 2.0 for i, j in pairs] + [legs[i] for i in range(len(legs)) if i not in paired]
    return np.array(people, float).reshape(-1, 2)


def trajectories(labels: Sequence[tuple[float, np.ndarray]], pair_m: float) -> list[tuple[list[int], np.ndarray]]:
    """Per labelled scan: the trajectory index of each labelled person and the people (:func:`labelled_people`)."""
    out: list[tuple[list[int], np.ndarray]] = []
    prev_t, prev_ids, prev_xy = -math.inf, [], np.zeros((0, 2))
    next_id = 0
    for t, legs in labels:
        xy = labelled_people(legs, pair_m)
        ids = [-1] * len(xy)
        if t - prev_t <= GAP_S:
            for i, j in _nearest_pairs(xy, prev_xy, LINK_M):
                ids[i] = prev_ids[j]
        for i in range(len(ids)):
            if ids[i] < 0:
                ids[i], next_id = next_id, next_id + 1
        out.append((ids, xy))
        prev_t, prev_ids, prev_xy = t, ids, xy
    return out


def identity_metrics(reports_by_scan: Sequence[Sequence[tuple[int, float, float]] | None],
                     labels: Sequence[tuple[float, np.ndarray]], pair_m: float, gate_m: float,
                     period_s: float) -> dict[str, Any]:
    """``id_switches`` of the reports (track id, x, y) per labelled scan (None: the scan was not run) along the
    labelled trajectories, ``id_switches_per_min`` (per minute of the labelled scans run) and
    ``labelled_trajectories`` (those with at least one located scan)."""
    last: dict[int, int] = {}
    switches = scans = 0
    for (ids, xy), reports in zip(trajectories(labels, pair_m), reports_by_scan, strict=True):
        if reports is None:
            continue
        scans += 1
        pts = np.array([[x, y] for _, x, y in reports], float).reshape(-1, 2)
        for i, j in _nearest_pairs(xy, pts, gate_m):
            track = int(reports[j][0])
            switches += ids[i] in last and last[ids[i]] != track
            last[ids[i]] = track
    minutes = scans * period_s / 60.0
    return {"id_switches": switches,
            "id_switches_per_min": round(switches / minutes, 2) if minutes > 0 else None,
            "labelled_trajectories": len(last)}
