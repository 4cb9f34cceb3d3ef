"""One obstacle id per person across the body tracker and the people stage (vipsm/identity.py)."""

import pytest

from vipsm.identity import ObstacleIdentity
from vipsm.types import Obstacle

P = 1 << 20  # a people-stage track id


def ob(tid: int, x: float = 0.0) -> Obstacle:
    return Obstacle(tid, x, 0.0, 1.0, 0.0, 0.25, 0.0, 0.1, -1, -1)


def ids(out: tuple[Obstacle, ...]) -> list[int]:
    return [o.track_id for o in out]


def test_a_walker_lost_and_found_by_the_body_tracker_keeps_one_id() -> None:
    idn = ObstacleIdentity(0.25)
    # body track 3 reported, person P stands for it
    assert ids(idn.relabel((ob(3),), (), {3: (P, 0.05)}, {3}, {P})) == [3]
    # body track 3 lost: the person is reported itself, under the body's id
    assert ids(idn.relabel((), (ob(P),), {}, {3}, {P})) == [3]
    # a new body track 5 found on the walker, the person standing for it: the same id
    assert ids(idn.relabel((ob(5),), (), {5: (P, 0.1)}, {5}, {P})) == [3]
    assert ids(idn.relabel((ob(5),), (), {}, {5}, {P})) == [3]  # kept for the track's life


def test_a_person_reported_first_gives_its_id_to_the_body_found_on_it() -> None:
    idn = ObstacleIdentity(0.25)
    assert ids(idn.relabel((), (ob(P),), {}, set(), {P})) == [P]
    assert ids(idn.relabel((ob(7),), (), {7: (P, 0.02)}, {7}, {P})) == [P]


def test_a_person_further_than_a_body_radius_passes_no_id() -> None:
    """A second walker linked for a cycle to the body tracker's walker (a leg pair's reach) is not it."""
    idn = ObstacleIdentity(0.25)
    assert ids(idn.relabel((ob(7),), (), {7: (P, 0.6)}, {7}, {P})) == [7]
    assert ids(idn.relabel((ob(7),), (ob(P),), {}, {7}, {P})) == [7, P]


def test_a_body_keeps_the_id_of_its_first_report() -> None:
    idn = ObstacleIdentity(0.25)
    assert ids(idn.relabel((ob(4),), (), {}, {4}, {P})) == [4]
    assert ids(idn.relabel((ob(4),), (), {4: (P, 0.0)}, {4}, {P})) == [4]  # the person takes 4 ...
    assert ids(idn.relabel((), (ob(P),), {}, {4}, {P})) == [4]  # ... and carries it


def test_a_body_reports_the_id_of_the_person_standing_for_it_now() -> None:
    """The body tracker's track may hold one walker, then another passing close (positive_3: its one body track
    took a first walker's id and went on to stand for a second, whose reports then alternated between the body's
    id and the second person's own, 11 identity switches along the labelled walker): the person standing for it
    is the longer-lived identity, so a body reports that person's id whenever one with an id stands for it,
    and keeps the last one it reported otherwise."""
    idn = ObstacleIdentity(0.25)
    a, b = P, P + 1
    idn.relabel((), (ob(a), ob(b, 3.0)), {}, set(), {a, b})  # both people reported themselves
    assert ids(idn.relabel((ob(6),), (ob(b, 3.0),), {6: (a, 0.1)}, {6}, {a, b})) == [a, b]
    assert ids(idn.relabel((ob(6),), (ob(a, 3.0),), {6: (b, 0.1)}, {6}, {a, b})) == [b, a]  # before: [a, 6]
    assert ids(idn.relabel((ob(6),), (), {}, {6}, {a, b})) == [b]


def test_no_id_is_given_twice_in_one_cycle() -> None:
    idn = ObstacleIdentity(0.25)
    idn.relabel((ob(3),), (), {3: (P, 0.0)}, {3}, {P})
    # body 3 still reported while a new body 5 on the person takes the person's id (3): 5 keeps its own
    out = idn.relabel((ob(3), ob(5)), (), {5: (P, 0.0)}, {3, 5}, {P})
    assert ids(out) == [3, 5]
    # the person reported beside its own body 3 (linked elsewhere this cycle): each id once
    out = idn.relabel((ob(3),), (ob(P),), {}, {3, 5}, {P})
    assert len(set(ids(out))) == 2


def test_entries_of_ended_tracks_are_dropped() -> None:
    idn = ObstacleIdentity(0.25)
    idn.relabel((ob(3),), (), {3: (P, 0.0)}, {3}, {P})
    idn.relabel((), (), {}, set(), set())
    assert not idn._body and not idn._person
    # a person id reused after its end starts afresh
    assert ids(idn.relabel((), (ob(P),), {}, set(), {P})) == [P]


def test_positions_are_unchanged() -> None:
    idn = ObstacleIdentity(0.25)
    idn.relabel((ob(3, 1.0),), (), {3: (P, 0.0)}, {3}, {P})
    (o,) = idn.relabel((), (ob(P, 2.5),), {}, {3}, {P})
    assert (o.track_id, o.x_m, o.vx_mps) == (3, 2.5, 1.0)


def test_bad_radius_is_refused() -> None:
    with pytest.raises(ValueError, match="same_m"):
        ObstacleIdentity(0.0)


def mover(tid: int, x: float, y: float, vx: float, vy: float) -> Obstacle:
    return Obstacle(tid, x, y, vx, vy, 0.25, 0.0, 0.1, -1, -1)


def stitcher() -> ObstacleIdentity:
    return ObstacleIdentity(0.25, gap_s=1.0, speed_mps=2.5, step_m=0.1)


def test_a_walker_dropped_and_found_again_within_its_reach_keeps_its_id() -> None:
    """The body tracker dropped a walker missed for a scan (its beams passed through the walker's centre)
    and started it afresh 0.7 s later, 0.35 m on, walking on: one id."""
    idn = stitcher()
    assert ids(idn.relabel((mover(40, 3.2, 0.4, 0.0, -0.5),), (), {}, {40}, set(), 10.0)) == [40]
    assert ids(idn.relabel((), (), {}, set(), set(), 10.3)) == []  # dropped
    assert ids(idn.relabel((mover(41, 3.15, 0.05, -0.1, -0.5),), (), {}, {41}, set(), 10.7)) == [40]
    assert ids(idn.relabel((mover(41, 3.1, 0.0, -0.1, -0.5),), (), {}, {41}, set(), 10.8)) == [40]


def test_a_new_track_out_of_reach_too_late_or_coming_towards_it_is_another_body() -> None:
    for new, stamp in ((mover(41, 3.2, -0.8, 0.0, -0.5), 10.7),  # 1.2 m in 0.7 s at 0.5 m/s
                       (mover(41, 3.2, 0.1, 0.0, -0.5), 11.2),  # after the tracker's 1 s
                       (mover(41, 3.2, 0.1, 0.0, 0.5), 10.7)):  # walking back towards where the other was
        idn = stitcher()
        idn.relabel((mover(40, 3.2, 0.4, 0.0, -0.5),), (), {}, {40}, set(), 10.0)
        idn.relabel((), (), {}, set(), set(), 10.1)
        assert ids(idn.relabel((new,), (), {}, {41}, set(), stamp)) == [41]


def test_an_ended_track_passes_its_id_once_and_the_memory_is_bounded() -> None:
    idn = stitcher()
    idn.relabel((mover(40, 3.2, 0.4, 0.0, -0.5),), (), {}, {40}, set(), 10.0)
    idn.relabel((), (), {}, set(), set(), 10.1)
    out = idn.relabel((mover(41, 3.2, 0.3, 0.0, -0.5), mover(42, 3.2, 0.2, 0.0, -0.5)), (), {}, {41, 42}, set(), 10.3)
    assert sorted(ids(out)) == [40, 42]
    idn.relabel((), (), {}, set(), set(), 20.0)
    assert not idn._ended and not idn._last


def test_without_a_gap_nothing_is_stitched() -> None:
    idn = ObstacleIdentity(0.25)
    idn.relabel((mover(40, 3.2, 0.4, 0.0, -0.5),), (), {}, {40}, set(), 10.0)
    idn.relabel((), (), {}, set(), set(), 10.1)
    assert ids(idn.relabel((mover(41, 3.2, 0.35, 0.0, -0.5),), (), {}, {41}, set(), 10.2)) == [41]
    with pytest.raises(ValueError, match="gap_s"):
        ObstacleIdentity(0.25, gap_s=-1.0)
