"""Per-person metrics of the hard people scenes (issue 29), for every scenario with people.

Definitions (docs/evaluation.md, "Per person"):

* **in view**: the laser sees the person: at least ``PERSON_BEAMS_IN_VIEW`` beams of the cycle's sweep
  hit the person's legs. The world's ray caster returns each beam's first hit, so a person hidden behind
  another body, a cart or a wall gets no beams and is not in view; nor is one behind the robot (outside
  the laser's 270 deg) or out of range. The camera plays no part. Nor is a person whose body overlaps a
  wall (its centre nearer to the wall than its radius): the crowd's walkers come and go through doorways
  the world does not model (the walls are drawn unbroken), so on their way in and out their legs stand in
  the wall's face, returns a few cm before it that no sensor could tell from the wall (a real doorway
  would show them against the room beyond).
* **walking**: the person's true speed is not zero at the cycle's time; **standing** otherwise; *standing
  still for more than 0.5 s* counts from the last instant it moved (before its first step: from t = 0).
* **located while walking** (``located_moving_fraction``): over the cycles in view and walking, the share
  with a reported moving obstacle (``Estimate.obstacles``) within ``LOCATED_GATE_M`` of the pelvis; every
  cycle the obstacles are assigned one-to-one to the moving bodies in view (people, carts, doors),
  nearest pair first, so one report cannot locate two people walking side by side.
* **located** (``located_fraction``): over the cycles in view, walking or standing, the share with a
  ``Estimate.people`` entry within ``LOCATED_GATE_M``, assigned one-to-one to the people in view.
* **identity** (``id_switches``): over the located cycles, in time order, how often the ``people`` entry
  assigned to the person has another track id than the one before (a person who stands, walks, is hidden
  or passes another keeps one id: 0; the CLEAR MOT metrics' ID switches, Bernardin and Stiefelhagen 2008).
* **position error**: the mean distance of those located assignments to the pelvis (``err_mean_m``:
  people entries; ``moving_err_mean_m``: moving obstacles).
* **velocity error** (``velocity_err_mean_mps``): the mean norm of the velocity difference of the
  located moving obstacles whose track is at least ``MIN_TRACK_AGE`` cycles old.
* **first report** (``first_report_s``, one per walk): for every start of a walk (the first, and each
  after a stop) the time from the start, or from the first cycle in view when the person was not in
  view when it started (it walked into view), to the first cycle it is located by a moving obstacle;
  null when the walk ends (or the run does) without one.
* **reported moving while standing** (``moving_while_standing_cycles``): cycles in which a moving
  obstacle, or a ``people`` entry flagged ``moving``, lies within ``LOCATED_GATE_M`` of a person that
  has stood still for more than ``STANDING_GRACE_S``, and that person is the true body nearest to it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hil_fakes.world import Scenario, Truth
from vipsm.assignment import greedy_pairs

#: a person is in view when at least this many beams hit its legs: a leg segment of 3 returns (the
#: smallest a leg detector clusters, leg_tracker's minimum) plus returns on the other leg
PERSON_BEAMS_IN_VIEW = 5
LOCATED_GATE_M = 0.5
MIN_TRACK_AGE = 10
#: a person standing still for longer than this must not be reported as moving
STANDING_GRACE_S = 0.5
CYCLE_S = 0.1


@dataclass
class PersonLog:
    """One person's counts over a run (one method)."""

    index: int
    walk_starts_s: list[float]
    in_view: int = 0
    located: int = 0
    errors_m: list[float] = field(default_factory=list)
    walking_in_view: int = 0
    located_moving: int = 0
    moving_errors_m: list[float] = field(default_factory=list)
    vel_errors_mps: list[float] = field(default_factory=list)
    moving_while_standing: int = 0
    #: per walk start: [reference time (None: not yet in view), first report delay (None: none yet)]
    walks: dict[float, list[float | None]] = field(default_factory=dict)
    standing_since_s: float = 0.0
    #: the track id of the ``people`` entry of the last located cycle, and how often it changed
    last_id: int | None = None
    id_switches: int = 0

    def result(self) -> dict[str, Any]:
        return {
            "index": self.index,
            "cycles_in_view": self.in_view,
            "cycles_walking_in_view": self.walking_in_view,
            "located_fraction": _share(self.located, self.in_view),
            "located_moving_fraction": _share(self.located_moving, self.walking_in_view),
            "err_mean_m": _mean(self.errors_m),
            "moving_err_mean_m": _mean(self.moving_errors_m),
            "velocity_err_mean_mps": _mean(self.vel_errors_mps),
            "first_report_s": [w[1] for start, w in sorted(self.walks.items()) if w[0] is not None],
            "moving_while_standing_cycles": self.moving_while_standing,
            "id_switches": self.id_switches,
        }


def _share(num: int, den: int) -> float | None:
    return round(num / den, 5) if den else None


def _mean(values: list[float]) -> float | None:
    return round(float(np.mean(values)), 5) if values else None


def _assign(est: list[tuple[float, float]], truth: list[tuple[int, float, float]]) -> dict[int, int]:
    """One-to-one, nearest pair first: true index -> estimate index."""
    d = np.array([[math.hypot(ex - tx, ey - ty) for ex, ey in est] for _, tx, ty in truth])
    return {truth[i][0]: j for i, j in greedy_pairs(d.reshape(len(truth), len(est)))}


def wall_segments(scenario: Scenario) -> np.ndarray:
    """The scenario's walls as (k, 4) rows x0, y0, x1, y1 (metres)."""
    walls = getattr(scenario, "walls", ())
    return np.array([[w.x0_m, w.y0_m, w.x1_m, w.y1_m] for w in walls], float).reshape(-1, 4)


def person_in_view(body: Any, beams: int, walls: np.ndarray) -> bool:
    """A person is in view (the module's definition): at least ``PERSON_BEAMS_IN_VIEW`` of the sweep's
    ``beams`` hit its legs and its centre is not inside one of ``walls`` (:func:`wall_segments`)."""
    return beams >= PERSON_BEAMS_IN_VIEW and not _in_a_wall(body, walls)


def _in_a_wall(body: Any, walls: np.ndarray) -> bool:
    """The body's centre lies nearer to one of ``walls`` ((k, 4): x0, y0, x1, y1) than its radius."""
    if not walls.size:
        return False
    p0, d = walls[:, :2], walls[:, 2:] - walls[:, :2]
    xy = np.array([body.x_m, body.y_m])
    u = np.clip(np.einsum("ij,ij->i", xy - p0, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-12), 0.0, 1.0)
    return bool(np.min(np.hypot(*(p0 + u[:, None] * d - xy).T)) < body.radius_m)


class PeopleScore:
    """Scores one method's ``Estimate.obstacles`` and ``Estimate.people`` against every true person."""

    def __init__(self, scenario: Scenario) -> None:
        self.persons = {
            i: PersonLog(i, list(o.walk_starts_s()))
            for i, o in enumerate(scenario.obstacles) if getattr(o, "kind", "") == "person"
        }
        self.walls = wall_segments(scenario)

    def update(self, t_s: float, estimate: Any, truth: Truth, hits: np.ndarray) -> None:
        """One cycle: ``truth`` at the estimate's stamp, ``hits`` the beams per true body."""
        view = {i: person_in_view(truth.obstacles[i], int(hits[i]), self.walls) for i in self.persons}
        for i, p in self.persons.items():
            if truth.obstacles[i].moving:
                p.standing_since_s = math.inf
            elif p.standing_since_s == math.inf:
                p.standing_since_s = t_s
        self._people(estimate.people, truth, view)
        self._moving(t_s, estimate.obstacles, truth, hits, view)
        self._standing(t_s, estimate, truth)

    def _people(self, people: Any, truth: Truth, view: dict[int, bool]) -> None:
        vis = [(i, truth.obstacles[i].x_m, truth.obstacles[i].y_m) for i in self.persons if view[i]]
        assigned = _assign([(q.x_m, q.y_m) for q in people], vis)
        for i, _, _ in vis:
            p = self.persons[i]
            p.in_view += 1
            if i in assigned:
                q, o = people[assigned[i]], truth.obstacles[i]
                err = math.hypot(q.x_m - o.x_m, q.y_m - o.y_m)
                if err <= LOCATED_GATE_M:
                    p.located += 1
                    p.errors_m.append(err)
                    p.id_switches += p.last_id is not None and q.track_id != p.last_id
                    p.last_id = q.track_id

    def _moving(self, t_s: float, obstacles: Any, truth: Truth, hits: np.ndarray, view: dict[int, bool]) -> None:
        moving = [(i, o.x_m, o.y_m) for i, o in enumerate(truth.obstacles)
                  if o.moving and (view[i] if i in view else int(hits[i]) >= PERSON_BEAMS_IN_VIEW)]
        assigned = _assign([(e.x_m, e.y_m) for e in obstacles], moving)
        for i, p in self.persons.items():
            o = truth.obstacles[i]
            if not (o.moving and view[i]):
                continue
            p.walking_in_view += 1
            start = max((w for w in p.walk_starts_s if w <= t_s + 1e-9), default=None)
            walk = p.walks.setdefault(start, [None, None]) if start is not None else [t_s, None]
            if walk[0] is None:  # in view at the walk's first cycle: from its start; else from now
                walk[0] = start if start is not None and t_s - start < CYCLE_S + 1e-9 else t_s
            e = obstacles[assigned[i]] if i in assigned else None
            err = math.hypot(e.x_m - o.x_m, e.y_m - o.y_m) if e is not None else math.inf
            if err > LOCATED_GATE_M:
                continue
            p.located_moving += 1
            p.moving_errors_m.append(err)
            if walk[1] is None:
                walk[1] = round(t_s - float(walk[0]), 3)
            if e.age_cycles >= MIN_TRACK_AGE:
                p.vel_errors_mps.append(math.hypot(e.vx_mps - o.vx_mps, e.vy_mps - o.vy_mps))

    def _standing(self, t_s: float, estimate: Any, truth: Truth) -> None:
        reports = [(e.x_m, e.y_m) for e in estimate.obstacles] + [(q.x_m, q.y_m) for q in estimate.people if q.moving]
        flagged: set[int] = set()
        for x, y in reports:
            d = [math.hypot(o.x_m - x, o.y_m - y) for o in truth.obstacles]
            if not d:
                return
            j = int(np.argmin(d))
            p = self.persons.get(j)
            if p is not None and d[j] <= LOCATED_GATE_M and t_s - p.standing_since_s > STANDING_GRACE_S + 1e-9:
                flagged.add(j)
        for j in flagged:
            self.persons[j].moving_while_standing += 1

    def results(self) -> list[dict[str, Any]]:
        return [p.result() for p in self.persons.values()]


def summary(persons: list[dict[str, Any]]) -> dict[str, Any]:
    """The scene's figures for issue 29's targets: the worst person's (None when undefined)."""

    def worst(key: str, pick: Any) -> float | None:
        vals = [p[key] for p in persons if p[key] is not None]
        return pick(vals) if vals else None

    delays = [d for p in persons for d in p["first_report_s"]]
    return {
        "person_located_min": worst("located_fraction", min),
        "person_located_moving_min": worst("located_moving_fraction", min),
        "person_err_mean_max_m": worst("err_mean_m", max),
        "person_moving_err_mean_max_m": worst("moving_err_mean_m", max),
        "person_velocity_err_max_mps": worst("velocity_err_mean_mps", max),
        "first_report_max_s": None if not delays or None in delays else max(delays),
        "first_reports_missing": sum(1 for d in delays if d is None),
        "moving_while_standing_cycles": sum(p["moving_while_standing_cycles"] for p in persons),
        "person_id_switches": sum(p["id_switches"] for p in persons),
    }
