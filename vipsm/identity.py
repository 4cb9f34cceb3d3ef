"""One obstacle id per person across the two trackers that report moving obstacles.

``Estimate.obstacles`` holds the body tracker's reported tracks (stage 6) and the people stage's moving
people that no body track stands for (stage 6b). A walker whose legs the scanner returns only now and
then (a 5.6 m scanner at 3-3.6 m, a leg hidden behind the other) is lost and found again by the body
tracker while the people stage, which tracks each leg, holds it throughout: without this stage the one
walker was reported as body track A, then for the cycles in between as the person, then as body track B,
three ids of which the middle ones last 1-3 cycles (a consumer following ids saw three obstacles, each
too short to show that it moved).

The people stage's person is the longer-lived identity, so it carries the id across: a moving person that
stands for a body track (:meth:`vipsm.people.PeopleTracker.bodies_standing_for`: the same body, reported
once) takes that body's reported id if it has none yet; a body track reported for the first time while a
person with an id stands for it takes the person's id; a person reported itself keeps its id (its own
track id unless it took one). An id once given to a track is kept for the track's life (a body's reports
stay one track), and no id is given twice in one cycle (the later one keeps its own track id then).
Positions, velocities and what is reported are unchanged: only ``track_id``.
"""

from __future__ import annotations

from dataclasses import replace

from .types import Obstacle


class ObstacleIdentity:
    """The reported id of each live body track and person (bounded: entries of tracks that ended are
    dropped each cycle)."""

    def __init__(self, same_m: float) -> None:
        """``same_m``: a person and a body track whose centres lie this close are one body (a person's
        radius); one standing for a body further off (a leg pair's reach: it suppresses a second report of
        the same person) passes no id, as a person beside the walker the body tracker holds may be linked
        to it for a cycle when the walker's own legs are not seen."""
        if not same_m > 0.0:
            raise ValueError(f"need same_m > 0, got {same_m}")
        self.same_m = same_m
        self._body: dict[int, int] = {}
        self._person: dict[int, int] = {}

    def relabel(self, bodies: tuple[Obstacle, ...], persons: tuple[Obstacle, ...],
                standing_for: dict[int, tuple[int, float]], live_bodies: set[int], live_persons: set[int]
                ) -> tuple[Obstacle, ...]:
        """``bodies``: the body tracker's reported obstacles; ``persons``: the people stage's (their
        ``track_id`` are the two trackers' own); ``standing_for``: body track id -> (the moving person that
        stands for it this cycle, their distance), a link when within ``same_m``; ``live_*``: the track ids
        still alive in either tracker. Returns the obstacles, bodies first, with their reported ids."""
        links = {b: p for b, (p, d) in standing_for.items() if d <= self.same_m}
        self._body = {k: v for k, v in self._body.items() if k in live_bodies}
        self._person = {k: v for k, v in self._person.items() if k in live_persons}
        for o in bodies:  # a body's first report: the id of the person standing for it, if it has one
            if o.track_id not in self._body:
                person = links.get(o.track_id)
                self._body[o.track_id] = self._person.get(person, o.track_id) if person is not None else o.track_id
        for body, person in links.items():  # a person with no id yet takes its body's
            if body in self._body and person not in self._person:
                self._person[person] = self._body[body]
        wanted = [self._body[o.track_id] for o in bodies]
        wanted += [self._person.setdefault(o.track_id, o.track_id) for o in persons]
        return _unique([*bodies, *persons], wanted)


def _unique(obstacles: list[Obstacle], wanted: list[int]) -> tuple[Obstacle, ...]:
    """Each obstacle with its wanted id, those keeping their own first; one whose wanted id another holds
    in this cycle keeps its own (the trackers' own ids are unique)."""
    ids = [o.track_id for o in obstacles]
    used = {w for o, w in zip(obstacles, wanted, strict=True) if w == o.track_id}
    for i, (o, w) in enumerate(zip(obstacles, wanted, strict=True)):
        if w != o.track_id and w not in used:
            ids[i] = w
            used.add(w)
    return tuple(o if t == o.track_id else replace(o, track_id=t) for o, t in zip(obstacles, ids, strict=True))
