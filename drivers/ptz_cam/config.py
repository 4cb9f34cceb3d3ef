"""Configuration and calibration of the SNC-RZ50: counts <-> radians, zoom -> field of view, intrinsics.

Everything the fact sheet marks [?] is a field here with the best default, so a measured camera is
described by config, not by code. API conventions (clearpathrobotics/ptz_action_server, and
``vipsm.types.Frame``): pan in radians, counter-clockwise (left) positive seen from above; tilt in
radians, up positive. VISCA pan counts are right-positive on a desktop mount [?], hence
``pan_sign = -1``.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

from .errors import ViscaConfigError

_DEG = math.pi / 180.0

#: Sony 25x block lens, magnification -> zoom position (Polycom Ceiling DocCam II appendix, [SEC]);
#: used as the RZ50's (26x) curve shape until the RZ50 is measured [?].
SONY_BLOCK_ZOOM_TABLE: tuple[tuple[int, float], ...] = (
    (0x0000, 1.0),
    (0x1781, 2.0),
    (0x213B, 3.0),
    (0x2752, 4.0),
    (0x2BB3, 5.0),
    (0x2F03, 6.0),
    (0x3364, 8.0),
    (0x362C, 10.0),
    (0x386A, 12.0),
    (0x3AFA, 15.0),
    (0x3DF8, 20.0),
    (0x4000, 26.0),  # the RZ50's optical tele end is 26x [?]
)


@dataclass(frozen=True)
class PtzCalibration:
    """Device units <-> SI. Defaults from the fact sheet's RZ50 section; [?] ones must be measured."""

    pan_counts_per_deg: float = 14.4  # [SEC] two sources
    pan_sign: int = -1  # VISCA + = right [?]; API + = left
    pan_zero_offset_deg: float = 0.0  # API pan of the camera's pan 0 (mount yaw on the robot; measure it)
    tilt_counts_per_deg: float = 14.4  # [?] sources conflict (14.4 or ~15.65, sign inverted)
    tilt_sign: int = 1  # VISCA + = up [?]
    pan_min_deg: float = -170.0  # [SEC]
    pan_max_deg: float = 170.0
    tilt_min_deg: float = -90.0  # [SEC] desktop mount
    tilt_max_deg: float = 25.0
    zoom_table: tuple[tuple[int, float], ...] = SONY_BLOCK_ZOOM_TABLE  # position -> magnification [?]
    optical_zoom_max: int = 0x4000  # [SEC]
    hfov_wide_deg: float = 54.0  # [?] 2*atan(3.6 mm / (2*3.5 mm))
    principal_offset_px: tuple[float, float] = (0.0, 0.0)  # (cx, cy) - image centre, for 640x480 [?]
    pixel_aspect: float = 1.0  # fy / fx; 1.0 for the 4:3 sizes [?]

    def __post_init__(self) -> None:
        if self.pan_counts_per_deg <= 0 or self.tilt_counts_per_deg <= 0:
            raise ViscaConfigError("counts per degree must be positive")
        if self.pan_sign not in (-1, 1) or self.tilt_sign not in (-1, 1):
            raise ViscaConfigError("pan_sign and tilt_sign must be -1 or +1")
        if not self.pan_min_deg < self.pan_max_deg or not self.tilt_min_deg < self.tilt_max_deg:
            raise ViscaConfigError("pan/tilt limits must have min < max")
        if not 0 < self.hfov_wide_deg < 180:
            raise ViscaConfigError("hfov_wide_deg must be in (0, 180)")
        table = self.zoom_table
        if len(table) < 2 or table[0][1] != 1.0:
            raise ViscaConfigError("zoom_table needs >= 2 rows and must start at magnification 1.0")
        for (p0, m0), (p1, m1) in zip(table, table[1:]):
            if not (p1 > p0 and m1 > m0):
                raise ViscaConfigError("zoom_table positions and magnifications must both increase")

    # -- pan/tilt -----------------------------------------------------------------------------

    def pan_rad_to_counts(self, pan_rad: float) -> int:
        return int(round(self.pan_sign * (pan_rad / _DEG - self.pan_zero_offset_deg) * self.pan_counts_per_deg))

    def tilt_rad_to_counts(self, tilt_rad: float) -> int:
        return int(round(self.tilt_sign * tilt_rad / _DEG * self.tilt_counts_per_deg))

    def pan_counts_to_rad(self, counts: int) -> float:
        return (self.pan_sign * counts / self.pan_counts_per_deg + self.pan_zero_offset_deg) * _DEG

    def tilt_counts_to_rad(self, counts: int) -> float:
        return self.tilt_sign * counts / self.tilt_counts_per_deg * _DEG

    def check_pan_tilt(self, pan_rad: float, tilt_rad: float) -> None:
        """Raise :class:`ViscaConfigError` for a target outside the mechanical range."""
        for name, value, lo, hi in (
            ("pan", pan_rad - self.pan_zero_offset_deg * _DEG, self.pan_min_deg, self.pan_max_deg),
            ("tilt", tilt_rad, self.tilt_min_deg, self.tilt_max_deg),
        ):
            if not math.isfinite(value) or not lo * _DEG - 1e-9 <= value <= hi * _DEG + 1e-9:
                raise ViscaConfigError(f"{name} {value!r} rad is outside {lo:g}..{hi:g} deg")

    # -- zoom ---------------------------------------------------------------------------------

    def magnification(self, zoom_position: int) -> float:
        """Optical magnification at a zoom position, interpolated in log(m); digital zoom beyond."""
        table = self.zoom_table
        if zoom_position <= table[0][0]:
            return table[0][1]
        if zoom_position >= table[-1][0]:
            # above the table: the digital range is a crop; not modelled beyond the table's end
            return table[-1][1]
        positions = [p for p, _ in table]
        i = bisect.bisect_right(positions, zoom_position)
        (p0, m0), (p1, m1) = table[i - 1], table[i]
        f = (zoom_position - p0) / (p1 - p0)
        return math.exp(math.log(m0) + f * (math.log(m1) - math.log(m0)))

    def zoom_position_for(self, magnification: float) -> int:
        """Inverse of :meth:`magnification` (log-interpolated)."""
        table = self.zoom_table
        if not math.isfinite(magnification) or not table[0][1] <= magnification <= table[-1][1]:
            raise ViscaConfigError(f"magnification {magnification!r} outside {table[0][1]}..{table[-1][1]}")
        mags = [m for _, m in table]
        i = min(bisect.bisect_left(mags, magnification), len(table) - 1)
        if i == 0:
            return table[0][0]
        (p0, m0), (p1, m1) = table[i - 1], table[i]
        f = (math.log(magnification) - math.log(m0)) / (math.log(m1) - math.log(m0))
        return int(round(p0 + f * (p1 - p0)))

    def hfov_rad(self, zoom_position: int) -> float:
        half = math.tan(self.hfov_wide_deg * _DEG / 2) / self.magnification(zoom_position)
        return 2 * math.atan(half)

    def intrinsics(self, zoom_position: int, width_px: int, height_px: int) -> CameraIntrinsics:
        if width_px <= 0 or height_px <= 0:
            raise ViscaConfigError(f"image size must be positive, got {width_px}x{height_px}")
        fx = (width_px / 2) / math.tan(self.hfov_rad(zoom_position) / 2)
        sx = width_px / 640.0
        sy = height_px / 480.0
        return CameraIntrinsics(
            fx_px=fx,
            fy_px=fx * self.pixel_aspect,
            cx_px=width_px / 2 + self.principal_offset_px[0] * sx,
            cy_px=height_px / 2 + self.principal_offset_px[1] * sy,
            width_px=width_px,
            height_px=height_px,
            hfov_rad=self.hfov_rad(zoom_position),
        )


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics for one zoom position and image size (the app turns this into vipsm's type)."""

    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    width_px: int
    height_px: int
    hfov_rad: float

    def bearing_rad(self, u_px: float) -> float:
        """Bearing of pixel column ``u`` relative to the optical axis, left positive (image x grows right)."""
        return -math.atan((u_px - self.cx_px) / self.fx_px)


@dataclass(frozen=True)
class ViscaConfig:
    """The VISCA link: port, timeouts, speeds. Speed model and timeouts are [?]: measure on the camera."""

    baudrate: int = 9600  # 9600 or 38400, must match the camera setting
    address: int = 1  # the RZ50 is always camera 1 (no daisy chain)
    ack_timeout_s: float = 1.0  # ACK normally within a few hundred ms
    inquiry_timeout_s: float = 1.0
    default_completion_timeout_s: float = 5.0  # commands whose duration is not modelled (focus, power ...)
    reset_timeout_s: float = 40.0  # the reset's homing run
    completion_margin: float = 1.5  # timeout = default + margin * predicted move time
    pan_max_speed: int = 0x18  # replaced by Pan-tiltMaxSpeedInq's answer when the camera answers
    tilt_max_speed: int = 0x14
    pan_max_dps: float = 300.0  # [SEC] at the max speed
    tilt_max_dps: float = 300.0  # [SEC]
    min_speed_dps: float = 2.0  # [?] speed 1; speeds interpolate linearly up to the max
    zoom_full_travel_s: float = 5.0  # [?] wide -> optical tele at the standard zoom speed
    stale_drain_s: float = 0.05  # quiet time waited after an unanswered request before the next one
    set_auto_pan_tilt_speed_off: bool = True  # [?] for the RZ50 (listed for the RZ30); failure tolerated
    digital_zoom_off: bool = True
    calibration: PtzCalibration = field(default_factory=PtzCalibration)

    def __post_init__(self) -> None:
        if self.baudrate not in (9600, 38400):
            raise ViscaConfigError(f"the SNC-RZ50 speaks 9600 or 38400 bit/s, not {self.baudrate}")
        for name in ("ack_timeout_s", "inquiry_timeout_s", "default_completion_timeout_s", "reset_timeout_s",
                     "pan_max_dps", "tilt_max_dps", "min_speed_dps", "zoom_full_travel_s", "completion_margin"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ViscaConfigError(f"{name} must be finite and > 0, got {value!r}")
        if not 1 <= self.pan_max_speed <= 0x7F or not 1 <= self.tilt_max_speed <= 0x7F:
            raise ViscaConfigError("max speeds must be 1..0x7F")

    def speed_dps(self, speed: int, max_speed: int, max_dps: float) -> float:
        """Predicted angular speed of a VISCA speed value (linear between speed 1 and the max) [?]."""
        if max_speed <= 1:
            return max_dps
        f = (min(max(speed, 1), max_speed) - 1) / (max_speed - 1)
        return self.min_speed_dps + f * (max_dps - self.min_speed_dps)


@dataclass(frozen=True)
class HttpConfig:
    """The camera's HTTP interface."""

    base_url: str = "http://192.168.0.100"  # may carry user:password@
    username: str | None = None
    password: str | None = None
    stream_path: str = "/image"  # or "/mjpeg" (follows the codec: force JPEG mode or use /mjpeg)
    frame_rate: int = 15  # speed= parameter
    oneshot_path: str = "/oneshotimage.jpg"
    passthrough_path: str = "/command/visca-ptzf.cgi"
    timeout_s: float = 5.0  # connect/read timeout of each HTTP call
    reconnect_initial_s: float = 0.2
    reconnect_max_s: float = 5.0
    buffer_frames: int = 4
    max_frame_bytes: int = 8 * 1024 * 1024  # guard against a runaway part, far above any real JPEG

    def __post_init__(self) -> None:
        if not 1 <= self.frame_rate <= 30:
            raise ViscaConfigError(f"frame_rate must be 1..30, got {self.frame_rate}")
        if not (math.isfinite(self.timeout_s) and self.timeout_s > 0):
            raise ViscaConfigError("timeout_s must be finite and > 0")
