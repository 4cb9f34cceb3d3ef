"""A confirmed track does not re-lock onto the static background beside its body (stage 6's association): a
detection with no motion evidence whose place was held when the laser last saw it (``Detection.held``) and
that lies outside the body's footprint is something else that stood there."""

from __future__ import annotations

import copy
import math
from types import SimpleNamespace

import numpy as np

from vipsm.estimator import _held_before
from vipsm.static_map import FreeSpaceGrid, StaticMapConfig
from vipsm.tracker import Detection, Track, Tracker, TrackerConfig
from vipsm.types import Pose2D, Scan


def _pair(x: float, y: float, evidence: bool = True, held: bool = False) -> Detection:
    return Detection(x, y, 0.25, False, 0, 3, 0.0, 0.1, evidence=evidence, sigma_m=0.06, kind="person", held=held)


def _leg(x: float, y: float, evidence: bool = False, held: bool = False, occluded: bool = False) -> Detection:
    return Detection(x, y, 0.25, False, 0, 3, 0.0, 0.1, evidence=evidence, sigma_m=0.12, kind="leg", held=held,
                     occluded=occluded)


def _slow_walker_then_lone_legs(tr: Tracker) -> float:
    """A walker at 0.35 m/s along +x at y = 2 seen as leg pairs for 2 s, then by two lone legs (its far leg
    hidden): its centre is known only to half a stride, and its covariance grows. Returns the last stamp."""
    for k in range(20):
        tr.step(0.1 * k, [_pair(0.035 * k, 2.0)])
    tr.step(2.0, [_leg(0.70 - 0.22, 2.05)])  # the rear leg, behind the centre
    tr.step(2.1, [_leg(0.735 - 0.20, 1.97, evidence=True)])
    return 2.1


def _piece_ahead(tr: Tracker, t: Track, stamp_s: float) -> tuple[float, float]:
    """A place 0.6 m ahead of the track's prediction: inside its gate grown by the lone legs (checked), beyond
    a person's footprint around the prediction and a pair's width beside its lone legs."""
    ahead = copy.deepcopy(t)
    tr._predict(ahead, stamp_s)  # noqa: SLF001 - the gate the old association gave it
    pred, sigma = ahead.state[:2], math.sqrt(ahead.cov[0, 0] + ahead.cov[1, 1])
    piece = (pred[0] + 0.6, pred[1] + 0.05)
    assert math.hypot(piece[0] - pred[0], piece[1] - pred[1]) < tr.config.gate_m + 2.0 * sigma
    return piece


def test_a_walkers_track_does_not_take_a_static_piece_beside_it_and_is_not_reported_on_it() -> None:
    """The walker of the still real recording's background report: seen by lone legs, its track's gate grew to
    0.66 m; its legs went unseen for a scan and a wall's piece, partly hidden, 0.6 m ahead of its prediction,
    the only detection near, was taken; the walker turned away (its legs seen again, with motion evidence), the
    track went back to the piece, held it for a second and was reported (its report window read the hop as a
    walk). The piece stood there before the walker came (held) and shows no motion: the track coasts over the
    scan instead, follows the walker, never takes the piece, and no track is reported on it."""
    tr = Tracker(TrackerConfig())
    t_s = _slow_walker_then_lone_legs(tr)
    t, = [t for t in tr.tracks if t.track_id == 1]
    assert t.confirmed and t.seen_as_person and t.kind == "leg"
    piece = _piece_ahead(tr, t, t_s + 0.1)
    walker = (float(t.state[0]), float(t.state[1]))
    reported_on_piece = []
    for j in range(1, 12):
        dets = [_leg(*piece, held=True, occluded=True)]
        if j > 1:  # the walker turned away at 0.85 m/s, seen by one leg at a time
            x, y = walker[0] + 0.03 * j, walker[1] - 0.08 * j
            dets.append(_leg(x, y + (0.15 if j % 2 else -0.15), evidence=True))
        for trk, det in tr.step(t_s + 0.1 * j, dets):
            if trk.track_id == 1:
                assert det is None or det.held is False, "the walker's track took the static piece"
            if tr.reported(trk) and math.hypot(trk.state[0] - piece[0], trk.state[1] - piece[1]) < 0.35:
                reported_on_piece.append(trk.track_id)
    assert not reported_on_piece


def test_a_held_detection_where_the_tracks_body_is_is_taken() -> None:
    """Held places inside the body's own footprint may hold the body's own returns (a walker whose legs were
    written into the map before its track masked them, a stance foot): the track takes its own leg pair at its
    prediction after coasting, and a lone leg beside one it took, both held and without motion evidence."""
    tr = Tracker(TrackerConfig())
    for k in range(20):
        tr.step(0.1 * k, [_pair(0.1 * k, 2.0)])
    for j in range(20, 23):  # coasting 0.3 s: the walker moved 0.3 m on from its last detection
        tr.step(0.1 * j, [])
    (t, det), = tr.step(2.3, [_pair(2.3, 2.0, evidence=False, held=True)])
    assert det is not None and det.kind == "person"
    (t, det), = tr.step(2.4, [_leg(2.4 + 0.25, 2.05, held=True)])
    assert det is not None and det.kind == "leg"


def test_a_held_detection_that_shows_motion_is_taken() -> None:
    """Motion evidence (a free-space violation, the camera's flow) outweighs the held place: a body that walked
    into the place where something stood (or stands beside it) is taken as before."""
    tr = Tracker(TrackerConfig())
    t_s = _slow_walker_then_lone_legs(tr)
    t, = [t for t in tr.tracks if t.track_id == 1]
    out = tr.step(t_s + 0.1, [_leg(*_piece_ahead(tr, t, t_s + 0.1), evidence=True, held=True, occluded=True)])
    assert [d for trk, d in out if trk.track_id == 1][0] is not None


def test_an_unconfirmed_track_is_not_judged_by_held_places() -> None:
    """Only a confirmed track is judged: an unconfirmed one is not reported, and its hop onto a static neighbour
    leaves a place that is not vacated, which confirmation refuses."""
    tr = Tracker(TrackerConfig())
    tr.step(0.0, [_leg(0.0, 2.0, evidence=True)])
    out = tr.step(0.1, [_leg(0.3, 2.0, held=True)])
    (t, det), = out
    assert not t.confirmed and det is not None


def test_a_body_on_the_long_seen_background_is_held_and_one_in_seen_free_space_is_not() -> None:
    """The estimator's ``held`` flag (its nearest return where the static map last saw something stand): a
    leg-sized piece of a wall the laser has returned from for a second is held; a body standing in space the
    beams crossed until now is not; a segment without finite returns is not."""
    bearings = np.linspace(-0.5, 0.5, 201)
    wall = np.full(bearings.size, 3.0)
    grid = FreeSpaceGrid(StaticMapConfig())
    for k in range(10):
        grid.integrate(0.1 * k, (0.0, 0.0), 0.0, wall, bearings)
    now = wall.copy()
    now[95:106] = 1.5  # a body in front of the wall, where the beams passed before
    now[150:155] = np.nan
    bodies = [SimpleNamespace(scan_index_start=40, scan_index_stop=46),
              SimpleNamespace(scan_index_start=95, scan_index_stop=106),
              SimpleNamespace(scan_index_start=150, scan_index_stop=155)]
    held = _held_before(grid, Pose2D(0.0, 0.0, 0.0), Scan(now, bearings, 1.0), bodies)
    assert held == [True, False, False]
