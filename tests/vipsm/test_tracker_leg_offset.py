"""A person's lone leg is measured as the centre plus the leg's offset, a state of the filter (stage 6,
``Tracker._update``): consecutive detections of one standing leg carry the same offset, not a white error."""

from __future__ import annotations

import math

from vipsm.tracker import KIND_CHANGE_M, Detection, Tracker, TrackerConfig


def _pair(x: float, y: float, evidence: bool = True) -> Detection:
    return Detection(x, y, 0.25, False, 0, 3, 0.0, 0.1, evidence=evidence, sigma_m=0.06, kind="person")


def _leg(x: float, y: float, evidence: bool = False) -> Detection:
    return Detection(x, y, 0.25, False, 0, 3, 0.0, 0.1, evidence=evidence, sigma_m=0.12, kind="leg")


def _walk_in_and_stop(tr: Tracker, period_s: float) -> float:
    """A walker along -x at 1 m/s, seen as leg pairs, stops at (1.0, -2.15) and stands 0.5 s seen as pairs
    (as a walker in a simulated crossing did, standing from 10.8 s). Returns the last stamp."""
    t_s = 0.0
    for k in range(20):
        t_s = period_s * k
        x = 1.0 + max(0.0, 1.0 * (1.4 - t_s))
        tr.step(t_s, [_pair(x, -2.15)])
    for _ in range(round(0.5 / period_s)):
        t_s += period_s
        tr.step(t_s, [_pair(1.0, -2.15, evidence=False)])
    return t_s


def test_a_standing_person_seen_by_one_leg_is_not_pulled_onto_it() -> None:
    """A person standing still, its far leg hidden, is seen for a second by its near leg alone, 0.11 m from the
    pair's midpoint. Each detection of that leg carries the same offset from the centre; taken as white noise
    (the leg's share of ``KIND_CHANGE_M``), their mean pulled the filter onto the leg at 0.2 m/s and the track
    was reported as moving for 9 cycles. As an offset of the filter's state, the first detection sets it and
    the next ones add no displacement: the track stands and is never reported, at 10 and 7.5 scans a second."""
    for period_s in (0.1, 0.1333):
        tr = Tracker(TrackerConfig())
        t_s = _walk_in_and_stop(tr, period_s)
        (t,) = tr.tracks
        assert t.confirmed and t.seen_as_person
        for _ in range(round(1.0 / period_s)):
            t_s += period_s
            tr.step(t_s, [_leg(1.02, -2.26)])
            assert t.speed_mps < tr.config.report_min_speed_mps
            assert not tr.reported(t)
        assert math.hypot(t.state[0] - 1.0, t.state[1] + 2.15) < 0.05


def test_a_walker_seen_by_one_leg_at_a_time_is_followed() -> None:
    """A walker at 0.5-1.2 m/s seen as leg pairs, then by its stance leg alone, a step every 0.4 s (the foot
    stands while the body passes over it, landing half a step ahead of the centre, then the other foot a step
    on): a standing leg's offset changes at the body's speed and each new leg's is not the last one's, so the
    track follows the walker within half a step and 0.25 m/s."""
    period_s, step_s = 0.1, 0.4
    for speed in (0.5, 0.8, 1.2):
        tr = Tracker(TrackerConfig())
        for k in range(15):
            tr.step(period_s * k, [_pair(speed * period_s * k, 2.0)])
        (t,) = tr.tracks
        for j in range(15, 40):
            t_s = period_s * j
            n = math.floor(t_s / step_s + 1e-9)
            foot = speed * step_s * (n + 0.5)
            tr.step(t_s, [_leg(foot, 2.0 + (0.1 if n % 2 else -0.1), evidence=True)])
            assert abs(t.state[0] - speed * t_s) < 0.5 * speed * step_s + 0.05
            if j >= 25:
                assert abs(t.speed_mps - speed) < 0.25


def test_the_leg_offset_is_forgotten_at_another_kind_or_another_leg() -> None:
    """The offset state is the lone leg seen last: a standing leg seen again keeps it (its spread stays below
    the prior's), another leg a stride away, or a leg after a pair, starts it afresh (``KIND_CHANGE_M``)."""
    tr = Tracker(TrackerConfig())
    t_s = _walk_in_and_stop(tr, 0.1)
    (t,) = tr.tracks
    tr.step(t_s + 0.1, [_leg(1.02, -2.26)])
    kept = float(t.model_covs[0, 4, 4])
    assert kept < KIND_CHANGE_M**2
    assert tr._same_leg(t, _leg(1.03, -2.25))  # noqa: SLF001
    assert not tr._same_leg(t, _leg(1.04, -2.01))  # noqa: SLF001 - the other leg, 0.25 m off
    tr.step(t_s + 0.2, [_pair(1.0, -2.15, evidence=False)])
    assert not tr._same_leg(t, _leg(1.02, -2.26))  # noqa: SLF001 - after a pair: either leg


def test_a_persons_leg_pair_after_a_lone_leg_measures_the_centre_at_its_own_noise() -> None:
    """A person who stood starts to walk (0 to 1.2 m/s in 0.6 s, a gait initiation) and is seen by a leg pair and
    a lone leg in turn. The pair measures the person's centre, the filter's own point (the lone leg's offset is a
    state of the filter), so it carries the pair's own noise whatever kind was seen before it. Counted as another
    point of the body (half of ``KIND_CHANGE_M`` more) each pair after a leg was discounted, and the filter's speed
    still lagged the walker's by 0.3 m/s 0.4 s after the walker reached it."""
    tr = Tracker(TrackerConfig())
    start_s, ramp_s, speed_mps = 1.0, 0.6, 1.2
    for k in range(30):
        t_s = 0.1 * k
        dt = min(max(t_s - start_s, 0.0), ramp_s)
        x = speed_mps * dt**2 / (2.0 * ramp_s) + speed_mps * max(t_s - start_s - ramp_s, 0.0)
        moving = t_s > start_s
        # the lone leg: the stance foot, a quarter stride ahead of or behind the centre while walking
        foot = 0.15 * (1.0 if k % 4 < 2 else -1.0) if moving else 0.0
        tr.step(t_s, [_pair(x, 2.0, moving) if k % 2 == 0 else _leg(x + foot, 2.1, moving)])
        if t_s >= start_s + ramp_s + 0.4 - 1e-9:
            (t,) = tr.tracks
            assert t.seen_as_person
            assert abs(t.speed_mps - speed_mps) < 0.1, (t_s, t.speed_mps)
