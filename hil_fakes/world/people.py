"""Walking people: two scissoring legs at the laser's height, a jointed body in the camera.

A person walks along an :class:`~hil_fakes.world.geometry.ObstaclePath` (the path of the pelvis, the
body centre the ground truth reports) and carries a :class:`Gait`. The gait is a function of the
distance walked, not of time, so a person who stands still keeps their feet where they are and a
person who starts walking starts from feet side by side.

Gait model (biomechanics textbook values: Winter, *Biomechanics and Motor Control of Human
Movement*; Perry, *Gait Analysis*): a full stride (two steps) is ``stride_m`` long (1.2-1.4 m at
1.0-1.4 m/s); each foot is on the ground for ``stance_frac`` (about 60 %) of the stride and swings
for the rest. In stance the foot stands still in the world, so relative to the pelvis it moves back
by ``stance_frac * stride_m``; in swing it moves forward by the same amount relative to the pelvis
(``stride_m`` in the world), with a smooth (cosine) profile. The two feet are half a stride out of
phase and ``hip_halfwidth_m`` to either side of the line of walking. A leg is a straight pendulum
from the hip (``leg_length_m`` above the floor) to the foot, so at height ``h`` the leg section is
offset from the pelvis by ``(1 - h / leg_length_m)`` times the foot's offset: at the laser's 0.3 m
the shins swing about 2/3 as far as the feet.
"""

from __future__ import annotations

import math

import numpy as np

from .geometry import Gait, ObstaclePath


def _foot_offset(p: np.ndarray, gait: Gait) -> np.ndarray:
    """Foot position along the walking direction relative to the pelvis, in metres, at gait phase p
    in [0, 1): stance from +a to -a linearly, swing back to +a on a cosine, a = stance * stride / 2."""
    a = 0.5 * gait.stance_frac * gait.stride_m
    st = gait.stance_frac
    stance = a - 2.0 * a * (p / st)
    q = np.clip((p - st) / (1.0 - st), 0.0, 1.0)
    swing = -a * np.cos(math.pi * q)
    return np.where(p < st, stance, swing)


def walking_direction(path: ObstaclePath, t_s: np.ndarray) -> np.ndarray:
    """Unit vectors (..., 2) a person faces at ``t_s``: the direction of motion, or while standing the
    direction of the path segment they stand on (before the start: the first; after the end: the last)."""
    pts = np.asarray(path.waypoints, float).reshape(-1, 2)
    vel = path.velocities(t_s)
    speed = np.hypot(vel[..., 0], vel[..., 1])[..., None]
    if len(pts) > 1:
        seg = np.diff(pts, axis=0)
        seg = seg / np.maximum(np.hypot(seg[:, 0], seg[:, 1]), 1e-9)[:, None]
        cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
        s = distance_walked(path, t_s)
        k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
        idle = seg[k]
    else:
        idle = np.broadcast_to(np.array([1.0, 0.0]), np.shape(t_s) + (2,))
    return np.where(speed > 1e-9, vel / np.where(speed > 1e-9, speed, 1.0), idle)


def distance_walked(path: ObstaclePath, t_s: np.ndarray) -> np.ndarray:
    return path.distance_m(np.asarray(t_s, float))


def leg_centres(path: ObstaclePath, gait: Gait, t_s: np.ndarray, height_m: float) -> np.ndarray:
    """Centres (..., 2 legs, 2) of the leg sections at ``height_m`` above the floor at ``t_s``."""
    t = np.asarray(t_s, float)
    centre = path.positions(t)
    fwd = walking_direction(path, t)
    left = np.stack([-fwd[..., 1], fwd[..., 0]], axis=-1)
    s = distance_walked(path, t) / gait.stride_m + gait.phase0
    shrink = max(0.0, 1.0 - height_m / gait.leg_length_m)
    legs = []
    for side, phase in ((1.0, 0.0), (-1.0, 0.5)):
        p = np.mod(s + phase, 1.0)
        along = _foot_offset(p, gait) * shrink
        legs.append(centre + along[..., None] * fwd + side * gait.hip_halfwidth_m * left)
    return np.stack(legs, axis=-2)


def body_parts(path: ObstaclePath, gait: Gait, t_s: float) -> list[tuple[float, float, float, float, float]]:
    """Vertical cylinders (x, y, radius, z_bottom, z_top) that make up the person in the camera:
    two legs (at knee height), torso, head and two arms swinging against the legs."""
    t = np.asarray(t_s, float)
    cx, cy = (float(v) for v in path.positions(t))
    fx, fy = (float(v) for v in walking_direction(path, t))
    lx, ly = -fy, fx
    h = gait.height_m
    hip_z = gait.leg_length_m * h / 1.75
    parts = []
    legs = leg_centres(path, gait, t, 0.5 * hip_z)
    for k in range(2):
        parts.append((float(legs[k, 0]), float(legs[k, 1]), 0.07, 0.0, hip_z))
    parts.append((cx, cy, 0.17, hip_z, 0.82 * h))
    parts.append((cx, cy, 0.10, 0.86 * h, h))
    for k, side in enumerate((1.0, -1.0)):
        # arms swing opposite to the leg on the same side, about 40 % of the leg's swing
        swing = -0.4 * float(np.dot(legs[k] - np.array([cx, cy]), np.array([fx, fy])))
        ax = cx + side * 0.23 * lx + swing * fx
        ay = cy + side * 0.23 * ly + swing * fy
        parts.append((ax, ay, 0.045, 0.48 * h, 0.80 * h))
    return parts
