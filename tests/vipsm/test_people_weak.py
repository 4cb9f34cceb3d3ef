"""Leg candidates below the detector's operating point (``LegDetection.weak``): they continue leg tracks,
weighed by their leg probability; alone they start nothing, two that can be one body's start a person whose
existence then decides (vipsm.people)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.legmodel import default_leg_model
from vipsm.bodies import BodiesConfig
from vipsm.legs import LegConfig
from vipsm.people import LegDetection, PeopleConfig, PeopleTracker, detect_legs, weak_floor
from vipsm.types import Pose2D

from .evidence import bayes_factor


def _pair(x: float, y: float, p: float, weak: bool, gap: float = 0.1) -> list[LegDetection]:
    return [LegDetection(x, y - gap, p, 0, 1, weak=weak), LegDetection(x, y + gap, p, 2, 3, weak=weak)]


def _two_legs_scan(range_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Two legs 0.11 m across, 0.24 m apart, at ``range_m`` before open space, on a 0.25 deg scanner."""
    b = np.radians(np.arange(-90.0, 90.0 + 1e-9, 0.25))
    r = np.full(b.size, np.nan)
    for centre in (-0.12, 0.12):
        r[np.abs(b - math.atan2(centre, range_m)) < math.atan2(0.055, range_m)] = range_m
    return r, b


def test_weak_floor_is_where_a_candidate_says_as_much_as_a_miss() -> None:
    c = PeopleConfig()
    q = weak_floor(c)
    hit = c.p_detect * q / (c.p_clutter * (1.0 - q))
    assert hit == pytest.approx((1.0 - c.p_detect) / (1.0 - c.p_clutter))
    assert 0.0 < q < 0.1


def test_candidates_below_the_operating_point_are_weak_not_dropped() -> None:
    """A leg whose probability lies below the operating point is returned as a weak candidate (with the
    option off, or below the floor, it is dropped as before)."""
    r, b = _two_legs_scan(2.0)
    model = default_leg_model()
    strict = PeopleConfig(LegConfig(threshold=0.99))
    legs = detect_legs(r, b, Pose2D(0.0, 0.0, 0.0), model, strict, BodiesConfig())
    assert len(legs) == 2 and all(g.weak and weak_floor(strict) <= g.p_leg < 0.99 for g in legs)
    assert detect_legs(r, b, Pose2D(0.0, 0.0, 0.0), model, PeopleConfig(LegConfig(threshold=0.99), weak_legs=False),
                       BodiesConfig()) == []
    loose = detect_legs(r, b, Pose2D(0.0, 0.0, 0.0), model, PeopleConfig(LegConfig(threshold=0.05)), BodiesConfig())
    assert len(loose) == 2 and not any(g.weak for g in loose)


def test_a_lone_weak_candidate_starts_no_leg_track_and_no_person() -> None:
    """A single leg-like segment below the operating point is what a post or a table leg gives: nothing."""
    tr = PeopleTracker(PeopleConfig(), default_leg_model())
    for k in range(10):
        tr.step(0.1 * k, [LegDetection(3.0, 0.0, 0.4, 0, 1, weak=True)])
    assert tr.legs == {} and tr.tracks == []


def test_a_pair_of_weak_candidates_starts_a_person_whose_existence_decides() -> None:
    """Two weak candidates within a stride, in no person's gate, start a person (a far person's legs mostly
    score below the operating point): one scored well above the floor is confirmed within a few scans; one
    scored at the floor says no more for a person than a miss, would be dropped at once and is not started.
    The shape of a pair of weak candidates says nothing of a body that moves (even odds), and it stands."""
    c = PeopleConfig()
    confirmed = {}
    for p in (0.35, weak_floor(c) + 1e-3):
        tr = PeopleTracker(c, default_leg_model())
        for k in range(5):
            tr.step(0.1 * k, _pair(7.0, 0.0, p, weak=True))
        confirmed[p] = [q for q in tr.people(0.4) if not q.moving]
        if p == 0.35:
            assert len(tr.tracks) == 1 and len(tr.tracks[0].leg_ids) == 2 and tr.tracks[0].p_dynamic <= 0.5
        else:  # its person would start below ``exist_drop``: not started, and no leg track of it lingers
            assert tr.tracks == [] and tr.legs == {}
    assert len(confirmed[0.35]) == 1 and confirmed[weak_floor(c) + 1e-3] == []


def test_a_weak_pair_in_a_persons_gate_starts_no_second_person() -> None:
    tr = PeopleTracker(PeopleConfig(), default_leg_model())
    tr.step(0.0, [LegDetection(3.0, 0.0, 0.9, 0, 1)])
    tr.step(0.1, [LegDetection(3.0, 0.0, 0.9, 0, 1), *_pair(3.25, 0.3, 0.35, weak=True)])
    assert len(tr.tracks) == 1


def test_a_person_of_weak_candidates_that_walks_is_no_moving_obstacle() -> None:
    """Weak candidates that walk off in a line with motion evidence on their beams (a wall piece and its
    neighbour sliding by as the robot drives) make a person, never a moving one: its motion comes from the
    detector's legs alone."""
    tr = PeopleTracker(PeopleConfig(), default_leg_model())
    for k in range(15):
        tr.step(0.1 * k, [LegDetection(2.0 + 0.1 * k, y, 0.4, 0, 1, evidence=True, weak=True) for y in (-0.1, 0.1)])
        assert not any(t.moving for t in tr.tracks)
    assert len(tr.tracks) == 1 and tr.tracks[0].p_dynamic <= 0.5
    assert tr.obstacles(tr.people(1.4), (), Pose2D(0.0, 0.0, 0.0)) == ()


def test_weak_candidates_keep_a_person_started_by_a_leg() -> None:
    """A far standing person: its legs pass the operating point in one scan, then score just below it. The
    weak candidates continue its leg tracks, and the person is confirmed and kept; without them its leg
    tracks end after ``leg_memory_s`` and the person is never confirmed."""
    out = {}
    for weak_legs in (True, False):
        tr = PeopleTracker(PeopleConfig(weak_legs=weak_legs), default_leg_model())
        tr.step(0.0, _pair(7.0, 0.0, 0.55, weak=False))
        for k in range(1, 20):
            tr.step(0.1 * k, _pair(7.0, 0.0, 0.3, weak=True) if weak_legs else [])
        out[weak_legs] = tr.people(1.9)
    (p,) = out[True]
    assert (p.x_m, p.y_m) == pytest.approx((7.0, 0.0), abs=0.02) and len(p.legs) == 2 and not p.moving
    assert out[False] == ()


def test_a_weak_candidate_never_displaces_a_leg() -> None:
    """A weak candidate nearer a leg track's prediction than a leg does not take the track from the leg; it
    takes a track no leg continued, if one is within reach, and is dropped otherwise."""
    tr = PeopleTracker(PeopleConfig(), default_leg_model())
    tr.step(0.0, [LegDetection(2.0, 0.0, 0.9, 0, 1)])
    (k,) = tr.legs
    tr.step(0.1, [LegDetection(2.02, 0.0, 0.3, 0, 1, weak=True), LegDetection(2.1, 0.0, 0.9, 2, 3)])
    assert tr.legs[k].det is not None and not tr.legs[k].det.weak and tr.legs[k].x_m == pytest.approx(2.1)
    assert len(tr.legs) == 1


def test_weak_candidates_below_the_floor_lose_a_person_faster_than_misses() -> None:
    """Existence weighs each candidate by its leg probability: one just above the floor leaves it about
    where a miss would; candidates that say "leg" (0.4) raise it."""
    c = PeopleConfig()
    ex = {}
    for p in (weak_floor(c) + 1e-6, 0.4):
        tr = PeopleTracker(c, default_leg_model())
        tr.step(0.0, _pair(3.0, 0.0, 0.9, weak=False))
        tr.step(0.1, _pair(3.0, 0.0, 0.9, weak=False))
        start = tr.tracks[0].existence
        tr.step(0.2, _pair(3.0, 0.0, p, weak=True))
        ex[p] = tr.tracks[0].existence / start
    low, high = ex.values()
    assert high > 1.0 > low


def test_weak_candidates_are_no_evidence_that_a_body_moves() -> None:
    """A thing taken for a leg once whose weak candidates then walk off in a line (a wall piece sliding by as
    the robot drives) gains nothing towards "a body that moves": neither their motion evidence nor their
    kinematics count (a weak candidate may be another thing's segment); the same detections as legs do."""
    gain = {}
    for weak in (False, True):
        tr = PeopleTracker(PeopleConfig(), default_leg_model())
        tr.step(0.0, _pair(2.0, 0.0, 0.9, weak=False))
        before = tr.tracks[0].p_dynamic
        for k in range(1, 6):
            tr.step(0.1 * k, _pair(2.0 + 0.1 * k, 0.0, 0.4, weak=weak) if not weak else
                    [LegDetection(2.0 + 0.1 * k, y, 0.4, 0, 1, evidence=True, weak=True) for y in (-0.1, 0.1)])
        gain[weak] = bayes_factor(before, tr.tracks[0].p_dynamic)
    assert gain[False] > 2.0 and gain[True] <= 1.0


def test_a_free_leg_track_is_not_kept_alive_by_weak_candidates() -> None:
    tr = PeopleTracker(PeopleConfig(), default_leg_model())
    tr.step(0.0, [LegDetection(2.0, 0.0, 0.9, 0, 1)])
    tr.tracks = []  # its person gone (dropped or pruned): the leg track belongs to nobody
    tr.step(0.1, [LegDetection(2.0, 0.0, 0.4, 0, 1, weak=True)])
    assert all(lt.det is None for lt in tr.legs.values())


def test_a_moving_person_seen_by_weak_candidates_alone_is_an_obstacle_only_while_it_surely_exists() -> None:
    """Weak candidates alone keep a walker in ``people``; it stays a moving obstacle while its existence stays
    at ``exist_confirm`` or above (they do not make it doubtful), not when it was doubtful already."""
    out = {}
    for doubt in (False, True):
        tr = PeopleTracker(PeopleConfig(), default_leg_model())
        for k in range(15):
            tr.step(0.1 * k, _pair(1.0 + 0.1 * k, 2.0, 0.9, weak=False) if k % 2 else
                    [LegDetection(1.0 + 0.1 * k, y, 0.9, 0, 1, evidence=True) for y in (1.9, 2.1)])
        if doubt:
            tr.tracks[0].existence = 0.3
        tr.step(1.5, _pair(2.5, 2.0, 0.3, weak=True))
        (p,) = tr.people(1.5)
        assert p.moving and len(p.legs) == 2
        out[doubt] = tr.obstacles((p,), (), Pose2D(0.0, 0.0, 0.0))
    assert len(out[False]) == 1 and out[True] == ()


def test_the_daemons_config_file_switches_weak_candidates_off() -> None:
    from app.config import load_config

    assert load_config(None, []).estimator.people.weak_legs
    assert not load_config(None, ["estimator.people.weak_legs=false"]).estimator.people.weak_legs
