"""A person at the laser's height: the sizes the body stage, the tracker and the people stage share.

One key for one physical quantity: the people stage's config (``vipsm.people.PeopleConfig``) holds them
and takes its defaults from :class:`PersonSize`; the body stage and the tracker read them through
:class:`PersonKeys`. This module imports none of those stages, so each can import it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol


class PersonKeys(Protocol):
    """A person at the laser's height, as the people stage's keys give it (``vipsm.people.PeopleConfig``,
    whose defaults are :class:`PersonSize`'s: one key for one physical quantity)."""

    leg_radius_m: float
    leg_pair_max_m: float
    person_radius_m: float
    leg_across_max_m: float
    leg_max_speed_mps: float
    leg_step_m: float


@dataclass(frozen=True)
class PersonSize:
    """The defaults of :class:`PersonKeys` (``PeopleConfig`` takes its defaults from here, so that this
    module need not import the people stage, which imports it)."""

    #: a leg's radius at the laser's height
    leg_radius_m: float = 0.06
    #: two legs of one person: centres at most this far apart (stride at the laser's height)
    leg_pair_max_m: float = 0.65
    #: a person's radius (shoulders seen from above)
    person_radius_m: float = 0.25
    #: two legs of a walking person: centres at most this far apart across its line of walking (the feet
    #: swing along it a hip's width apart, 0.1-0.2 m at the laser's height, plus each centre's few cm)
    leg_across_max_m: float = 0.3
    #: a leg moves at most this fast (a swing leg: about twice the walking speed) ...
    leg_max_speed_mps: float = 3.0
    #: ... plus this (its centre's noise) between two detections
    leg_step_m: float = 0.1


def leg_reach_m(keys: PersonKeys, dt_s: float) -> float:
    """How far one leg's centre may be from where it was ``dt_s`` earlier: ``leg_step_m`` plus
    ``leg_max_speed_mps`` over that time (the people stage's leg association gate; the tracker's test of
    whether two leg pairs can be the same two legs)."""
    return keys.leg_step_m + keys.leg_max_speed_mps * max(dt_s, 0.0)


def across_beyond_m(dx: float, dy: float, line: tuple[float, float], sigma_rad: float) -> float:
    """How far ``(dx, dy)`` lies across the unit vector ``line`` (a walker's line of walking) beyond what its
    uncertainty (one sigma of its direction, ``sigma_rad``) allows: the offset across, less two sigma times
    the offset along it (a walker turning or stepping aside). Two legs of one walker lie within
    ``PersonKeys.leg_across_max_m`` of its line by this measure (the body stage's pairing and the people
    stage's split judge alike)."""
    ux, uy = line
    return abs(dx * uy - dy * ux) - 2.0 * sigma_rad * abs(dx * ux + dy * uy)
