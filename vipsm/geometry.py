"""2-D rigid-body helpers shared by the estimator modules (SI units, x forward, y left, CCW angles)."""

from __future__ import annotations

import math

import numpy as np

from .types import Pose2D


def wrap_angle(a_rad: float) -> float:
    """The angle folded into [-pi, pi)."""
    return (a_rad + math.pi) % (2.0 * math.pi) - math.pi


def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """a (+) b: the pose b, given in a's frame, expressed in a's parent frame."""
    c, s = math.cos(a.theta_rad), math.sin(a.theta_rad)
    return Pose2D(
        a.x_m + c * b.x_m - s * b.y_m,
        a.y_m + s * b.x_m + c * b.y_m,
        wrap_angle(a.theta_rad + b.theta_rad),
    )


def inverse(a: Pose2D) -> Pose2D:
    """The pose of a's parent frame expressed in a's frame."""
    c, s = math.cos(a.theta_rad), math.sin(a.theta_rad)
    return Pose2D(-c * a.x_m - s * a.y_m, s * a.x_m - c * a.y_m, wrap_angle(-a.theta_rad))


def between(a: Pose2D, b: Pose2D) -> Pose2D:
    """(-a) (+) b: the pose b expressed in a's frame (both given in one common frame)."""
    return compose(inverse(a), b)


def transform_point(pose: Pose2D, x_m: float, y_m: float) -> tuple[float, float]:
    c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
    return pose.x_m + c * x_m - s * y_m, pose.y_m + s * x_m + c * y_m


def scan_points(pose: Pose2D, ranges_m: np.ndarray, bearings_rad: np.ndarray) -> np.ndarray:
    """(k, 2) points of polar returns taken from ``pose``, in ``pose``'s parent frame (NaN stays NaN)."""
    c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
    xl, yl = ranges_m * np.cos(bearings_rad), ranges_m * np.sin(bearings_rad)
    return np.stack([pose.x_m + c * xl - s * yl, pose.y_m + s * xl + c * yl], axis=1)


IDENTITY = Pose2D(0.0, 0.0, 0.0)
