"""The estimator's inputs and outputs. Pure data: numpy arrays and frozen dataclasses, SI units.

These types are the contract between the estimator (``vipsm``), the simulated world
(``hil_fakes.world``), the evaluation and the daemon (``app``). Frames: the robot frame has x
forward, y left, angles counter-clockwise; the world frame is the odometry frame of the first scan
unless the caller says otherwise.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Pose2D:
    x_m: float
    y_m: float
    theta_rad: float

    def as_array(self) -> np.ndarray:
        return np.array([self.x_m, self.y_m, self.theta_rad], dtype=float)


@dataclass(frozen=True)
class Scan:
    """One laser sweep in the laser frame (mounted at ``EstimatorConfig``'s laser pose on the robot).

    ``ranges_m`` holds NaN where the sensor gave no valid return (below DMIN, error codes, no echo),
    never 0. ``bearings_rad`` come from the sensor's own parameters (PP on the UTM-30LX), ascending.
    ``stamp_s`` is the host-clock time of the first beam; beam i was taken at
    ``stamp_s + i * beam_dt_s``.
    """

    ranges_m: np.ndarray
    bearings_rad: np.ndarray
    stamp_s: float
    seq: int = 0
    beam_dt_s: float = 0.0
    intensities: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.ranges_m.shape != self.bearings_rad.shape or self.ranges_m.ndim != 1:
            raise ValueError(
                f"ranges_m {self.ranges_m.shape} and bearings_rad {self.bearings_rad.shape} must be equal 1-D shapes"
            )


@dataclass(frozen=True)
class Odometry:
    """Wheel odometry of the base in its own odometry frame."""

    x_m: float
    y_m: float
    theta_rad: float
    v_mps: float
    w_radps: float
    stamp_s: float

    @property
    def pose(self) -> Pose2D:
        return Pose2D(self.x_m, self.y_m, self.theta_rad)


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels for the image size the frame has."""

    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    width_px: int
    height_px: int
    #: lens distortion (Brown-Conrady, normalised coordinates); 0 = pinhole. Flow points are
    #: undistorted with these before bearings are computed (:mod:`vipsm.distortion`).
    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0

    @property
    def distortion(self) -> tuple[float, float, float, float]:
        return (self.k1, self.k2, self.p1, self.p2)


@dataclass(frozen=True)
class Frame:
    """One camera image with the pan/tilt in force when it was captured.

    ``pan_rad`` is the camera's pan relative to the robot's x axis (counter-clockwise positive,
    i.e. left), ``tilt_rad`` positive up. ``image`` is uint8, grey (H, W) or BGR (H, W, 3).
    """

    image: np.ndarray
    stamp_s: float
    intrinsics: Intrinsics
    pan_rad: float = 0.0
    tilt_rad: float = 0.0
    seq: int = 0


@dataclass(frozen=True)
class Obstacle:
    """A tracked moving obstacle in the world frame."""

    track_id: int
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    radius_m: float
    bearing_min_rad: float
    bearing_max_rad: float
    scan_index_start: int
    scan_index_stop: int  # exclusive
    age_cycles: int = 1
    #: the track's 4x4 covariance of (x_m, y_m, vx_mps, vy_mps), row-major; () = not known
    covariance: tuple[float, ...] = ()
    #: the tracker has seen it as a leg pair (a person)
    person: bool = False


@dataclass(frozen=True)
class Person:
    """A tracked person (walking or standing) in the world frame (:mod:`vipsm.people`)."""

    track_id: int
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    #: position covariance (m^2), row-major 2 x 2: xx, xy, yx, yy
    covariance: tuple[float, float, float, float]
    #: the walking model's probability (the IMM's P(moving))
    p_moving: float
    #: moving with hysteresis: P(moving) reached ``PeopleConfig.moving_on`` and has not fallen below ``moving_off``
    moving: bool
    #: the track's existence probability
    existence: float
    #: the legs seen this cycle (world frame): two, one, or none while coasting
    legs: tuple[tuple[float, float], ...] = ()


@dataclass(frozen=True)
class MatchQuality:
    beams_used: int
    iterations: int
    residual_m: float
    converged: bool


class EstimateFlag(enum.Flag):
    NONE = 0
    FIRST_SCAN = enum.auto()  # nothing to match against yet; pose from odometry
    ODOMETRY_FALLBACK = enum.auto()  # the match was refused; pose from odometry
    NO_FRAME = enum.auto()  # no camera frame: plain PSM for this cycle
    PLAIN_PSM = enum.auto()  # restoration switched off (the baseline)
    OBSTACLE_TOO_LARGE = enum.auto()  # restoration refused: the obstacle covers too much of the scan
    BRIDGE_INVALID = enum.auto()  # a cut segment spanned two surfaces and was invalidated, not bridged
    STALE_FRAME = enum.auto()  # the frame was too old for the scan and was not used
    FRAME_ERROR = enum.auto()  # the frame could not be processed (bad image) and was not used
    #: no odometry and no accepted match this cycle: the pose is the constant-velocity prediction alone
    POSE_UNCERTAIN = enum.auto()
    #: the frame had no earlier frame within the flow's ``max_frame_gap_s`` (the first frame, or frames
    #: further apart than that): no optical flow, so no visual cut this cycle
    NO_FLOW = enum.auto()


@dataclass(frozen=True)
class Estimate:
    stamp_s: float
    pose: Pose2D
    covariance: np.ndarray  # 3x3, (x_m, y_m, theta_rad)
    obstacles: tuple[Obstacle, ...]
    quality: MatchQuality
    flags: EstimateFlag = EstimateFlag.NONE
    restored_indices: tuple[tuple[int, int], ...] = field(default_factory=tuple)  # [start, stop) cut from the scan
    #: every tracked person, walking or standing (``obstacles`` stays the paper's moving obstacles)
    people: tuple[Person, ...] = field(default_factory=tuple)
