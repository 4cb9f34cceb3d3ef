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
once) takes that body's reported id if it has none yet; a body track reports the id of the person with an id
standing for it whenever one does (the body tracker may hold one walker, then another passing close), and
the last id it reported otherwise (at its first report its own); a person reported itself keeps its id (its
own track id unless it took one). A person's id is kept for its track's life, and no id is given twice in one
cycle (the later one keeps its own track id then).
The body tracker also drops a coasting track whose centre a beam of the scan passes through, which it
does too when the scanner misses a walker's legs for a scan; the walker is then started afresh. A track
reported for the first time shortly after, where the ended one could have got to and moving on from there,
takes its id (``ObstacleIdentity(gap_s=...)``: the tracker's own coast time and reach).
Positions, velocities and what is reported are unchanged: only ``track_id``.
"""

from __future__ import annotations

import math
from dataclasses import replace

from .types import Obstacle


class ObstacleIdentity:
    """The reported id of each live body track and person, and the last report of each reported track that
    ended within ``gap_s`` (bounded: entries of tracks that ended longer ago are dropped each cycle)."""

    def __init__(self, same_m: float, gap_s: float = 0.0, speed_mps: float = 0.0, step_m: float = 0.0) -> None:
        """``same_m``: a person and a body track whose centres lie this close are one body (a person's
        radius); one standing for a body further off (a leg pair's reach: it suppresses a second report of
        the same person) passes no id, as a person beside the walker the body tracker holds may be linked
        to it for a cycle when the walker's own legs are not seen. ``gap_s`` > 0: a track reported for the
        first time within ``gap_s`` of the last report of a reported track that ended takes its id (the
        nearest such; each once) when it lies within ``step_m`` + v x the time between of that report, v the
        faster of the two tracks' reported speeds (at most ``speed_mps``), and, further than ``step_m``, its
        velocity points away from there. The body tracker's own bounds: ``tracker.max_missed_s`` (a
        confirmed body unseen that long is still tracked), ``max_speed_mps`` and ``step_noise_m`` (how far
        one body's detections move in a time)."""
        if not same_m > 0.0 or min(gap_s, speed_mps, step_m) < 0.0:
            raise ValueError(f"need same_m > 0 and gap_s, speed_mps, step_m >= 0, got {same_m}, {gap_s}, "
                             f"{speed_mps}, {step_m}")
        self.same_m, self.gap_s, self.speed_mps, self.step_m = same_m, gap_s, speed_mps, step_m
        self._body: dict[int, int] = {}
        self._person: dict[int, int] = {}
        #: the last report of each live track, and of each ended one: (stamp, x, y, speed, id)
        self._last: dict[tuple[str, int], tuple[float, float, float, float, int]] = {}
        self._ended: list[tuple[float, float, float, float, int]] = []

    def relabel(self, bodies: tuple[Obstacle, ...], persons: tuple[Obstacle, ...],
                standing_for: dict[int, tuple[int, float]], live_bodies: set[int], live_persons: set[int],
                stamp_s: float = 0.0) -> tuple[Obstacle, ...]:
        """``bodies``: the body tracker's reported obstacles; ``persons``: the people stage's (their
        ``track_id`` are the two trackers' own); ``standing_for``: body track id -> (the moving person that
        stands for it this cycle, their distance), a link when within ``same_m``; ``live_*``: the track ids
        still alive in either tracker. Returns the obstacles, bodies first, with their reported ids."""
        links = {b: p for b, (p, d) in standing_for.items() if d <= self.same_m}
        self._forget(live_bodies, live_persons, stamp_s)
        for o in bodies:  # the id of the person standing for it, if it has one; else the last it reported
            person = links.get(o.track_id)
            own = self._person.get(person) if person is not None else None
            if own is not None:
                self._body[o.track_id] = own
            elif o.track_id not in self._body:
                self._body[o.track_id] = self._stitched(o, stamp_s)
        for body, person in links.items():  # a person with no id yet takes its body's
            if body in self._body and person not in self._person:
                self._person[person] = self._body[body]
        for o in persons:
            if o.track_id not in self._person:
                self._person[o.track_id] = self._stitched(o, stamp_s)
        wanted = [self._body[o.track_id] for o in bodies] + [self._person[o.track_id] for o in persons]
        out = _unique([*bodies, *persons], wanted)
        keys = [("b", o.track_id) for o in bodies] + [("p", o.track_id) for o in persons]
        for k, o in zip(keys, out, strict=True):
            self._last[k] = (stamp_s, o.x_m, o.y_m, math.hypot(o.vx_mps, o.vy_mps), o.track_id)
        return out

    def _forget(self, live_bodies: set[int], live_persons: set[int], stamp_s: float) -> None:
        self._body = {k: v for k, v in self._body.items() if k in live_bodies}
        self._person = {k: v for k, v in self._person.items() if k in live_persons}
        held = set(self._body.values()) | set(self._person.values())
        for k in [k for k in self._last if k[1] not in (live_bodies if k[0] == "b" else live_persons)]:
            last = self._last.pop(k)
            if self.gap_s > 0.0 and last[4] not in held:
                self._ended.append(last)
        self._ended = [e for e in self._ended if stamp_s - e[0] <= self.gap_s]

    def _stitched(self, o: Obstacle, stamp_s: float) -> int:
        """The id of the nearest ended track whose last report ``o`` may continue, else ``o``'s own: within
        ``step_m`` + the faster of the two reported speeds (at most ``speed_mps``) x the time between, and
        moving away from there."""
        best, pick = math.inf, None
        speed = math.hypot(o.vx_mps, o.vy_mps)
        for i, (t, x, y, v, _) in enumerate(self._ended):
            d = math.hypot(o.x_m - x, o.y_m - y)
            came = d <= self.step_m or (o.x_m - x) * o.vx_mps + (o.y_m - y) * o.vy_mps > 0.0
            if came and d <= self.step_m + min(max(v, speed), self.speed_mps) * (stamp_s - t) and d < best:
                best, pick = d, i
        return self._ended.pop(pick)[4] if pick is not None else o.track_id


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
