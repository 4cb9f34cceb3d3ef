"""What the fake SNC-RZ50 sees: the renderer interface and a test pattern for runs without a world."""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np


class Renderer(Protocol):
    width_px: int
    height_px: int

    def render(self, t_s: float, pan_rad: float, tilt_rad: float, hfov_rad: float) -> np.ndarray:
        """uint8 BGR (height_px, width_px, 3) image seen at time t_s with the camera panned pan_rad (CCW/left
        positive, relative to the robot's x axis), tilted tilt_rad (up positive), horizontal field of view hfov_rad."""
        ...


class TestPatternRenderer:
    """A world-fixed pattern (stripes every 10 deg of azimuth, a horizon) plus a block moving with time."""

    __test__ = False  # not a pytest class

    def __init__(self, width_px: int = 320, height_px: int = 240) -> None:
        self.width_px = width_px
        self.height_px = height_px

    def render(self, t_s: float, pan_rad: float, tilt_rad: float, hfov_rad: float) -> np.ndarray:
        w, h = self.width_px, self.height_px
        f = (w / 2) / math.tan(hfov_rad / 2)
        u = np.arange(w, dtype=np.float64)
        v = np.arange(h, dtype=np.float64)
        azimuth = pan_rad - np.arctan((u - w / 2) / f)  # left positive
        elevation = tilt_rad - np.arctan((v - h / 2) / f)
        stripe = (np.floor(np.degrees(azimuth) / 10.0).astype(np.int64) & 1).astype(np.uint8)
        sky = elevation > 0
        img = np.empty((h, w, 3), dtype=np.uint8)
        img[:, :, 0] = (60 + 150 * stripe)[None, :]
        img[:, :, 1] = np.where(sky, 180, 80)[:, None]
        img[:, :, 2] = ((np.degrees(azimuth) * 4) % 256).astype(np.uint8)[None, :]
        # a block moving across the image once every 4 s
        bw = max(4, w // 10)
        x0 = int((t_s % 4.0) / 4.0 * (w - bw))
        y0 = h // 3
        img[y0 : y0 + bw, x0 : x0 + bw] = (255, 255, 255)
        return img
