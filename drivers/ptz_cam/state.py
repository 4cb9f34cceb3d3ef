"""The camera's pan/tilt/zoom state: what the VISCA client reads and what frames carry (its own module,
so the client and the frame source both import it and not each other)."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class PtzState:
    """Pan/tilt/zoom in SI (pan left-positive, tilt up-positive) plus the raw device values."""

    pan_rad: float
    tilt_rad: float
    zoom_position: int
    hfov_rad: float
    pan_counts: int
    tilt_counts: int
    stamp_s: float  # host monotonic time of the reading
    moving: bool  # a pan/tilt/zoom command was in flight (or a drive active) at stamp_s

    @property
    def pan_deg(self) -> float:
        return math.degrees(self.pan_rad)

    @property
    def tilt_deg(self) -> float:
        return math.degrees(self.tilt_rad)
