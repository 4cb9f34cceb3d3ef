"""Scenario definitions: the paper's two experiments and custom ones from a dict of parameters.

A scenario is fully described by a flat dict of parameters (``PARAMS`` lists them with units,
defaults and limits). :func:`build_scenario` turns such a dict into the room, the obstacles' scripted
paths, the robot's start pose and speed and the odometry noise; the evaluation (``vipsm-robot eval``)
and the daemon's ``sim`` command both build their worlds through it, from CLI flags or from a TOML
file (:func:`load_scenario_file`).

The paper's experiments (Lee et al. 2013) fix the room (4.9 m x 8.0 m, walls on three sides), the
robot's speed (0.20 m/s, straight ahead), the obstacle (a 0.80 m cylinder at 0.15 m/s that starts 5 s
after the robot) and the angle of its path to the robot's (45 deg approaching / 90 deg crossing). It is
silent on start positions and duration; this module fixes them as follows:

* Room: x in [0, 8.0] m along the robot's path, y in [-2.45, 2.45] m; walls on the left (y = +2.45),
  the right (y = -2.45) and at the far end (x = 8.0); the end behind the robot (x = 0) is open.
* Robot: starts at (0.6, 0.0) heading +x, commanded ``robot_speed_mps`` from t = 0 (the base's
  acceleration limit applies), for ``duration_s`` = 30 s (300 estimator cycles at 0.1 s).
* Obstacle: its path is a straight line at ``crossing_deg`` to the robot's path, moving towards the
  robot (velocity (-cos a, -sin a) * speed: at 90 deg it crosses from left to right, at 0 deg it comes
  head-on on a parallel lane), placed so that the obstacle's centre passes ``closest_approach_m``
  (1.0 m) from the robot's centre at ``closest_approach_time_s`` (17 s), after crossing in front of the
  robot. With these values the obstacle is 3-4 m ahead when it starts at 5 s, crosses the robot's path
  about 1.5 m ahead of the laser (scenario 2), comes within 0.6 m of the robot's body and, near the
  closest approach, covers 40-55 deg of the scan (160-220 of 1081 beams), which is what pulls plain PSM
  off. It stands still where its path leaves the room (0.05 m from a wall), and a path that would
  start outside the room starts where it enters it (later than ``obstacle_start_s`` if need be).
* ``obstacles`` > 1: obstacle k (k >= 1) is the mirror image (coming from the other side) of the first,
  with its closest approach 3 s later per k (later still if it would touch an earlier obstacle).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hil_fakes.wheel_odometry import OdometryNoise

from .camera_effects import IDEAL_CAMERA, CameraEffects
from .clutter import Clutter, box, furnish
from .geometry import Gait, ObstaclePath, RigidBox, Wall
from .laser_effects import IDEAL_LASER, LaserEffects
from .pedestrians import PEDESTRIAN_DATA_DIR, RecordedPath, TrajectoryFileError, fitted_waypoints, load_paths
from .scenes import with_walk_profile

ROOM_LENGTH_M = 8.0
ROOM_WIDTH_M = 4.9
ROBOT_START = (0.6, 0.0, 0.0)
#: Pioneer 3-DX half diagonal (width 425 mm, length 511 mm): the robot's bounding radius
ROBOT_RADIUS_M = 0.33
#: side of the ``box_in_path_x_m`` box (a cardboard box, as in the clutter)
BOX_IN_PATH_M = 0.5
#: clearance kept between an obstacle and a wall at the ends of its path
WALL_MARGIN_M = 0.05
#: base odometry noise; ``odom_noise`` scales all of it (0 = perfect odometry)
BASE_ODOMETRY_NOISE = {
    "scale_error": 0.01,
    "heading_drift_rad_per_m": 0.01,
    "sigma_trans_frac": 0.01,
    "sigma_rot_rad_per_rad": 0.02,
    "sigma_rot_rad_per_m": 0.01,
}


class ScenarioError(ValueError):
    """A bad scenario parameter; ``key`` names it."""

    def __init__(self, key: str, message: str) -> None:
        super().__init__(f"scenario key '{key}': {message}")
        self.key = key


@dataclass(frozen=True)
class Param:
    kind: type
    default: Any
    lo: float | None
    hi: float | None
    unit: str
    help: str


PARAMS: dict[str, Param] = {
    "crossing_deg": Param(float, 90.0, 0.0, 180.0, "deg", "angle between the obstacle's path and the robot's"),
    "obstacle_speed_mps": Param(float, 0.15, 0.01, 2.0, "m/s", "obstacle speed"),
    "obstacle_diameter_m": Param(float, 0.80, 0.10, 2.0, "m", "obstacle (cylinder) diameter"),
    "obstacle_height_m": Param(float, 1.70, 0.10, 3.0, "m", "obstacle height (camera rendering)"),
    "obstacle_start_s": Param(float, 5.0, 0.0, None, "s", "time the obstacle starts moving"),
    "robot_speed_mps": Param(float, 0.20, 0.0, 1.5, "m/s", "commanded forward speed of the robot"),
    "duration_s": Param(float, 30.0, 0.5, 3600.0, "s", "length of the run"),
    "obstacles": Param(int, 1, 0, 4, "", "number of moving obstacles (0: a static room)"),
    "odom_noise": Param(float, 1.0, 0.0, 20.0, "x", "odometry noise scale (0 = perfect, 1 = default model)"),
    "seed": Param(int, 1, 0, 2**32 - 1, "", "seed of every random generator of the world"),
    # individual odometry-noise terms (OdometryNoise fields); when given they replace odom_noise x base
    "odom_scale_error": Param(float, None, -0.5, 0.5, "", "odometry distance scale error (0.01 = +1 %)"),
    "odom_heading_drift_rad_per_m": Param(float, None, -1.0, 1.0, "rad/m", "odometry heading drift"),
    "odom_sigma_trans_frac": Param(float, None, 0.0, 1.0, "m/sqrt(m)", "odometry distance noise"),
    "odom_sigma_rot_rad_per_rad": Param(float, None, 0.0, 1.0, "rad/sqrt(rad)", "odometry heading noise per turn"),
    "odom_sigma_rot_rad_per_m": Param(float, None, 0.0, 1.0, "rad/sqrt(m)", "odometry heading noise per metre"),
    "closest_approach_m": Param(float, 1.0, 0.0, 3.0, "m", "closest distance robot centre - obstacle centre"),
    "closest_approach_time_s": Param(float, 17.0, 0.0, None, "s", "time of the closest approach"),
    # the robot's path
    "robot_yaw_rate_radps": Param(
        float, 0.0, -0.5, 0.5, "rad/s", "commanded turn rate (a curve) from robot_turn_start_s"
    ),
    "robot_turn_start_s": Param(float, 0.0, 0.0, None, "s", "time the robot starts turning"),
    # people
    "person_stride_m": Param(float, 1.3, 0.6, 2.0, "m", "a walking person's stride (two steps)"),
    "person_leg_diameter_m": Param(float, 0.12, 0.06, 0.25, "m", "leg (shin) diameter at the laser's height"),
    "step_aside_m": Param(float, 0.0, -2.0, 2.0, "m", "head-on walker: sidestep (left +) when step_aside_gap_m away"),
    "step_aside_gap_m": Param(float, 2.5, 1.0, 6.0, "m", "head-on walker: distance to the robot at the sidestep"),
    "person_path_id": Param(int, 0, 0, None, "", "recorded pedestrian id in person_path_source (0: the first usable)"),
    # the hard people scenes (issue 29; hil_fakes/world/scenes.py)
    "walk_accel_s": Param(float, 0.0, 0.0, 2.0, "s", "a walker's time to reach its speed from standing and to "
                          "stop (0: at once; 0.6 is one step)"),
    "stop_at_fraction": Param(float, 0.0, 0.0, 0.95, "", "the walker stops at this fraction of its path (0: never)"),
    "stop_duration_s": Param(float, 3.0, 0.0, 60.0, "s", "how long a stopping walker stands"),
    "companion_offset_m": Param(float, 0.0, 0.0, 2.0, "m", "a second person beside the first walker, body "
                                "centres this far apart across the walking direction (0: none)"),
    "cart_length_m": Param(float, 0.0, 0.0, 1.5, "m", "the first walker pushes a cart this long (0: none)"),
    "cart_width_m": Param(float, 0.5, 0.2, 1.0, "m", "the cart's width"),
    "crowd_walkers": Param(int, 7, 1, 10, "", "scene crowd: recorded walkers (plus the first one's companion)"),
    "crowd_spacing_s": Param(float, 1.2, 0.3, 10.0, "s", "scene crowd: time between the walkers' closest approaches"),
    "wall_gap_m": Param(float, 0.2, 0.05, 1.5, "m", "scene along_wall: the wall to the nearer leg's surface"),
    "door_hinge_x_m": Param(float, 5.0, 2.5, ROOM_LENGTH_M - 0.5, "m", "scene door: the hinge's x in the left wall "
                            "(the doorway's far side)"),
    "door_width_m": Param(float, 0.9, 0.6, 1.2, "m", "scene door: the leaf's width"),
    "door_open_s": Param(float, 6.0, 0.0, None, "s", "scene door: the door starts opening"),
    "door_close_s": Param(float, 12.0, 0.0, None, "s", "scene door: the door starts closing (0: stays open)"),
    "door_swing_s": Param(float, 1.5, 0.3, 10.0, "s", "scene door: one swing's duration (90 deg)"),
    "lights_off_s": Param(float, 0.0, 0.0, None, "s", "the room's lights go off (0: never)"),
    "lights_on_s": Param(float, 0.0, 0.0, None, "s", "the lights come on again (0: never)"),
    "lights_off_level": Param(float, 1.0 / 3.0, 0.05, 1.0, "", "light level with the lights off (the camera's gain "
                              "and noise rise by its inverse)"),
    # static clutter
    "clutter": Param(int, 0, 0, 3, "", "furniture: 0 none, 1-3 chairs, tables, boxes, a bin, a post per level"),
    "box_in_path_x_m": Param(
        float, 0.0, 0.0, ROOM_LENGTH_M - 0.5, "m", "a 0.5 m box standing on the robot's path, its centre at this x "
        "(the robot starts at 0.6 m; 0: none): what the protective field must stop for"
    ),
    # the realistic world's effects (ignored by the ideal world); defaults from datasheets and physics
    "laser_divergence_deg": Param(float, 0.3, 0.0, 2.0, "deg", "UTM-30LX beam divergence [?] (0.25-0.4)"),
    "laser_echo_separation_m": Param(float, 1.1, 0.0, 10.0, "m", "range apart at which two echoes are "
                                     "resolved (pulse std x 2): closer ones merge into a mixed pixel"),
    "laser_noise_scale": Param(float, 1.0, 0.0, 10.0, "x", "range noise scale: 1 = the measured UTM-30LX "
                               "(2.2 mm + 0.7 mm/m), 3 = the datasheet's +-30 mm read as 3 sigma at 1-3 m"),
    "laser_dropout_prob": Param(float, 0.001, 0.0, 0.5, "", "random no-return probability per beam"),
    "laser_spurious_prob": Param(float, 2e-4, 0.0, 0.5, "", "spurious short return probability per beam"),
    "laser_grazing_limit_deg": Param(float, 78.0, 45.0, 90.0, "deg", "no return beyond this incidence"),
    "camera_k1": Param(float, -0.15, -0.5, 0.5, "", "radial distortion k1 (barrel < 0)"),
    "camera_k2": Param(float, 0.02, -0.5, 0.5, "", "radial distortion k2"),
    "camera_pp_offset_px": Param(float, 3.0, -20.0, 20.0, "px", "principal point offset (x; y is -2/3 of it)"),
    "camera_mount_yaw_deg": Param(float, 0.4, -5.0, 5.0, "deg", "camera mount yaw error"),
    "camera_fps": Param(float, 25.0, 1.0, 60.0, "1/s", "camera frame rate (its own free-running clock)"),
    "camera_clock_ppm": Param(float, 60.0, -1000.0, 1000.0, "ppm", "camera clock rate error"),
    "camera_latency_min_s": Param(float, 0.04, 0.0, 1.0, "s", "capture-to-delivery latency, lower bound"),
    "camera_latency_max_s": Param(float, 0.10, 0.0, 1.0, "s", "capture-to-delivery latency, upper bound"),
    "camera_exposure_s": Param(float, 1.0 / 60.0, 0.0, 0.1, "s", "exposure time (motion blur)"),
    "camera_exposure_drift": Param(float, 0.03, 0.0, 0.3, "", "auto-exposure gain drift amplitude"),
    "camera_vignetting": Param(float, 0.25, 0.0, 0.8, "", "brightness fall-off in the corners"),
    "camera_jpeg_quality": Param(int, 65, 1, 100, "", "JPEG quality of the frames"),
    "camera_poweron_pan_deg": Param(float, 12.0, -170.0, 170.0, "deg", "pan the camera powers on with (sim)"),
    "camera_poweron_zoom": Param(int, 0x0600, 0, 0x4000, "", "zoom position the camera powers on with (sim)"),
    "odom_wheelbase_error": Param(float, 0.02, -0.2, 0.2, "", "effective wheelbase error (rotation scale)"),
    "sip_delay_s": Param(float, 0.03, 0.0, 0.1, "s", "encoder sampling to SIP sending"),
}

#: parameters that take one of a few words
CHOICES: dict[str, tuple[str, ...]] = {
    "world": ("realistic", "ideal"),
    "obstacle_kind": ("cylinder", "person"),
    #: "scripted": straight lines; else the shape of a real recorded path (ETH/UCY) between the same ends
    "person_path_source": ("scripted", "eth_hotel", "ucy_zara01"),
    #: the bodies' layout: crossings (the paper's), a crowd, a walker along a wall, a door (scenes.py)
    "scene": ("crossing", "crowd", "along_wall", "door"),
    #: which targets the evaluation checks: issue 11's (the first realistic suite) or issue 29's (the hard
    #: people scenes: every person located >= 90 % of its time in view, ...; app/evaluation/metrics.py)
    "targets": ("issue11", "issue29"),
}
#: the realistic world's effect parameters: the ideal world ignores them
EFFECT_KEYS = tuple(k for k in PARAMS if k.startswith(("laser_", "camera_"))) + ("odom_wheelbase_error", "sip_delay_s")

PAPER_SCENARIOS: dict[str, dict[str, Any]] = {
    "1": {"name": "scenario1_45deg", "crossing_deg": 45.0},
    "2": {"name": "scenario2_90deg", "crossing_deg": 90.0},
}


@dataclass(frozen=True)
class Scenario:
    name: str
    params: dict[str, Any]
    walls: tuple[Wall, ...]
    #: the moving bodies: cylinders and people (ObstaclePath), carts and doors (RigidBox)
    obstacles: tuple[ObstaclePath | RigidBox, ...]
    robot_start: tuple[float, float, float]
    robot_speed_mps: float
    duration_s: float
    odometry_noise: OdometryNoise
    seed: int
    notes: tuple[str, ...] = field(default_factory=tuple)
    #: "realistic" or "ideal"
    world: str = "ideal"
    clutter: Clutter = field(default_factory=Clutter)
    laser_effects: LaserEffects = IDEAL_LASER
    camera_effects: CameraEffects = IDEAL_CAMERA
    #: the controller samples its encoders this long before it sends a SIP
    sip_delay_s: float = 0.0
    #: odometry in ARCOS integer units (mm, 2 pi / 4096 rad)
    odom_quantize: bool = False
    robot_yaw_rate_radps: float = 0.0
    robot_turn_start_s: float = 0.0
    #: (pan_deg, zoom position) the fake camera powers on with: the daemon must set its own
    camera_poweron: tuple[float, int] = (0.0, 0)

    def command_at(self, t_s: float) -> tuple[float, float]:
        """The velocity command (v_mps, w_radps) the scenario's driver gives at scenario time ``t_s``."""
        w = self.robot_yaw_rate_radps if t_s >= self.robot_turn_start_s else 0.0
        return self.robot_speed_mps, w

    def static_footprints(self) -> list[tuple[float, float, float, str]]:
        """(x_m, y_m, radius_m, kind) of every piece of furniture (for the evaluation's reports)."""
        return self.clutter.footprints()


def default_params() -> dict[str, Any]:
    return {**{key: p.default for key, p in PARAMS.items()}, **{key: ch[0] for key, ch in CHOICES.items()}}


def validate_params(raw: dict[str, Any]) -> dict[str, Any]:
    """Defaults overlaid with ``raw``, type-checked and range-checked; unknown keys are errors."""
    out: dict[str, Any] = {"name": "custom", **default_params()}
    for key, value in raw.items():
        if key == "name":
            if not isinstance(value, str) or not value:
                raise ScenarioError(key, f"must be a non-empty string, got {value!r}")
            out[key] = value
            continue
        if key in CHOICES:
            if value not in CHOICES[key]:
                raise ScenarioError(key, f"must be one of {', '.join(CHOICES[key])}, got {value!r}")
            out[key] = value
            continue
        spec = PARAMS.get(key)
        if spec is None:
            raise ScenarioError(key, f"unknown key (known: name, {', '.join([*CHOICES, *PARAMS])})")
        if value is None and spec.default is None:
            out[key] = None  # optional term left unset
            continue
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ScenarioError(key, f"must be a number, got {value!r}")
        if spec.kind is int:
            if isinstance(value, float) and not value.is_integer():
                raise ScenarioError(key, f"must be an integer, got {value!r}")
            value = int(value)
        else:
            value = float(value)
            if not math.isfinite(value):
                raise ScenarioError(key, f"must be finite, got {value!r}")
        if spec.lo is not None and value < spec.lo:
            raise ScenarioError(key, f"must be >= {spec.lo}{' ' + spec.unit if spec.unit else ''}, got {value}")
        if spec.hi is not None and value > spec.hi:
            raise ScenarioError(key, f"must be <= {spec.hi}{' ' + spec.unit if spec.unit else ''}, got {value}")
        out[key] = value
    if out["person_path_source"] != "scripted" and out["obstacle_kind"] != "person":
        raise ScenarioError("person_path_source", "a recorded path is walked by a person: needs obstacle_kind person")
    if out["lights_on_s"] and out["lights_on_s"] <= out["lights_off_s"]:
        raise ScenarioError("lights_on_s", "must be after lights_off_s (or 0: never)")
    if out["door_close_s"] and out["door_close_s"] < out["door_open_s"] + out["door_swing_s"]:
        raise ScenarioError("door_close_s", "must be at least door_swing_s after door_open_s (or 0: never)")
    legs_m = 2 * (Gait().hip_halfwidth_m + out["person_leg_diameter_m"] / 2)
    if 0 < out["companion_offset_m"] < legs_m:
        raise ScenarioError("companion_offset_m", f"{out['companion_offset_m']} m: the two people's legs would "
                            f"overlap; 0 (none) or >= {legs_m:.2f} m")
    if out["scene"] in ("crowd", "along_wall") and out["obstacle_kind"] != "person":
        raise ScenarioError("scene", f"scene {out['scene']} is walked by people: needs obstacle_kind person")
    if out["camera_latency_min_s"] > out["camera_latency_max_s"]:
        raise ScenarioError("camera_latency_min_s", "must be <= camera_latency_max_s")
    min_ca = body_diameter_m(out) / 2 + ROBOT_RADIUS_M + 0.05
    if out["closest_approach_m"] < min_ca:
        raise ScenarioError(
            "closest_approach_m",
            f"{out['closest_approach_m']} m would hit the robot: needs >= {min_ca:.2f} m for this obstacle diameter",
        )
    return out


def body_diameter_m(prm: dict[str, Any]) -> float:
    """The moving body's diameter: the cylinder's, or a person's body (shoulders)."""
    return 2 * Gait().body_radius_m if prm.get("obstacle_kind") == "person" else prm["obstacle_diameter_m"]


def paper_params(which: str, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Parameters of the paper's scenario ``which`` ("1" or "2") with optional overrides."""
    if which not in PAPER_SCENARIOS:
        raise ScenarioError("scenario", f"unknown scenario {which!r} (known: {', '.join(PAPER_SCENARIOS)})")
    return {**PAPER_SCENARIOS[which], **(overrides or {})}


def load_scenario_file(path: str | Path) -> dict[str, Any]:
    """Read a TOML scenario file: flat keys from ``PARAMS`` plus ``name`` (or the same under [scenario])."""
    p = Path(path)
    try:
        with p.open("rb") as fh:
            data = tomllib.load(fh)
    except OSError as exc:
        raise ScenarioError("scenario_file", f"cannot read {p}: {exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError("scenario_file", f"{p} is not valid TOML: {exc}") from exc
    if set(data) == {"scenario"} and isinstance(data["scenario"], dict):
        data = data["scenario"]
    data.setdefault("name", p.stem)
    validate_params(data)
    return data


def paper_room() -> tuple[Wall, ...]:
    half = ROOM_WIDTH_M / 2
    return (
        Wall(0.0, half, ROOM_LENGTH_M, half, reflectivity=0.65),  # left
        Wall(ROOM_LENGTH_M, half, ROOM_LENGTH_M, -half, reflectivity=0.55),  # far end
        Wall(ROOM_LENGTH_M, -half, 0.0, -half, reflectivity=0.6),  # right
    )


def robot_x_at(t_s: float, x0_m: float, speed_mps: float, accel_mps2: float = 0.3) -> float:
    """Robot centre x at t_s when commanded ``speed_mps`` from t = 0 under the acceleration limit."""
    if speed_mps <= 0:
        return x0_m
    t_acc = speed_mps / accel_mps2
    if t_s <= t_acc:
        return x0_m + 0.5 * accel_mps2 * t_s * t_s
    return x0_m + speed_mps * t_s - speed_mps * speed_mps / (2 * accel_mps2)


def _box_interval(p: np.ndarray, v: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[float, float]:
    """Times [t_in, t_out] (relative) where p + v*t lies inside the box [lo, hi]; empty -> (inf, -inf)."""
    t_in, t_out = -math.inf, math.inf
    for k in range(2):
        if abs(v[k]) < 1e-12:
            if not lo[k] <= p[k] <= hi[k]:
                return math.inf, -math.inf
            continue
        a, b = (lo[k] - p[k]) / v[k], (hi[k] - p[k]) / v[k]
        t_in, t_out = max(t_in, min(a, b)), min(t_out, max(a, b))
    return t_in, t_out


def _obstacle_path(prm: dict[str, Any], side: float, t_ca: float, key: str) -> ObstaclePath:
    a = math.radians(prm["crossing_deg"])
    vo = prm["obstacle_speed_mps"] * np.array([-math.cos(a), -side * math.sin(a)])
    vr = np.array([prm["robot_speed_mps"], 0.0])
    u = vo - vr
    nu = float(np.hypot(*u))
    if nu < 1e-6:
        raise ScenarioError(key, "the obstacle would move exactly with the robot and never approach it")
    # perpendicular to the relative velocity, on the side that makes the obstacle pass in front
    n = side * np.array([-u[1], u[0]]) / nu
    if abs(u[1]) < 1e-9:  # parallel lanes: pass on the right (left when mirrored)
        n = np.array([0.0, -side])
    x0, y0, _ = ROBOT_START
    p_ca = np.array([robot_x_at(t_ca, x0, prm["robot_speed_mps"]), y0]) + prm["closest_approach_m"] * n
    r = body_diameter_m(prm) / 2
    lo = np.array([r + WALL_MARGIN_M, -ROOM_WIDTH_M / 2 + r + WALL_MARGIN_M])
    hi = np.array([ROOM_LENGTH_M - r - WALL_MARGIN_M, ROOM_WIDTH_M / 2 - r - WALL_MARGIN_M])
    t_in, t_out = _box_interval(p_ca, vo, lo, hi)
    if not t_in <= 0.0 <= t_out:
        raise ScenarioError(
            key,
            f"the closest approach at t = {t_ca:.1f} s would be at ({p_ca[0]:.2f}, {p_ca[1]:.2f}) m, outside the room",
        )
    t_move = max(prm["obstacle_start_s"], t_ca + t_in)
    t_end = t_ca + t_out
    if t_end <= t_move:
        raise ScenarioError(key, "the obstacle's path inside the room ends before it starts moving")
    p_start = p_ca + vo * (t_move - t_ca)
    p_end = p_ca + vo * (t_end - t_ca)
    waypoints = [(float(p_start[0]), float(p_start[1])), (float(p_end[0]), float(p_end[1]))]
    if prm["step_aside_m"] != 0.0:
        waypoints = _with_sidestep(prm, waypoints, t_move, float(lo[1]), float(hi[1]))
    if prm["person_path_source"] == "scripted":
        return _body(prm, tuple(waypoints), float(t_move))
    body = _body(prm, _recorded_waypoints(prm, waypoints[0], waypoints[-1], lo, hi), float(t_move))
    t = np.linspace(body.start_s, body.end_s, max(2, int((body.end_s - body.start_s) * 20)))
    xy = body.positions(t)
    robot_x = np.array([robot_x_at(float(ti), ROBOT_START[0], prm["robot_speed_mps"]) for ti in t])
    gap_m = np.hypot(xy[:, 0] - robot_x, xy[:, 1] - ROBOT_START[1])
    if float(np.min(gap_m)) < body.radius_m + ROBOT_RADIUS_M + 0.05:
        raise ScenarioError("person_path_id", f"pedestrian {prm['person_path_id']}'s fitted path would hit the robot")
    return body


@functools.lru_cache(maxsize=4)
def _recorded(source: str) -> dict[int, RecordedPath]:
    """The recorded pedestrians of ``source`` (read once per process; the files are read-only data)."""
    try:
        return load_paths(PEDESTRIAN_DATA_DIR / f"{source}.csv", min_samples=10)
    except TrajectoryFileError as exc:
        raise ScenarioError("person_path_source", str(exc)) from exc


def _recorded_waypoints(
    prm: dict[str, Any], start: tuple[float, float], end: tuple[float, float], lo: np.ndarray, hi: np.ndarray
) -> tuple[tuple[float, float], ...]:
    """The chosen recorded pedestrian's path shape between the scripted path's ends (inside the room)."""
    key = "person_path_source"
    paths = _recorded(prm[key])
    usable = sorted(pid for pid, p in paths.items() if float(np.hypot(*(p.xy_m[-1] - p.xy_m[0]))) >= 2.0)
    pid = prm["person_path_id"] or (usable[0] if usable else -1)
    if pid not in usable:
        raise ScenarioError("person_path_id", f"no pedestrian {pid} walking >= 2 m in {prm[key]} (e.g. {usable[:5]})")
    pts = fitted_waypoints(paths[pid], start, end)
    arr = np.asarray(pts)
    if np.any(arr < lo - 1e-9) or np.any(arr > hi + 1e-9):
        raise ScenarioError("person_path_id", f"pedestrian {pid}'s path leaves the room when fitted to this crossing")
    return pts


def _body(prm: dict[str, Any], waypoints: tuple[tuple[float, float], ...], start_s: float) -> ObstaclePath:
    if prm["obstacle_kind"] == "person":
        gait = Gait(stride_m=prm["person_stride_m"], leg_radius_m=prm["person_leg_diameter_m"] / 2)
        return ObstaclePath(
            gait.body_radius_m,
            waypoints,
            prm["obstacle_speed_mps"],
            start_s,
            gait.height_m,
            reflectivity=0.4,
            gait=gait,
        )
    return ObstaclePath(
        prm["obstacle_diameter_m"] / 2, waypoints, prm["obstacle_speed_mps"], start_s, prm["obstacle_height_m"]
    )


def _with_sidestep(
    prm: dict[str, Any], waypoints: list[tuple[float, float]], t_move: float, y_lo: float, y_hi: float
) -> list[tuple[float, float]]:
    """Insert a sidestep of ``step_aside_m`` (a 45 deg diagonal) where the walker is
    ``step_aside_gap_m`` ahead of the robot, then keep walking parallel to the old line."""
    (x0, y0), (x1, y1) = waypoints
    d = np.array([x1 - x0, y1 - y0])
    length = float(np.hypot(*d))
    u = d / max(length, 1e-9)
    s_m = 0.0
    for k in range(1, 1000):
        s_m = min(length, k * 0.02)
        t = t_move + s_m / prm["obstacle_speed_mps"]
        gap = math.hypot(x0 + u[0] * s_m - robot_x_at(t, ROBOT_START[0], prm["robot_speed_mps"]), y0 + u[1] * s_m)
        if gap <= prm["step_aside_gap_m"] or s_m >= length:
            break
    side = np.array([-u[1], u[0]]) * prm["step_aside_m"]
    a = np.array([x0, y0]) + u * s_m
    b = a + u * abs(prm["step_aside_m"]) + side
    b[1] = min(max(b[1], y_lo), y_hi)
    end = np.array([x1, y1]) + (b - a - u * abs(prm["step_aside_m"]))
    end[1] = b[1]
    return [(x0, y0), (float(a[0]), float(a[1])), (float(b[0]), float(b[1])), (float(end[0]), float(end[1]))]


def _min_separation(a: ObstaclePath, b: ObstaclePath, t_end: float, inside: bool = False) -> float:
    """Closest distance of two bodies' centres over [0, t_end] (``inside``: only while both are in the room)."""
    t = np.linspace(0.0, t_end, max(2, int(t_end * 20)))
    pa, pb = a.positions(t), b.positions(t)
    d = np.hypot(*(pa - pb).T)
    if inside:
        d = np.where(_in_room(pa) & _in_room(pb), d, np.inf)
    return float(np.min(d))


def _in_room(xy: np.ndarray) -> np.ndarray:
    return (np.abs(xy[:, 1]) < ROOM_WIDTH_M / 2) & (xy[:, 0] > 0.0) & (xy[:, 0] < ROOM_LENGTH_M)


def _crossings(prm: dict[str, Any]) -> tuple[list[ObstaclePath], list[str]]:
    """The paper's crossing bodies: obstacle 0 at ``crossing_deg``, obstacle k its mirror image 3 s later
    per k (later still until no two bodies come within 0.1 m)."""
    obstacles: list[ObstaclePath] = []
    notes: list[str] = []
    for k in range(prm["obstacles"]):
        side = 1.0 if k % 2 == 0 else -1.0
        t_ca = prm["closest_approach_time_s"] + 3.0 * k
        for _ in range(40):
            path = _obstacle_path(prm, side, t_ca, "closest_approach_time_s" if k == 0 else "obstacles")
            horizon = max(prm["duration_s"], t_ca + 1.0)
            clear = all(
                _min_separation(path, other, horizon) > path.radius_m + other.radius_m + 0.1 for other in obstacles
            )
            if clear:
                break
            t_ca += 1.0
        else:
            raise ScenarioError("obstacles", f"no collision-free path found for obstacle {k + 1}")
        if path.start_s > prm["obstacle_start_s"] + 1e-9:
            notes.append(f"obstacle {k + 1} starts moving at {path.start_s:.2f} s (its path enters the room then)")
        obstacles.append(path)
    return obstacles, notes


def _bodies(prm: dict[str, Any]) -> tuple[list[Any], list[str], tuple[Wall, ...]]:
    """The scene's moving bodies (walkers, cylinders, a cart, a door), notes, and its walls."""
    from . import scenes

    room = paper_room()
    if prm["scene"] == "door":
        wall_y = ROOM_WIDTH_M / 2
        bodies: list[Any] = [scenes.door(prm, wall_y)]
        return bodies, [], scenes.doorway_walls(prm, room, wall_y)
    if prm["scene"] == "crowd":
        bodies, notes = _crowd(prm)
    elif prm["scene"] == "along_wall":
        bodies, notes = [_along_wall(prm)], []
    else:
        bodies, notes = _crossings(prm)
    if bodies and prm["cart_length_m"] > 0:
        try:
            bodies[0] = scenes.shortened_for_cart(bodies[0], prm["cart_length_m"])
        except ValueError as exc:
            raise ScenarioError("cart_length_m", str(exc)) from exc
    if prm["scene"] != "crowd":  # a crowd's walkers have theirs
        bodies = [scenes.with_walk_profile(b, prm) if b.gait is not None else b for b in bodies]
    if bodies and prm["companion_offset_m"] > 0:
        bodies.insert(1, scenes.companion(bodies[0], prm["companion_offset_m"]))
    if bodies and prm["cart_length_m"] > 0:
        bodies.append(scenes.cart(bodies[0], prm["cart_length_m"], prm["cart_width_m"], prm["duration_s"]))
    if prm["scene"] != "crossing" or any(prm[k] > 0 for k in _WALKER_KEYS):
        for k, b in enumerate(bodies):  # the paper's crossings are placed clear by construction
            _check_in_room(b, prm, k)
    return bodies, notes, room


#: the keys that change how a crossing's walker walks (a stop, a companion, a cart)
_WALKER_KEYS = ("walk_accel_s", "stop_at_fraction", "companion_offset_m", "cart_length_m")


def _check_in_room(body: Any, prm: dict[str, Any], k: int) -> None:
    """Every body stays inside the room (or leaves it through its open end) and clear of the robot's
    commanded path (the robot's radius + the body's + 5 cm)."""
    if _robot_gap_m(body, prm) < body.radius_m + ROBOT_RADIUS_M + 0.05:
        raise ScenarioError("scene", f"body {k + 1} ({body.kind}) would hit the robot")
    path = robot_path(prm, 0.05)
    xy = body.positions(path[:, 0])
    if body.kind == "door" or prm["scene"] == "crowd":  # a crowd comes and goes through the walls' doorways
        return
    lim = ROOM_WIDTH_M / 2 - body.radius_m + 1e-6
    if np.any(np.abs(xy[:, 1]) > lim) or np.any(xy[:, 0] > ROOM_LENGTH_M - body.radius_m + 1e-6):
        raise ScenarioError("scene", f"body {k + 1} ({body.kind}) leaves the room through a wall")


def _robot_gap_m(body: Any, prm: dict[str, Any]) -> float:
    """Closest distance between the body's centre and the robot's on its commanded path."""
    path = robot_path(prm, 0.05)
    xy = body.positions(path[:, 0])
    return float(np.min(np.hypot(xy[:, 0] - path[:, 1], xy[:, 1] - path[:, 2])))


def _crowd(prm: dict[str, Any]) -> tuple[list[ObstaclePath], list[str]]:
    """``crowd_walkers`` recorded pedestrians crossing at spread angles, each at its recorded mean speed,
    closest approaches ``crowd_spacing_s`` apart, no two bodies (the companion aside) closer than 0.1 m."""
    from .scenes import CROWD_ANGLES_DEG, CROWD_APPROACH_M, CROWD_SPEED_MPS

    source = prm["person_path_source"] if prm["person_path_source"] != "scripted" else "eth_hotel"
    paths = _recorded(source)
    ids = sorted(pid for pid, p in paths.items() if float(np.hypot(*(p.xy_m[-1] - p.xy_m[0]))) >= 2.0)
    ids = ids[ids.index(prm["person_path_id"]):] if prm["person_path_id"] in ids else ids
    walkers: list[ObstaclePath] = []
    chosen: list[int] = []
    horizon = prm["duration_s"]
    pad = prm["companion_offset_m"]
    for k in range(prm["crowd_walkers"]):
        for pid, shift in ((pid, 0.6 * j) for j in range(9) for pid in list(ids[:20])):
            t_ca = prm["closest_approach_time_s"] + prm["crowd_spacing_s"] * k + shift
            speed = float(np.clip(paths[pid].mean_speed_mps(), *CROWD_SPEED_MPS))
            one = {**prm, "person_path_source": source, "person_path_id": pid, "obstacle_speed_mps": speed,
                   "crossing_deg": CROWD_ANGLES_DEG[k % len(CROWD_ANGLES_DEG)],
                   "closest_approach_m": CROWD_APPROACH_M[k % len(CROWD_APPROACH_M)]}
            try:
                path = _through_doorways(_obstacle_path(one, 1.0 if k % 2 == 0 else -1.0, t_ca, "crowd_walkers"))
            except ScenarioError:
                continue
            path = with_walk_profile(path, prm)
            if _robot_gap_m(path, prm) < path.radius_m + ROBOT_RADIUS_M + 0.05:
                continue
            gaps = [_min_separation(path, w, horizon, inside=True) - path.radius_m - w.radius_m
                    - (pad if j == 0 else 0.0) for j, w in enumerate(walkers)]
            if all(g > 0.1 for g in gaps):
                walkers.append(path)
                chosen.append(pid)
                ids.remove(pid)
                break
        else:
            raise ScenarioError("crowd_walkers", f"no recorded path fits walker {k + 1} clear of the others")
    speeds = [round(w.speed_mps, 2) for w in walkers]
    return walkers, [f"crowd: {source} pedestrians {chosen} walked at {speeds} m/s"]


#: a crowd's walkers come from and go to this far behind the walls (through doorways the laser does not
#: resolve: the wall is drawn unbroken), so that nobody waits inside the room for their turn
DOORWAY_DEPTH_M = 1.0


def _through_doorways(path: ObstaclePath) -> ObstaclePath:
    """``path`` extended ``DOORWAY_DEPTH_M`` beyond both ends (out through the wall it ends at), starting
    that much earlier: the walker comes in from outside the room and leaves it."""
    pts = np.asarray(path.waypoints, float)
    u0 = (pts[1] - pts[0]) / max(float(np.hypot(*(pts[1] - pts[0]))), 1e-9)
    u1 = (pts[-1] - pts[-2]) / max(float(np.hypot(*(pts[-1] - pts[-2]))), 1e-9)
    out = np.vstack([pts[0] - DOORWAY_DEPTH_M * u0, pts, pts[-1] + DOORWAY_DEPTH_M * u1])
    return dataclasses.replace(path, waypoints=tuple((float(x), float(y)) for x, y in out),
                               start_s=max(0.0, path.start_s - DOORWAY_DEPTH_M / path.speed_mps))


def _along_wall(prm: dict[str, Any]) -> ObstaclePath:
    """A person walking along the left wall towards the robot and out of the open end, the nearer leg's
    surface ``wall_gap_m`` from the wall (a straight line: the wall forces one)."""
    gait = Gait(stride_m=prm["person_stride_m"], leg_radius_m=prm["person_leg_diameter_m"] / 2)
    y = ROOM_WIDTH_M / 2 - prm["wall_gap_m"] - gait.leg_radius_m - gait.hip_halfwidth_m
    if y + gait.body_radius_m > ROOM_WIDTH_M / 2 + 0.15:
        raise ScenarioError("wall_gap_m", "the walker's shoulders would be in the wall")
    x0 = ROOM_LENGTH_M - gait.body_radius_m - WALL_MARGIN_M
    return ObstaclePath(gait.body_radius_m, ((x0, y), (-1.5, y)), prm["obstacle_speed_mps"], prm["obstacle_start_s"],
                        gait.height_m, reflectivity=0.4, gait=gait)


def build_scenario(raw: dict[str, Any]) -> Scenario:
    """Build a scenario from a dict of parameters (see ``PARAMS``; missing keys take defaults)."""
    prm = validate_params(raw)
    obstacles, notes, room = _bodies(prm)
    realistic = prm["world"] == "realistic"
    k_noise = prm["odom_noise"]
    terms = {key: val * k_noise for key, val in BASE_ODOMETRY_NOISE.items()}
    for key in BASE_ODOMETRY_NOISE:
        if prm.get("odom_" + key) is not None:
            terms[key] = prm["odom_" + key]
    if realistic:
        terms["rot_scale_error"] = prm["odom_wheelbase_error"] * k_noise
    noise = OdometryNoise(**terms, seed=prm["seed"])
    clutter = Clutter()
    if prm["clutter"] > 0:
        rng = np.random.default_rng([prm["seed"], 11])
        half = ROOM_WIDTH_M / 2
        keepout = tuple(
            (*o.waypoints[i], *o.waypoints[i + 1], o.radius_m + 0.3)
            for o in obstacles
            for i in range(len(o.waypoints) - 1)
        )
        clutter = furnish(rng, prm["clutter"], (0.3, ROOM_LENGTH_M), (-half, half), ROBOT_RADIUS_M + 0.45, keepout)
    if prm["box_in_path_x_m"] > 0.0:
        if prm["box_in_path_x_m"] - BOX_IN_PATH_M / 2 <= ROBOT_START[0] + ROBOT_RADIUS_M:
            raise ScenarioError("box_in_path_x_m", "the box would stand on the robot at its start")
        walls = box(prm["box_in_path_x_m"], ROBOT_START[1], 0.0, BOX_IN_PATH_M, 0.6)
        clutter = Clutter(clutter.circles, clutter.walls + tuple(walls))
    return Scenario(
        name=str(prm["name"]),
        params=prm,
        walls=room + clutter.walls,
        obstacles=tuple(obstacles),
        robot_start=ROBOT_START,
        robot_speed_mps=prm["robot_speed_mps"],
        duration_s=prm["duration_s"],
        odometry_noise=noise,
        seed=prm["seed"],
        notes=tuple(notes),
        world=prm["world"],
        clutter=clutter,
        laser_effects=laser_effects(prm) if realistic else IDEAL_LASER,
        camera_effects=camera_effects(prm) if realistic else IDEAL_CAMERA,
        sip_delay_s=prm["sip_delay_s"] if realistic else 0.0,
        odom_quantize=realistic,
        camera_poweron=(prm["camera_poweron_pan_deg"], prm["camera_poweron_zoom"]) if realistic else (0.0, 0),
        robot_yaw_rate_radps=prm["robot_yaw_rate_radps"],
        robot_turn_start_s=prm["robot_turn_start_s"],
    )


def robot_path(prm: dict[str, Any], step_s: float = 0.05) -> np.ndarray:
    """(N, 3) times and centre positions of the commanded robot path: ``robot_speed_mps`` reached
    under the acceleration limit, ``robot_yaw_rate_radps`` from ``robot_turn_start_s``."""
    t = np.arange(0.0, prm["duration_s"] + step_s, step_s)
    x = np.array([robot_x_at(float(ti), 0.0, prm["robot_speed_mps"]) for ti in t])
    ds = np.diff(x, prepend=0.0)  # distance covered per step
    heading = ROBOT_START[2] + prm["robot_yaw_rate_radps"] * np.clip(t - prm["robot_turn_start_s"], 0.0, None)
    px = ROBOT_START[0] + np.cumsum(ds * np.cos(heading))
    py = ROBOT_START[1] + np.cumsum(ds * np.sin(heading))
    return np.stack([t, px, py], axis=1)


def check_robot_path(scenario: Scenario) -> None:
    """The robot's commanded path (``Scenario.command_at``, what ``eval`` drives) stays inside the
    room's walls and off the furniture: a run in which it drives through a wall or a table measures
    nothing. (``sim`` is driven by the daemon's mission, not by these commands.)"""
    prm, clutter = scenario.params, scenario.clutter
    key = "robot_yaw_rate_radps" if prm["robot_yaw_rate_radps"] else "robot_speed_mps"
    half = ROOM_WIDTH_M / 2 - ROBOT_RADIUS_M
    furniture = clutter.footprints()
    for t, x, y in robot_path(prm):
        if x > ROOM_LENGTH_M - ROBOT_RADIUS_M or abs(y) > half:
            raise ScenarioError(key, f"the robot's path reaches a wall at {t:.1f} s ({x:.2f}, {y:.2f}) m: "
                                     "shorten duration_s or change the speed or turn")
        for cx, cy, r, kind in furniture:
            if math.hypot(x - cx, y - cy) < r + ROBOT_RADIUS_M:
                raise ScenarioError(key, f"the robot's path runs into a {kind} at {t:.1f} s ({x:.2f}, {y:.2f}) m")


def laser_effects(prm: dict[str, Any]) -> LaserEffects:
    return LaserEffects(
        divergence_rad=math.radians(prm["laser_divergence_deg"]),
        echo_separation_m=prm["laser_echo_separation_m"],
        dropout_prob=prm["laser_dropout_prob"],
        noise_scale=prm["laser_noise_scale"],
        spurious_prob=prm["laser_spurious_prob"],
        grazing_limit_deg=prm["laser_grazing_limit_deg"],
    )


def camera_effects(prm: dict[str, Any]) -> CameraEffects:
    off = prm["camera_pp_offset_px"]
    return CameraEffects(
        k1=prm["camera_k1"],
        k2=prm["camera_k2"],
        pp_offset_px=(off, -2.0 * off / 3.0),
        mount_yaw_rad=math.radians(prm["camera_mount_yaw_deg"]),
        fps=prm["camera_fps"],
        clock_ppm=prm["camera_clock_ppm"],
        latency_s=(prm["camera_latency_min_s"], prm["camera_latency_max_s"]),
        exposure_s=prm["camera_exposure_s"],
        exposure_drift=prm["camera_exposure_drift"],
        vignetting=prm["camera_vignetting"],
        jpeg_quality=prm["camera_jpeg_quality"],
        lights=tuple(ev for ev in ((prm["lights_off_s"], prm["lights_off_level"]), (prm["lights_on_s"], 1.0))
                     if ev[0] > 0),
    )


def paper_scenario(which: str, overrides: dict[str, Any] | None = None) -> Scenario:
    """The paper's scenario "1" (45 deg approach) or "2" (90 deg crossing), optionally modified."""
    return build_scenario(paper_params(which, overrides))


#: ``eval --scenario realistic``: the realistic world's suite (name -> parameters). People walk at
#: 1.0-1.4 m/s (Bohannon 1997: comfortable gait speed of adults 1.3-1.5 m/s; indoors, slower).
_PERSON = {
    "obstacle_kind": "person",
    "obstacle_speed_mps": 1.2,
    "obstacle_start_s": 2.0,
    "closest_approach_m": 1.2,
    "closest_approach_time_s": 9.0,
    "duration_s": 20.0,
}
REALISTIC_SUITE: dict[str, dict[str, Any]] = {
    "paper1": {"crossing_deg": 45.0},
    "paper2": {"crossing_deg": 90.0},
    "cross_30": {**_PERSON, "crossing_deg": 30.0},
    "cross_60": {**_PERSON, "crossing_deg": 60.0, "obstacle_speed_mps": 1.0},
    "cross_90": {**_PERSON, "crossing_deg": 90.0, "obstacle_speed_mps": 1.4},
    "head_on_step_aside": {
        **_PERSON,
        "crossing_deg": 0.0,
        "obstacle_speed_mps": 1.0,
        "closest_approach_m": 0.65,
        "step_aside_m": 0.9,
        "step_aside_gap_m": 2.5,
        "closest_approach_time_s": 12.0,
    },
    "two_people_opposite": {**_PERSON, "crossing_deg": 90.0, "obstacles": 2, "closest_approach_time_s": 8.0},
    "curve_crossing": {
        **_PERSON,
        "crossing_deg": 90.0,
        "robot_yaw_rate_radps": 0.05,
        "robot_turn_start_s": 1.0,
        "closest_approach_m": 1.5,
    },
    "cylinder_clutter": {"crossing_deg": 45.0, "clutter": 2},
    "static_clutter": {"obstacles": 0, "clutter": 3, "duration_s": 25.0},
    "stand_then_walk": {
        **_PERSON,
        "crossing_deg": 90.0,
        "obstacle_speed_mps": 1.1,
        "obstacle_start_s": 7.0,
        "closest_approach_time_s": 10.5,
        "closest_approach_m": 1.5,
        "duration_s": 18.0,
    },
}
#: the hard people scenes (issue 29, scenes.py): recorded walking paths, starts and stops over one step,
#: checked against issue 29's targets (``targets = "issue29"``)
_HARD = {**_PERSON, "person_path_source": "eth_hotel", "walk_accel_s": 0.6, "targets": "issue29"}
REALISTIC_SUITE.update({
    "crowd": {**_HARD, "scene": "crowd", "crowd_walkers": 7, "companion_offset_m": 0.4, "obstacle_start_s": 0.0,
              "closest_approach_time_s": 5.0, "duration_s": 20.0},
    "stop_and_go": {**_HARD, "crossing_deg": 90.0, "obstacle_speed_mps": 1.1, "obstacle_start_s": 3.0,
                    "stop_at_fraction": 0.3, "stop_duration_s": 3.0, "closest_approach_m": 2.0,
                    "closest_approach_time_s": 8.0, "duration_s": 20.0},
    "wall_hugger": {**_HARD, "scene": "along_wall", "person_path_source": "scripted", "wall_gap_m": 0.2,
                    "obstacle_start_s": 3.0, "duration_s": 15.0},
    "turn_in_place": {**_HARD, "crossing_deg": 90.0, "robot_speed_mps": 0.0, "robot_yaw_rate_radps": 0.5,
                      "robot_turn_start_s": 0.0, "obstacle_start_s": 4.0, "closest_approach_m": 1.5,
                      "closest_approach_time_s": 7.0, "duration_s": 16.0},
    "cart_pusher": {**_HARD, "crossing_deg": 90.0, "obstacle_speed_mps": 1.0, "cart_length_m": 0.8,
                    "cart_width_m": 0.5, "closest_approach_m": 1.8, "closest_approach_time_s": 9.0},
    "lights_off": {"obstacles": 0, "clutter": 2, "duration_s": 25.0, "lights_off_s": 5.0, "lights_on_s": 15.0,
                   "lights_off_level": 1.0 / 3.0, "targets": "issue29"},
    "door_swing": {"scene": "door", "obstacles": 0, "door_open_s": 6.0, "door_close_s": 12.0, "door_swing_s": 1.5,
                   "duration_s": 20.0, "targets": "issue29"},
})
#: each suite scenario's default seed (any other seed works: ``suite_scenario(name, seed)``)
SUITE_SEEDS: dict[str, int] = {name: 101 + k for k, name in enumerate(REALISTIC_SUITE)}


def suite_params(name: str, seed: int | None = None, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    if name not in REALISTIC_SUITE:
        raise ScenarioError("scenario", f"unknown suite scenario {name!r} (known: {', '.join(REALISTIC_SUITE)})")
    prm: dict[str, Any] = {"name": name, **REALISTIC_SUITE[name], "seed": SUITE_SEEDS[name] if seed is None else seed}
    return {**prm, **(overrides or {})}


def suite_scenario(name: str, seed: int | None = None, overrides: dict[str, Any] | None = None) -> Scenario:
    """One scenario of the realistic suite, with its default seed or ``seed``, optionally modified."""
    return build_scenario(suite_params(name, seed, overrides))
