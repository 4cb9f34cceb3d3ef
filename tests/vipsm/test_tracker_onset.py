"""Stage 6's motion state: a confirmed track's walk is judged from its filter's last stand (a change point with
hysteresis), so the detections of the stand do not outvote a start, and one detection of a standing person whose
composition changed (a leg paired with a piece beside it) is no walk. Simulated clock: scan stamps only."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from vipsm.tracker import ONSET_STEPS, Detection, Tracker, TrackerConfig


def _det(x: float, y: float, kind: str = "person", evidence: bool = True) -> Detection:
    sigma = {"person": 0.06, "leg": 0.12, "body": 0.03}[kind]
    return Detection(x, y, 0.1 if kind != "body" else 0.25, kind == "body", 0, 3, 0.0, 0.1, evidence=evidence,
                     sigma_m=sigma, sigma_across_m=0.025 if kind == "person" else None, kind=kind)


def _walk_in_and_stop(tr: Tracker, stop_xy: tuple[float, float], period_s: float) -> float:
    """A walker seen as leg pairs at 1 m/s along -y for 2 s, stopping at ``stop_xy``: its track confirmed and
    reported; returns the stamp of the stop."""
    n = round(2.0 / period_s)
    for k in range(n + 1):
        t = k * period_s
        out = tr.step(t, [_det(stop_xy[0], stop_xy[1] + 2.0 - t)])
    assert any(tr.reported(trk) for trk, _ in out)
    return n * period_s


def test_a_standing_person_seen_by_a_lone_leg_then_once_as_a_leg_and_a_piece_is_not_reported() -> None:
    """The traced turn_in_place case (docs/estimator.md stage 6): a person standing at (2.09, -2.12), seen as
    leg pairs and as one lone leg 0.22 m off, then once as that leg paired with a leg-sized piece (the midpoint
    0.29 m off the pelvis), then a lone leg, then nothing for 0.3 s. The old report window read the newest
    midpoints as a walk (0.17 m/s over the window) and the coasting track stayed reported."""
    tr = Tracker(TrackerConfig())
    pelvis, leg, jumped = (2.09, -2.12), (2.23, -1.95), (2.35, -2.24)
    t = _walk_in_and_stop(tr, pelvis, 0.1)
    stand = [pelvis] * 20 + [leg] * 4 + [pelvis] * 5 + [leg] * 4 + [pelvis] * 2 + [leg]
    sequence = [(xy, "person" if xy == pelvis else "leg") for xy in stand] + [(jumped, "person"), (leg, "leg")]
    for k, seen in enumerate(sequence + [None] * 3):
        t = round(t + 0.1, 6)
        out = tr.step(t, [] if seen is None else [_det(*seen[0], kind=seen[1], evidence=False)])
        if k >= 10:  # 1 s after the stop: standing
            assert not any(tr.reported(trk) for trk, _ in out), t


@pytest.mark.parametrize("period_s", [0.1, 0.133])
def test_a_walker_who_stood_2_s_is_reported_two_steps_after_its_filter_starts(period_s: float) -> None:
    """A walker who stood for 2 s, seen as a round body (its legs one segment), starts at 2.2 m/s^2 up to 1.1 m/s
    and is seen as leg pairs (stop_and_go's second start, traced in docs/estimator.md stage 6). Its filter leaves
    the stand once it reaches report_window_speed_mps; the walk counts from the last detection it stood with, and
    two steps from it (two steps define a direction) the track is reported, however many of the report window's
    detections are from the stand. The old window's least-squares speed with an offset per kind, 7-8 of its 10
    detections standing bodies, read the first pairs' displacement as the change of kind and held the report."""
    c = TrackerConfig()
    tr = Tracker(c)
    x0, y0 = 1.0, 0.0
    t_stop = _walk_in_and_stop(tr, (x0, y0), period_s)
    t_start = t_stop + 2.0
    moved_s = reported_s = None
    t = t_stop
    while t < t_start + 1.5 and reported_s is None:
        t = round(t + period_s, 6)
        dt = max(t - t_start, 0.0)
        accel_s = 1.1 / 2.2
        d = 0.5 * 2.2 * min(dt, accel_s) ** 2 + 1.1 * max(dt - accel_s, 0.0)
        out = tr.step(t, [_det(x0, y0 - d, kind="person" if t > t_start else "body", evidence=t > t_start)])
        (trk, _), = out
        if t_stop + 1.0 <= t <= t_start:  # a walker who stops stays reported 0.2-0.5 s
            assert not tr.reported(trk)
        if t > t_start and moved_s is None and trk.speed_mps >= c.report_window_speed_mps:
            moved_s = t
        if t > t_start and tr.reported(trk):
            reported_s = t
    assert moved_s is not None and reported_s is not None
    assert reported_s == pytest.approx(moved_s + (ONSET_STEPS - 1) * period_s, abs=1e-6)


def test_the_traced_second_start_is_reported_at_its_third_leg_pair() -> None:
    """A walker's second start after a stop, as traced in simulation (10.0-11.0 s): the walker stood seen as a
    round body, then walked on seen as leg pairs, the first already 7 cm on. The old window's least-squares
    speed with an offset per kind, 7 of its 10 detections standing bodies, was 0.06 m/s at the third pair (the
    filter's 0.42) and the report waited for the fourth; from the filter's last stand the third pair reports."""
    tr = Tracker(TrackerConfig())
    t = _walk_in_and_stop(tr, (3.94, 0.86), 0.1)
    stand = [(3.94, 0.86, "body")] * 20 + [(3.94, 0.84, "body")]
    walk = [(3.98, 0.80, "person"), (3.98, 0.73, "person"), (3.97, 0.65, "person")]
    for k, (x, y, kind) in enumerate(stand + walk):
        t = round(t + 0.1, 6)
        (trk, _), = tr.step(t, [_det(x, y, kind=kind, evidence=kind == "person")])
        if k >= 10:  # a walker who stops stays reported 0.2-0.5 s
            assert tr.reported(trk) == ((x, y) == walk[-1][:2]), t


def test_a_stand_lasts_two_detections_and_a_walk_from_it_needs_two_steps_of_one_kind() -> None:
    """``Tracker._walk_start`` on report-window rows (stamp, x, y, kind code, radius, view, stood): one row with
    which the filter stood (a walker turning back passes through zero speed, as one in a real recording did at
    9.33 s) is no stand; from two in a row the walk counts from the last, and needs two steps between detections
    of one kind (a lone leg, 1, and a pair's midpoint, 2, are different points of a person)."""
    def rows(kinds: str, stood: str) -> list[tuple[float, ...]]:
        return [(0.1 * i, 0.0, 0.0, float(k), math.nan, math.nan, float(s == "S"))
                for i, (k, s) in enumerate(zip(kinds, stood, strict=True))]
    start = Tracker._walk_start
    assert start(rows("2222222222", "----------")) == 0
    assert start(rows("2222222222", "-------S--")) == 0
    assert start(rows("2222222222", "------SS--")) == 7
    assert start(rows("2222222222", "SSSSSSSS--")) == 7
    assert start(rows("2222222212", "------SS--")) is None  # pair, leg, pair: one step between pairs
    assert start(rows("2222221222", "-----SS---")) == 6  # pair, leg, pair, pair: two
    assert start(rows("2222221212", "-----SS---")) is None  # leg, pair, leg, pair: one step of each
    assert start(rows("2222222222", "-------SS-")) is None  # one step since the stand
    assert start(rows("2222222222", "SSSSSSSSSS")) is None  # standing


def _cart_pushed_to_a_stop() -> Tracker:
    """A tracker that saw a partly hidden cart (a fitted 0.34 m circle) pushed across the view for 2 s, up to
    (4.15, -1.67)."""
    tr = Tracker(TrackerConfig())
    for k in range(20):
        tr.step(0.1 * k, [Detection(4.15, -3.47 + 0.09 * k, 0.34, True, 0, 20, 0.0, 0.1, sigma_m=0.03, kind="body",
                                    occluded=True, behind_rad=math.atan2(-3.47 + 0.09 * k, 4.15 - 3.1))])
    return tr


def test_a_stopped_cart_whose_fit_drifts_beyond_its_radius_change_is_not_reported() -> None:
    """A pushed cart that stopped, as traced in simulation (11.6-12.6 s): the stopped cart's fit shrank 0.34 ->
    0.17 m as the robot drove up and its centre, moved back along the view line by the radius's change, still drifted
    4 cm in 0.2 s. From the filter's stand that read as 0.12 m/s and was reported before the walk had to beat its own
    standard error; now the speed since the stand (0.39 m/s over its three detections) is within one standard error
    (1.0 m/s with the partly hidden fit's noise, half its radius): no walk, with no exception for fitted centres."""
    tr = _cart_pushed_to_a_stop()
    stood = [(4.15, -1.67, 0.34, -0.99)] * 25
    drift = [(4.11, -1.64, 0.30, -1.035), (4.08, -1.62, 0.27, -1.052), (4.05, -1.58, 0.23, -1.067),
             (4.02, -1.55, 0.20, -1.084), (3.99, -1.53, 0.17, -1.10)]
    for k, (x, y, r, view) in enumerate(stood + drift):
        t = round(2.0 + 0.1 * k, 6)
        out = tr.step(t, [Detection(x, y, r, True, 0, 20, 0.0, 0.1, evidence=False, sigma_m=0.03, kind="body",
                                    occluded=True, behind_rad=view)])
        if k >= 10:
            assert not any(tr.reported(trk) for trk, _ in out), t


def test_a_standing_person_seen_by_a_lone_leg_then_by_jittering_pairs_is_not_reported() -> None:
    """A standing person, as traced in a simulated crossing (16.2-17.2 s): its track held one lone leg 0.29 m off
    the pelvis, then took leg pairs 7 cm apart as its seen legs changed. From the filter's stand their speed
    (0.36 m/s over three pairs) is within one standard error of a pair's noise (0.42 m/s): no walk (reported without
    that test); a start's three pairs (0.15 m in 0.2 s) are beyond it."""
    tr = Tracker(TrackerConfig())
    t = 0.0
    for k in range(21):  # walks in seen by one leg
        t = round(0.1 * k, 6)
        tr.step(t, [_det(3.92, 0.11 - 0.1 * k, kind="leg")])
    stand = [(3.92, -1.89, "leg")] * 20
    pairs = [(3.86, -2.13, "person"), (3.87, -2.14, "person"), (3.88, -2.20, "person"), (3.92, -2.17, "person")]
    for k, (x, y, kind) in enumerate(stand + pairs):
        t = round(t + 0.1, 6)
        (trk, _), = tr.step(t, [_det(x, y, kind=kind, evidence=False)])
        if k >= 10:
            assert not tr.reported(trk), t


def test_a_stopped_cart_whose_shrinking_fit_drifts_and_whose_track_takes_two_pairs_is_not_reported() -> None:
    """A pushed cart that stopped, as traced in simulation (12.1-13.1 s): the stopped cart's partly hidden fit shrank
    0.34 -> 0.11 m as the robot drove up, its centre sliding 0.24 m (0.2 m of it the radius's change along the line
    it lies behind its surface on), then the track took two leg pairs of the pusher's legs and the cart 0.3-0.4 m off
    it. From the filter's stand the detections as placed walked off (the fits' 0.3 m/s, a fit's noise half its
    radius), and both views of the window moved: reported at 0.74 m/s, 0.33 m from the standing pusher. With each fit
    moved by its radius's change the fits drift 4 cm in 0.5 s, within one standard error: no walk, as for every other
    test of the window, both views must show it."""
    tr = _cart_pushed_to_a_stop()
    stood = [(4.151, -1.674, 0.344, -0.583)] * 25
    shrink = [(4.115, -1.644, 0.305, -0.641), (4.078, -1.614, 0.265, -0.72), (4.05, -1.584, 0.232, -0.803),
              (4.02, -1.554, 0.197, -0.902), (3.99, -1.526, 0.163, -1.024), (3.971, -1.499, 0.135, -1.133),
              (3.96, -1.474, 0.112, -1.235)]
    fits = [Detection(x, y, r, True, 0, 20, 0.0, 0.1, evidence=True, sigma_m=0.03, kind="body", occluded=True,
                      behind_rad=view) for x, y, r, view in stood + shrink]
    pairs = [Detection(x, y, 0.1, False, 0, 3, 0.0, 0.1, evidence=False, sigma_m=0.06, sigma_across_m=0.025,
                       kind="person", occluded=hidden)
             for x, y, hidden in ((4.103, -1.346, True), (3.935, -1.187, False), (4.11, -1.397, True),
                                  (4.108, -1.397, False), (4.107, -1.399, False))]
    for k, det in enumerate(fits + pairs):
        t = round(2.0 + 0.1 * k, 6)
        out = tr.step(t, [det])
        if k >= 10:
            assert not any(tr.reported(trk) for trk, _ in out), t


def test_a_standing_person_whose_other_leg_is_seen_as_a_leg_sized_fit_is_not_reported() -> None:
    """A person standing at (3.92, 2.15), as traced in simulation (13.0-16.3 s), seen as leg pairs (midpoint 5 cm off
    the pelvis) and as one lone leg 0.28 m off in turn; then a lone leg for 1 s (the filter drifts to it at 0.2 m/s:
    it leaves its stand), three pairs 5 cm apart, the lone leg, and the other leg twice as a leg-sized round body (a
    fit of 0.11 m, 0.23 m off the pelvis on the far side). The newer half's pair midpoints were judged with that fit
    as one of them: the pair to the fit read as 0.23 m in 0.4 s, reported at 0.51 m/s. A pair's midpoint and a fitted
    centre are different points (an offset per kind): they stood."""
    tr = Tracker(TrackerConfig())
    px, py = 3.92, 2.15
    t = _walk_in_and_stop(tr, (px, py - 0.05), 0.1)
    pair, leg, fit = ((0.0, -0.05), "person"), ((-0.10, -0.26), "leg"), ((0.08, 0.21), "body")
    stand = ([pair] * 5 + [leg] * 3 + [pair] * 2 + [leg] * 3) * 2 + [pair] * 3 + [leg] * 10
    tail = [((-0.03, -0.03), "person"), ((0.02, -0.01), "person"), ((0.02, -0.01), "person"), leg, fit, fit,
            ((0.01, -0.01), "person"), ((0.05, 0.21), "body")]
    for k, ((dx, dy), kind) in enumerate(stand + tail):
        t = round(t + 0.1, 6)
        det = _det(px + dx, py + dy, kind=kind, evidence=False)
        if kind == "body":
            det = replace(det, radius_m=0.11)
        (trk, _), = tr.step(t, [det])
        if k >= 10:
            assert not tr.reported(trk), t
