"""Lens distortion (Brown-Conrady: radial k1, k2; tangential p1, p2) on normalised image coordinates.

Normalised coordinates are ``x = (u - cx) / fx``, ``y = (v - cy) / fy``; the coefficients are
independent of the image scale. ``distort`` maps ideal (pinhole) coordinates to the lens's,
``undistort`` inverts it by fixed-point iteration (bounded: ``iterations`` steps).
"""

from __future__ import annotations

import numpy as np


def distort(x: np.ndarray, y: np.ndarray, k1: float, k2: float, p1: float, p2: float):
    """Distorted normalised coordinates of ideal ones."""
    r2 = x * x + y * y
    radial = 1.0 + k1 * r2 + k2 * r2 * r2
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return xd, yd


def undistort(xd: np.ndarray, yd: np.ndarray, k1: float, k2: float, p1: float, p2: float, iterations: int = 8):
    """Ideal normalised coordinates of distorted ones (identity when all coefficients are 0)."""
    if k1 == 0.0 and k2 == 0.0 and p1 == 0.0 and p2 == 0.0:
        return xd, yd
    x, y = xd, yd
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1.0 + k1 * r2 + k2 * r2 * r2
        dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        x = (xd - dx) / radial
        y = (yd - dy) / radial
    return x, y
