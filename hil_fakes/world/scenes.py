"""The hard people scenes (issue 29): how their bodies are built.

Each builder turns a validated parameter dict (``scenarios.PARAMS``) into the scene's moving bodies,
and where needed its walls; :func:`hil_fakes.world.scenarios.build_scenario` calls them by the
``scene`` key. The effects and their sources:

* **Starting and stopping** (``walk_accel_s``): a walker reaches walking speed from standing, and stands
  from walking, within about one step (gait initiation: Breniere & Do 1986, steady speed at the end of
  the first step, about 0.6 s); the speed ramps linearly over ``walk_accel_s``, so the distance walked is
  a smooth function of time (:func:`walk_profile`).
* **Stop and go** (``stop_at_fraction``, ``stop_duration_s``): the walker stops at that fraction of its
  path, stands ``stop_duration_s`` and walks on.
* **A companion** (``companion_offset_m``): a second person walks beside the first, their body centres
  ``companion_offset_m`` apart across the walking direction (to its left; on curves the outer one walks
  faster, as pairs do), legs in step (pairs walking side by side tend to fall into step).
* **A cart** (``cart_length_m`` x ``cart_width_m``): a rigid box pushed ``CART_REACH_M`` ahead of its
  pusher's pelvis, its long axis along the pusher's heading over the last ``CART_HEADING_BASE_M`` walked
  (a cart follows the hands, it does not turn on the spot); seen by the laser between 0.15 and 0.95 m.
* **A crowd** (``scene = "crowd"``): ``crowd_walkers`` recorded pedestrians (ETH/UCY shapes, each walked
  at its own recorded mean speed) crossing in front of the robot at spread angles, closest approaches
  ``crowd_spacing_s`` apart, kept clear of each other (bodies >= 0.1 m apart), the first with a companion.
* **Along a wall** (``scene = "along_wall"``): a person walks along the left wall towards the robot and
  out of the room's open end, the nearer leg's surface ``wall_gap_m`` from the wall (a wall forces a
  straight line; a recorded shape's sway would cross it, so this walker's path is straight).
* **A door** (``scene = "door"``): a 40 mm leaf ``door_width_m`` wide in the left wall, hinged at
  ``door_hinge_x_m`` (the doorway's far side), swings 90 deg into the room at ``door_open_s`` and back at
  ``door_close_s``, each swing over ``door_swing_s`` on a cosine (peak about 95 deg/s for 1.5 s, a door
  pushed by hand [?]); behind the doorway a corridor 1.2 m deep, which the laser sees while the door is open.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from .geometry import ObstaclePath, RigidBox, Wall

#: pose knots of rigid boxes and of offset paths are sampled this often
KNOT_DT_S = 0.02
#: a cart's rear is this far ahead of its pusher's pelvis (hands on the handle, arms bent)
CART_REACH_M = 0.45
#: a cart's heading: the direction of its pusher's last this-many metres walked
CART_HEADING_BASE_M = 0.5
#: a cart's body at the laser's height: a box from 0.15 to 0.95 m (a utility cart with side panels)
CART_Z_M = (0.15, 0.95)
#: the door leaf's thickness and height; the doorway is 2 cm wider than the leaf
DOOR_THICKNESS_M = 0.04
DOOR_HEIGHT_M = 2.0
DOOR_CLEARANCE_M = 0.02
#: the corridor behind the doorway
CORRIDOR_DEPTH_M = 1.2
#: crowd: crossing angles (deg) of walkers 0, 1, ... (cycled), closest approaches (m, cycled)
CROWD_ANGLES_DEG = (90.0, 60.0, 120.0, 75.0, 105.0, 45.0, 135.0, 90.0, 60.0, 120.0)
CROWD_APPROACH_M = (1.3, 1.7, 2.1)
#: the range of recorded mean speeds walked (slower samples are people dawdling or waiting)
CROWD_SPEED_MPS = (0.6, 1.6)


# ------------------------------------------------------------------------------------- speed profiles
def _leg_knots(t0: float, s0: float, s1: float, v: float, accel_s: float) -> tuple[list[tuple[float, float]], float]:
    """Knots (t, s) of one walk from s0 to s1 starting at t0 at top speed v, ramping up and down over
    ``accel_s`` (a triangle when the walk is too short to reach v); and the time it ends."""
    d = s1 - s0
    if accel_s <= 0:
        return [(t0, s0), (t0 + d / v, s1)], t0 + d / v
    a = v / accel_s
    t_r = min(accel_s, math.sqrt(d / a))
    v_top = a * t_r
    t_cruise = (d - a * t_r * t_r) / v_top
    total = 2 * t_r + t_cruise

    def s_at(t: float) -> float:
        if t < t_r:
            return 0.5 * a * t * t
        if t < t_r + t_cruise:
            return 0.5 * a * t_r * t_r + v_top * (t - t_r)
        u = total - t
        return d - 0.5 * a * u * u

    ts = np.append(np.arange(0.0, total, KNOT_DT_S), total)
    return [(t0 + float(t), s0 + min(d, s_at(float(t)))) for t in ts], t0 + total


def walk_profile(length_m: float, start_s: float, speed_mps: float, accel_s: float,
                 stop_at_m: float = 0.0, stop_duration_s: float = 0.0) -> tuple[tuple[float, float], ...]:
    """Distance walked against time: start at ``start_s``, optionally stop at ``stop_at_m`` for
    ``stop_duration_s``, walk to the end; speed ramps over ``accel_s`` at every start and stop."""
    ends = [stop_at_m, length_m] if 0.0 < stop_at_m < length_m else [length_m]
    knots: list[tuple[float, float]] = []
    t, s = start_s, 0.0
    for end in ends:
        leg, t_end = _leg_knots(t, s, end, speed_mps, accel_s)
        knots += leg if not knots else leg[1:] if abs(leg[0][0] - knots[-1][0]) < 1e-9 else leg
        t, s = t_end + stop_duration_s, end
    return tuple(knots)


def with_walk_profile(path: ObstaclePath, prm: dict[str, Any]) -> ObstaclePath:
    """``path`` walked with the scene's starts and stops (``walk_accel_s``, ``stop_at_fraction``)."""
    if prm["walk_accel_s"] <= 0 and prm["stop_at_fraction"] <= 0:
        return path
    knots = walk_profile(path.length_m, path.start_s, path.speed_mps, prm["walk_accel_s"],
                         prm["stop_at_fraction"] * path.length_m, prm["stop_duration_s"])
    return dataclasses.replace(path, profile=knots)


# ------------------------------------------------------------------------------------- companions, carts
def _headings(path: ObstaclePath, t: np.ndarray, base_m: float) -> np.ndarray:
    """Unit heading (N, 2) at times t: the chord over the last ``base_m`` walked (the first segment's
    direction before that)."""
    s = path.distance_m(t)
    pts = np.asarray(path.waypoints, float).reshape(-1, 2)
    first = pts[min(1, len(pts) - 1)] - pts[0]
    back = path.positions_at_distance(np.maximum(s - base_m, 0.0))
    chord = path.positions_at_distance(np.maximum(s, base_m)) - back
    chord = np.where(s[:, None] > 1e-6, chord, first)
    return chord / np.maximum(np.hypot(chord[:, 0], chord[:, 1]), 1e-9)[:, None]


def _moving_times(path: ObstaclePath) -> np.ndarray:
    t0 = path.start_s
    t1 = path.end_s
    return np.append(np.arange(t0, t1, KNOT_DT_S), t1)


def companion(path: ObstaclePath, offset_m: float) -> ObstaclePath:
    """A second person beside ``path``'s walker, body centres ``offset_m`` apart (to its left), in step,
    beside its line of walking over the last stride: a walker's path sways by a few degrees within a stride
    (recorded paths: heading sigma 8 deg), and a companion held square to each sway would swing its own
    speed by the offset times that turn rate (0.5-1.2 m/s beside a steady 0.9 m/s)."""
    t = _moving_times(path)
    stride_m = path.gait.stride_m if path.gait is not None else 1.0
    left = _headings(path, t, stride_m) @ np.array([[0.0, 1.0], [-1.0, 0.0]])
    pts = path.positions(t) + offset_m * left
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    keep = np.concatenate([[True], np.diff(s) > 1e-9])
    t, pts, s = t[keep], pts[keep], s[keep]
    return dataclasses.replace(path, waypoints=tuple((float(x), float(y)) for x, y in pts),
                               profile=tuple(zip(t.tolist(), s.tolist(), strict=True)))


def cart(pusher: ObstaclePath, length_m: float, width_m: float, duration_s: float) -> RigidBox:
    """The cart ``pusher`` pushes: its rear ``CART_REACH_M`` ahead of the pelvis, along the heading."""
    t = np.append(np.arange(0.0, duration_s, KNOT_DT_S), duration_s)
    u = _headings(pusher, t, CART_HEADING_BASE_M)
    c = pusher.positions(t) + (CART_REACH_M + length_m / 2) * u
    yaw = np.arctan2(u[:, 1], u[:, 0])
    knots = tuple((float(a), float(b), float(d), float(e)) for a, b, d, e in zip(t, c[:, 0], c[:, 1], yaw, strict=True))
    return RigidBox("cart", length_m, width_m, knots, height_m=CART_Z_M[1], z0_m=CART_Z_M[0], reflectivity=0.5)


def shortened_for_cart(path: ObstaclePath, length_m: float) -> ObstaclePath:
    """``path`` ending ``CART_REACH_M + length_m`` earlier, so the cart ahead stops where the walker would."""
    keep = path.length_m - (CART_REACH_M + length_m)
    if keep <= 0.5:
        raise ValueError("the pusher's path is too short for the cart")
    pts = path.positions_at_distance(np.linspace(0.0, keep, max(2, int(keep / 0.05))))
    return dataclasses.replace(path, waypoints=tuple((float(x), float(y)) for x, y in pts))


# ------------------------------------------------------------------------------------- doors
def door(prm: dict[str, Any], wall_y_m: float) -> RigidBox:
    """The door leaf: hinged at (``door_hinge_x_m``, wall) on the doorway's far side (seen from the robot's
    start), closed along -x in the wall, open at -90 deg (into the room, the leaf facing the robot),
    swinging on a cosine over ``door_swing_s`` from ``door_open_s`` and back from ``door_close_s``."""
    t = np.append(np.arange(0.0, prm["duration_s"], KNOT_DT_S), prm["duration_s"])
    sw = prm["door_swing_s"]

    def swing(t0: float) -> np.ndarray:
        u = np.clip((t - t0) / sw, 0.0, 1.0)
        return 0.5 * (1.0 - np.cos(math.pi * u))

    opened = swing(prm["door_open_s"]) - (swing(prm["door_close_s"]) if prm["door_close_s"] > 0 else 0.0)
    yaw = math.pi + 0.5 * math.pi * opened
    hx, half = prm["door_hinge_x_m"] - DOOR_CLEARANCE_M / 2, prm["door_width_m"] / 2
    cx, cy = hx + half * np.cos(yaw), wall_y_m + half * np.sin(yaw)
    knots = tuple((float(a), float(b), float(c), float(d)) for a, b, c, d in zip(t, cx, cy, yaw, strict=True))
    return RigidBox("door", prm["door_width_m"], DOOR_THICKNESS_M, knots, height_m=DOOR_HEIGHT_M, reflectivity=0.55)


def doorway_walls(prm: dict[str, Any], room: tuple[Wall, ...], wall_y_m: float) -> tuple[Wall, ...]:
    """The room's walls with the left wall (the first) cut for the doorway and a corridor behind it."""
    left, rest = room[0], room[1:]
    x1 = prm["door_hinge_x_m"]
    x0 = x1 - prm["door_width_m"] - DOOR_CLEARANCE_M
    back = wall_y_m + CORRIDOR_DEPTH_M
    c0, c1 = max(left.x0_m, x0 - 1.0), min(left.x1_m, x1 + 1.0)
    return (
        Wall(left.x0_m, wall_y_m, x0, wall_y_m, reflectivity=left.reflectivity),
        Wall(x1, wall_y_m, left.x1_m, wall_y_m, reflectivity=left.reflectivity),
        Wall(c0, wall_y_m, c0, back, reflectivity=0.6),
        Wall(c0, back, c1, back, reflectivity=0.6),
        Wall(c1, back, c1, wall_y_m, reflectivity=0.6),
        *rest,
    )
