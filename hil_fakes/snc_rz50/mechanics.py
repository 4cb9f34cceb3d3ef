"""The fake SNC-RZ50's mechanics: its specification and the pan, tilt and zoom axes moving in time."""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

# ---------------------------------------------------------------------------------------------
# The camera's mechanics


@dataclass
class FakeCameraSpec:
    """The fake's own model of the RZ50 (fact sheet values; [?] ones are guesses, as on the real camera)."""

    pan_counts_per_deg: float = 14.4
    pan_min_counts: int = -2448  # -170 deg
    pan_max_counts: int = 2448
    tilt_counts_per_deg: float = 14.4  # [?]
    tilt_min_counts: int = -1296  # -90 deg  [?]
    tilt_max_counts: int = 360  # +25 deg  [?]
    pan_speed_max: int = 0x18
    tilt_speed_max: int = 0x14
    max_dps: float = 300.0  # at the maximum speed; linear in the speed value [?]
    zoom_optical_max: int = 0x4000
    zoom_digital_max: int = 0x7AC0
    zoom_full_travel_s: float = 2.0  # wide -> optical tele at the fastest speed [?]
    reset_duration_s: float = 1.5
    vendor: int = 0x0020
    model: int = 0x0510  # [?] not known for the RZ50
    rom_version: int = 0x0100
    sockets: int = 2
    pan_nibbles: int = 4  # 5 emulates the newer BRC/SRG answer layout
    answers_version: bool = True
    width_px: int = 320
    height_px: int = 240
    hfov_wide_deg: float = 54.0
    # magnification by zoom position (Sony 25x block table from the fact sheet, 26x at 0x4000)
    zoom_table: tuple[tuple[int, float], ...] = (
        (0x0000, 1.0), (0x1781, 2.0), (0x213B, 3.0), (0x2752, 4.0), (0x2BB3, 5.0), (0x2F03, 6.0),
        (0x3364, 8.0), (0x362C, 10.0), (0x386A, 12.0), (0x3AFA, 15.0), (0x3DF8, 20.0), (0x4000, 26.0),
    )

    def hfov_rad(self, zoom: float) -> float:
        table = self.zoom_table
        z = min(max(zoom, table[0][0]), table[-1][0])
        mag = table[-1][1]
        for (p0, m0), (p1, m1) in zip(table, table[1:]):
            if p0 <= z <= p1:
                mag = math.exp(math.log(m0) + (z - p0) / (p1 - p0) * (math.log(m1) - math.log(m0)))
                break
        if zoom > self.zoom_optical_max:  # digital: a crop, up to 12x more
            mag *= 1.0 + 11.0 * (zoom - self.zoom_optical_max) / (self.zoom_digital_max - self.zoom_optical_max)
        return 2 * math.atan(math.tan(math.radians(self.hfov_wide_deg) / 2) / mag)


class _Axis:
    """One axis: at rest, moving linearly to a target, or driving at a constant rate until stopped."""

    def __init__(self, lo: float, hi: float) -> None:
        self.lo, self.hi = lo, hi
        self.p0 = 0.0
        self.t0 = 0.0
        self.target = 0.0
        self.t1 = 0.0
        self.rate = 0.0  # counts/s while driving

    def position(self, now: float) -> float:
        if self.rate:
            return min(max(self.p0 + self.rate * (now - self.t0), self.lo), self.hi)
        if now >= self.t1 or self.t1 <= self.t0:
            return self.target
        return self.p0 + (self.target - self.p0) * (now - self.t0) / (self.t1 - self.t0)

    def move_to(self, now: float, target: float, duration_s: float) -> None:
        self.p0 = self.position(now)
        self.rate = 0.0
        self.t0, self.t1, self.target = now, now + duration_s, target

    def drive(self, now: float, rate: float) -> None:
        p = self.position(now)
        self.p0, self.t0, self.rate, self.target, self.t1 = p, now, rate, p, now

    def stop(self, now: float) -> None:
        p = self.position(now)
        self.p0 = self.target = p
        self.t0 = self.t1 = now
        self.rate = 0.0


class CameraState:
    """Pan, tilt, zoom, focus, power; shared by the VISCA port, the pass-through CGI and the renderer."""

    def __init__(self, spec: FakeCameraSpec) -> None:
        self.spec = spec
        self.lock = threading.RLock()
        self.pan = _Axis(spec.pan_min_counts, spec.pan_max_counts)
        self.tilt = _Axis(spec.tilt_min_counts, spec.tilt_max_counts)
        self.zoom = _Axis(0, spec.zoom_digital_max)
        self.focus_auto = True
        self.power_on = True
        self.digital_zoom = False
        self.auto_pt_speed = True

    def ptz(self, now: float) -> tuple[float, float, float]:
        """(pan counts, tilt counts, zoom position) at ``now``."""
        with self.lock:
            return self.pan.position(now), self.tilt.position(now), self.zoom.position(now)

    def view(self, now: float) -> tuple[float, float, float]:
        """(pan_rad CCW positive, tilt_rad up positive, hfov_rad) for the renderer."""
        p, t, z = self.ptz(now)
        s = self.spec
        return -math.radians(p / s.pan_counts_per_deg), math.radians(t / s.tilt_counts_per_deg), s.hfov_rad(z)
