"""A person at the laser's height: the sizes the body stage, the tracker and the people stage share.

One key for one physical quantity: the people stage's config (``vipsm.people.PeopleConfig``) holds them
and takes its defaults from :class:`PersonSize`; the body stage and the tracker read them through
:class:`PersonKeys`. This module imports none of those stages, so each can import it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol


class PersonKeys(Protocol):
    """A person at the laser's height, as the people stage's keys give it (``vipsm.people.PeopleConfig``,
    whose defaults are :class:`PersonSize`'s: one key for one physical quantity)."""

    leg_radius_m: float
    leg_pair_max_m: float
    person_radius_m: float
    leg_across_max_m: float


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


def across_beyond_m(dx: float, dy: float, line: tuple[float, float], sigma_rad: float) -> float:
    """How far ``(dx, dy)`` lies across the unit vector ``line`` (a walker's line of walking) beyond what its
    uncertainty (one sigma of its direction, ``sigma_rad``) allows: the offset across, less two sigma times
    the offset along it (a walker turning or stepping aside). Two legs of one walker lie within
    ``PersonKeys.leg_across_max_m`` of its line by this measure (the body stage's pairing and the people
    stage's split judge alike)."""
    ux, uy = line
    return abs(dx * uy - dy * ux) - 2.0 * sigma_rad * abs(dx * ux + dy * uy)


def leg_density(dx: float, dy: float, hidden_s: float, walk_share: float, v_mps: tuple[float, float],
                sigma_m: float) -> float:
    """The density (per square metre) of a leg's position ``(dx, dy)`` from where it was last seen, ``hidden_s``
    ago, given its person's motion state: standing, the leg stays there (a leg centre's noise ``sigma_m``);
    walking (probability ``walk_share``, at velocity ``v_mps``), it either stands or swings ahead along the
    line of walking at up to twice the body's speed, i.e. anywhere from 0 to 2 |v| ``hidden_s`` ahead: a
    Gaussian of that spread's mean and variance along the line (plus the noise), the noise across it."""
    stand = math.exp(-0.5 * (dx * dx + dy * dy) / sigma_m**2) / (2.0 * math.pi * sigma_m**2)
    speed = math.hypot(*v_mps)
    if walk_share <= 0.0 or speed <= 0.0:
        return stand
    ux, uy = v_mps[0] / speed, v_mps[1] / speed
    ahead = speed * hidden_s
    along, across = dx * ux + dy * uy - ahead, -dx * uy + dy * ux
    s_along = math.sqrt(sigma_m**2 + ahead**2 / 3.0)
    walk = math.exp(-0.5 * ((along / s_along) ** 2 + (across / sigma_m) ** 2)) / (2.0 * math.pi * s_along * sigma_m)
    return (1.0 - walk_share) * stand + walk_share * walk
