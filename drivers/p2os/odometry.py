"""Odometry from ARCOS SIPs: wrap-safe integer accumulation, conversion to SI only at output.

Sans-I/O like the codec: :class:`OdometryTracker` is fed decoded :class:`~drivers.p2os.codec.Sip`
packets with their host receipt stamps and returns :class:`OdometrySample` in SI units.

* XPOS/YPOS are 15-bit counters and THPOS a 12-bit (4096 per revolution) heading, signed or not
  depending on the firmware. Each SIP's change is the shortest signed difference (mod 32768 and mod
  4096), accumulated in unbounded Python ints, and multiplied by the conversion factors only when a
  sample is made: nothing is lost at crawl speed, in long drives or through wraps (unlike p2os's
  per-SIP rounding and 100 mm filter).
* The pose is reported in the frame of the first SIP of the connection (as ARIA does): (0, 0, 0)
  there, x ahead of the robot. After :meth:`OdometryTracker.request_seto` the controller's origin
  becomes the frame (the first SIP near raw zero re-baselines); after
  :meth:`OdometryTracker.restart_session` (reconnect, controller reset) the next SIP continues from
  the last reported pose and the sample says so (``rebaselined``).
* A SIP that comes late is flagged (``gap``, ``missed_cycles``); if the time since the previous SIP
  allows more motion than half a counter range, the sample is flagged ``ambiguous`` as well. No
  change is ever discarded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from .codec import Sip
from .errors import ArcosConfigError

#: exact heading unit: 2*pi / 4096 rad (ARIA's .p files round it to 0.00153, a 0.26 % scale error)
ANGLE_CONV_RAD = 2.0 * math.pi / 4096.0
XY_MODULUS = 1 << 15
TH_MODULUS = 4096


def _signed_diff(new: int, old: int, modulus: int) -> int:
    half = modulus // 2
    return (new - old + half) % modulus - half


def _signed(value: int, modulus: int) -> int:
    value %= modulus
    return value - modulus if value >= modulus // 2 else value


def _wrap_pi(angle_rad: float) -> float:
    wrapped = math.remainder(angle_rad, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


# Sonar poses of p3dx.p (x mm, y mm, heading deg), indices 0..15 (fact sheet section 1.9).
P3DX_SONAR_POSES_MM_DEG: tuple[tuple[float, float, float], ...] = (
    (69, 136, 90), (114, 119, 50), (148, 78, 30), (166, 27, 10),
    (166, -27, -10), (148, -78, -30), (114, -119, -50), (69, -136, -90),
    (-157, -136, -90), (-203, -119, -130), (-237, -78, -150), (-255, -27, -170),
    (-255, 27, 170), (-237, 78, 150), (-203, 119, 130), (-157, 136, 90),
)  # fmt: skip


@dataclass(frozen=True)
class SonarPose:
    x_m: float
    y_m: float
    theta_rad: float


def _sonar_poses(table: tuple[tuple[float, float, float], ...]) -> tuple[SonarPose, ...]:
    return tuple(SonarPose(x / 1000.0, y / 1000.0, math.radians(th)) for x, y, th in table)


@dataclass(frozen=True)
class RobotParams:
    """Conversion factors and geometry of one robot subclass (ARIA's ``<subclass>.p``)."""

    subclass: str
    dist_conv_mm_per_count: float
    angle_conv_rad_per_unit: float = ANGLE_CONV_RAD
    vel_conv: float = 1.0  # SIP wheel speed unit, mm/s
    range_conv_mm: float = 1.0  # sonar range unit, mm
    diff_conv: float = 0.0056  # rad/s per mm/s of (vR - vL)/2, used only when the SIP lacks ROTVEL
    vel2_divisor_mmps: int = 20
    max_v_mps: float = 2.2  # absolute caps when no CONFIGpac came (p3dx.p MaxVelocity / MaxRVelocity)
    max_w_radps: float = math.radians(500.0)
    sonar_poses: tuple[SonarPose, ...] = _sonar_poses(P3DX_SONAR_POSES_MM_DEG)

    def __post_init__(self) -> None:
        for name in ("dist_conv_mm_per_count", "angle_conv_rad_per_unit", "vel_conv", "range_conv_mm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ArcosConfigError(f"RobotParams.{name} must be finite and > 0, got {value}")


ROBOT_PARAMS: dict[str, RobotParams] = {
    "p3dx": RobotParams(subclass="p3dx", dist_conv_mm_per_count=0.485),
    "p3dx-sh": RobotParams(subclass="p3dx-sh", dist_conv_mm_per_count=1.0),
}


def params_for_subclass(
    subclass: str,
    *,
    fallback: str | None = None,
    dist_conv_mm_per_count: float | None = None,
    angle_conv_rad_per_unit: float | None = None,
) -> RobotParams:
    """The table for a SYNC2 subclass (lower-cased, as ARIA does), with optional overrides.

    An unknown subclass raises :class:`ArcosConfigError` unless ``fallback`` names a known one, or
    ``dist_conv_mm_per_count`` is given (then the p3dx geometry is used with that factor).
    """
    key = subclass.strip().lower()
    params = ROBOT_PARAMS.get(key)
    if params is None:
        if fallback is not None:
            if fallback.lower() not in ROBOT_PARAMS:
                raise ArcosConfigError(f"fallback subclass {fallback!r} is not one of {sorted(ROBOT_PARAMS)}")
            params = replace(ROBOT_PARAMS[fallback.lower()], subclass=key)
        elif dist_conv_mm_per_count is not None:
            params = replace(ROBOT_PARAMS["p3dx"], subclass=key)
        else:
            raise ArcosConfigError(
                f"unknown robot subclass {subclass!r}: known {sorted(ROBOT_PARAMS)}; "
                "set a fallback subclass or dist_conv_mm_per_count explicitly"
            )
    if dist_conv_mm_per_count is not None:
        params = replace(params, dist_conv_mm_per_count=dist_conv_mm_per_count)
    if angle_conv_rad_per_unit is not None:
        params = replace(params, angle_conv_rad_per_unit=angle_conv_rad_per_unit)
    return params


@dataclass(frozen=True)
class SonarSample:
    """One new sonar reading with the transducer's pose on the robot (None for an index without a pose)."""

    index: int
    range_m: float
    pose: SonarPose | None


@dataclass(frozen=True)
class OdometrySample:
    """One SIP in SI units. Pose in the connection's odometry frame (see module docstring)."""

    stamp_s: float  # host time.monotonic() at receipt
    seq: int  # SIPs received in this driver instance, counting from 0 (ARCOS has no packet counter)
    x_m: float
    y_m: float
    theta_rad: float  # wrapped to (-pi, pi]
    theta_unwrapped_rad: float
    v_mps: float
    w_radps: float
    left_wheel_mps: float
    right_wheel_mps: float
    battery_v: float
    motors_enabled: bool
    moving_flag: bool  # SIP type 0x33; simulators always send 0x32, so do not rely on it
    estop_pressed: bool
    left_stall: bool
    right_stall: bool
    front_bumpers: int  # bit mask, bit 0 = first front bumper
    rear_bumpers: int
    flags: int  # raw FLAGS word
    sonars: tuple[SonarSample, ...]
    gap: bool = False  # the previous SIP came more than gap_factor cycles earlier
    missed_cycles: int = 0
    ambiguous: bool = False  # so long a gap that a counter could have wrapped more than half its range
    rebaselined: bool = False  # this SIP set a new baseline (first SIP, after SETO or a reconnect)
    device_time_ms: int | None = None  # the controller's own clock when the SIP carries one
    fault_flags: int | None = None


@dataclass
class OdometryStats:
    sips: int = 0
    gaps: int = 0
    missed_cycles: int = 0
    ambiguous: int = 0
    rebaselines: int = 0
    seto_timeouts: int = 0


class OdometryTracker:
    """Turns SIPs into :class:`OdometrySample` (see the module docstring)."""

    def __init__(
        self,
        params: RobotParams,
        *,
        sip_cycle_s: float = 0.1,
        gap_factor: float = 2.5,
        max_v_mps: float | None = None,
        max_w_radps: float | None = None,
        seto_window_sips: int = 20,
    ) -> None:
        if sip_cycle_s <= 0 or gap_factor <= 1.0:
            raise ArcosConfigError("need sip_cycle_s > 0 and gap_factor > 1")
        self.params = params
        self.sip_cycle_s = sip_cycle_s
        self.gap_factor = gap_factor
        self.max_v_mps = max_v_mps if max_v_mps is not None else params.max_v_mps
        self.max_w_radps = max_w_radps if max_w_radps is not None else params.max_w_radps
        self.seto_window_sips = seto_window_sips
        self.stats = OdometryStats()
        # integer accumulators (raw frame, device units) and the previous raw values
        self._acc: tuple[int, int, int] | None = None
        self._prev_raw: tuple[int, int, int] = (0, 0, 0)
        self._origin: tuple[int, int, int] = (0, 0, 0)
        self._offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # pose the origin maps to
        self._prev_stamp_s: float | None = None
        self._seq = -1
        self._seto_left = 0
        self._last_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)

    # -- re-baselining --------------------------------------------------------------------------

    def request_seto(self) -> None:
        """SETO was sent: from the first SIP whose raw pose is near zero, the controller's origin is the frame."""
        self._seto_left = self.seto_window_sips

    def restart_session(self) -> None:
        """A new session (reconnect or controller reset): the next SIP continues from the last pose."""
        self._acc = None
        self._prev_stamp_s = None
        self._seto_left = 0

    @property
    def seto_pending(self) -> bool:
        return self._seto_left > 0

    # -- conversion -----------------------------------------------------------------------------

    def _near_zero(self, xs: int, ys: int, ths: int, sip: Sip) -> bool:
        """Whether a raw pose is what the controller reports shortly after SETO.

        The tolerance is the motion possible in three SIP cycles at the speed the SIP itself reports
        (plus a small margin), so a robot standing far from its raw origin is never mistaken for one
        that was just reset.
        """
        p = self.params
        horizon_s = 3 * self.sip_cycle_s
        v_mmps = max(abs(sip.left_vel_raw), abs(sip.right_vel_raw)) * p.vel_conv
        if sip.rotvel_decidegps is not None:
            w_radps = abs(math.radians(sip.rotvel_decidegps / 10.0))
        else:
            w_radps = abs(sip.right_vel_raw - sip.left_vel_raw) * p.vel_conv / 2.0 * p.diff_conv
        tol_counts = min(XY_MODULUS // 8, 20 + v_mmps * horizon_s / p.dist_conv_mm_per_count)
        tol_units = min(TH_MODULUS // 8, 8 + w_radps * horizon_s / p.angle_conv_rad_per_unit)
        return abs(xs) <= tol_counts and abs(ys) <= tol_counts and abs(ths) <= tol_units

    def _pose(self) -> tuple[float, float, float, float]:
        assert self._acc is not None
        p = self.params
        ox, oy, oth = self._origin
        dx_mm = (self._acc[0] - ox) * p.dist_conv_mm_per_count
        dy_mm = (self._acc[1] - oy) * p.dist_conv_mm_per_count
        th0 = oth * p.angle_conv_rad_per_unit
        c, s = math.cos(th0), math.sin(th0)
        rx = (c * dx_mm + s * dy_mm) / 1000.0
        ry = (-s * dx_mm + c * dy_mm) / 1000.0
        rth = (self._acc[2] - oth) * p.angle_conv_rad_per_unit
        fx, fy, fth = self._offset
        cf, sf = math.cos(fth), math.sin(fth)
        th_unwrapped = fth + rth
        return (fx + cf * rx - sf * ry, fy + sf * rx + cf * ry, _wrap_pi(th_unwrapped), th_unwrapped)

    def update(self, sip: Sip, stamp_s: float) -> OdometrySample:
        p = self.params
        raw = (sip.x_raw & 0x7FFF, sip.y_raw & 0x7FFF, sip.th_raw % TH_MODULUS)
        signed = (_signed(raw[0], XY_MODULUS), _signed(raw[1], XY_MODULUS), _signed(raw[2], TH_MODULUS))
        self._seq += 1
        self.stats.sips += 1
        gap, missed, ambiguous = self._gap(stamp_s)
        self._prev_stamp_s = stamp_s
        rebaselined = self._accumulate(raw, signed, sip)
        self._prev_raw = raw
        if rebaselined:
            self.stats.rebaselines += 1
        x_m, y_m, th, th_unwrapped = self._pose()
        self._last_pose = (x_m, y_m, th_unwrapped)
        left_mps = sip.left_vel_raw * p.vel_conv / 1000.0
        right_mps = sip.right_vel_raw * p.vel_conv / 1000.0
        if sip.rotvel_decidegps is not None:
            w = math.radians(sip.rotvel_decidegps / 10.0)
        else:
            w = (sip.right_vel_raw - sip.left_vel_raw) * p.vel_conv / 2.0 * p.diff_conv
        battery_dv = sip.battery_x10_dv if sip.battery_x10_dv is not None else sip.battery_dv
        return OdometrySample(
            stamp_s=stamp_s,
            seq=self._seq,
            x_m=x_m,
            y_m=y_m,
            theta_rad=th,
            theta_unwrapped_rad=th_unwrapped,
            v_mps=(left_mps + right_mps) / 2.0,
            w_radps=w,
            left_wheel_mps=left_mps,
            right_wheel_mps=right_mps,
            battery_v=battery_dv / 10.0,
            motors_enabled=sip.motors_enabled,
            moving_flag=sip.packet_type == 0x33,
            estop_pressed=sip.estop_pressed,
            left_stall=sip.left_stall,
            right_stall=sip.right_stall,
            front_bumpers=sip.front_bumpers,
            rear_bumpers=sip.rear_bumpers,
            flags=sip.flags,
            sonars=self._sonars(sip),
            gap=gap,
            missed_cycles=missed,
            ambiguous=ambiguous,
            rebaselined=rebaselined,
            device_time_ms=sip.uc_time_ms,
            fault_flags=sip.fault_flags,
        )

    def _gap(self, stamp_s: float) -> tuple[bool, int, bool]:
        """(a gap since the last SIP, the SIP cycles missed in it, whether the motion in it may have
        wrapped the position counters: the unwrapped pose is then ambiguous)."""
        if self._prev_stamp_s is None:
            return False, 0, False
        p = self.params
        dt = stamp_s - self._prev_stamp_s
        if dt <= self.gap_factor * self.sip_cycle_s:
            return False, 0, False
        missed = max(1, round(dt / self.sip_cycle_s) - 1)
        self.stats.gaps += 1
        self.stats.missed_cycles += missed
        half_xy_m = XY_MODULUS / 2 * p.dist_conv_mm_per_count / 1000.0
        half_th_rad = TH_MODULUS / 2 * p.angle_conv_rad_per_unit
        ambiguous = self.max_v_mps * dt >= half_xy_m or self.max_w_radps * dt >= half_th_rad
        self.stats.ambiguous += int(ambiguous)
        return True, missed, ambiguous

    def _accumulate(self, raw: tuple[int, int, int], signed: tuple[int, int, int], sip: Sip) -> bool:
        """Fold the SIP's counters into the unwrapped accumulator; True when it starts a new baseline
        (the first SIP of a session, or the zero after a SETO)."""
        if self._acc is None:
            # first SIP of a session: continue from the last pose (zero at the very start)
            self._acc = signed
            self._origin = signed
            if self._seq > 0:
                self._offset = (self._last_pose[0], self._last_pose[1], self._last_pose[2])
            return True
        if self._seto_left > 0 and self._near_zero(*signed, sip):
            self._acc = signed
            self._origin = (0, 0, 0)
            self._offset = (0.0, 0.0, 0.0)
            self._seto_left = 0
            return True
        ax, ay, ath = self._acc
        px, py, pth = self._prev_raw
        self._acc = (
            ax + _signed_diff(raw[0], px, XY_MODULUS),
            ay + _signed_diff(raw[1], py, XY_MODULUS),
            ath + _signed_diff(raw[2], pth, TH_MODULUS),
        )
        if self._seto_left > 0:
            self._seto_left -= 1
            if self._seto_left == 0:
                self.stats.seto_timeouts += 1
        return False

    def _sonars(self, sip: Sip) -> tuple[SonarSample, ...]:
        p = self.params
        return tuple(
            SonarSample(
                index=r.index,
                range_m=r.range_raw * p.range_conv_mm / 1000.0,
                pose=p.sonar_poses[r.index] if r.index < len(p.sonar_poses) else None,
            )
            for r in sip.sonars
        )
