"""Identity on the labelled recordings (app/evaluation/identity.py): people from labelled legs, their
trajectories, and the identity switches of the tracks that stand for them."""

from __future__ import annotations

import numpy as np
import pytest

from app.evaluation.identity import GAP_S, identity_metrics, labelled_people, trajectories

PAIR_M = 0.6


def _walker(n: int, y: float = 0.0, x0: float = 1.0, t0: float = 0.0) -> list[tuple[float, np.ndarray]]:
    """A walker along x at 1 m/s labelled at 10 Hz, both legs labelled 0.2 m apart across."""
    return [(t0 + k * 0.1, np.array([[x0 + 0.1 * k, y - 0.1], [x0 + 0.1 * k, y + 0.1]])) for k in range(n)]


def test_labelled_legs_pair_within_a_stride_and_a_leg_left_over_is_a_person() -> None:
    legs = np.array([[2.0, 0.1], [4.0, 1.0], [2.0, -0.1], [4.5, 1.0], [7.0, 0.0]])
    people = labelled_people(legs, PAIR_M)
    np.testing.assert_allclose(people, [[2.0, 0.0], [4.25, 1.0], [7.0, 0.0]])
    assert labelled_people(np.zeros((0, 2)), PAIR_M).shape == (0, 2)


def test_trajectories_follow_people_and_break_at_a_gap_in_the_labels() -> None:
    labels = _walker(5) + _walker(3, x0=1.5, t0=0.4 + 2 * GAP_S)
    ids = [i for i, _ in trajectories(labels, PAIR_M)]
    assert ids == [[0]] * 5 + [[1]] * 3
    # two people 1 m apart walking side by side stay two trajectories; a leg hidden moves the centre 0.1 m
    two = [(t, np.vstack([a, b if k != 2 else b[:1]])) for k, ((t, a), (_, b)) in
           enumerate(zip(_walker(4), _walker(4, y=1.0), strict=True))]
    assert [sorted(i) for i, _ in trajectories(two, PAIR_M)] == [[0, 1]] * 4


def test_identity_switches_count_changes_of_the_track_along_a_labelled_trajectory() -> None:
    labels = _walker(10)
    xs = [legs[:, 0].mean() for _, legs in labels]
    # track 7 for 4 scans, missed for 2 (no switch: found again under its id), then track 9: one switch
    reports = [[(7, x + 0.05, 0.0)] if k < 4 else [] if k < 6 else [(7, x, 0.0)] if k == 6 else [(9, x, 0.0)]
               for k, x in enumerate(xs)]
    m = identity_metrics(reports, labels, PAIR_M, 0.5, 0.1)
    assert m["id_switches"] == 1 and m["labelled_trajectories"] == 1
    assert m["id_switches_per_min"] == pytest.approx(1 / (10 * 0.1 / 60), rel=1e-3)
    # a report beyond the gate stands for nobody; scans not run (None) count nothing
    far = [[(k, x + 0.6, 0.0)] for k, x in enumerate(xs)]
    assert identity_metrics(far, labels, PAIR_M, 0.5, 0.1)["id_switches"] == 0
    assert identity_metrics([None] * 10, labels, PAIR_M, 0.5, 0.1) == \
        {"id_switches": 0, "id_switches_per_min": None, "labelled_trajectories": 0}


def test_two_people_whose_tracks_swap_are_two_switches() -> None:
    labels = [(t, np.vstack([a, b])) for (t, a), (_, b) in zip(_walker(6), _walker(6, y=1.0), strict=True)]
    reports = []
    for k, (_, legs) in enumerate(labels):
        x = float(legs[0, 0])
        one, two = (1, 2) if k < 3 else (2, 1)
        reports.append([(one, x, 0.0), (two, x, 1.0)])
    assert identity_metrics(reports, labels, PAIR_M, 0.5, 0.1)["id_switches"] == 2
