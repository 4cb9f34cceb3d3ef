"""Odometry from SIPs: wraps, integer accumulation, factors by subclass, gaps, re-baselining."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.p2os.codec import Sip, SonarReading
from drivers.p2os.errors import ArcosConfigError
from drivers.p2os.odometry import (
    ANGLE_CONV_RAD,
    OdometryTracker,
    params_for_subclass,
)

P3DX = params_for_subclass("p3dx")


def sip(x: int, y: int, th: int, lvel: int = 0, rvel: int = 0, **kw: object) -> Sip:
    base: dict[str, object] = dict(
        packet_type=0x32,
        x_raw=x & 0x7FFF,
        y_raw=y & 0x7FFF,
        th_raw=th,
        left_vel_raw=lvel,
        right_vel_raw=rvel,
        battery_dv=125,
        stall_bumpers=0,
        control_raw=0,
        flags=0x1F,
        compass_raw=0,
        sonars=(),
    )
    base.update(kw)
    return Sip(**base)  # type: ignore[arg-type]


def test_factors_by_subclass_and_overrides() -> None:
    assert params_for_subclass("p3dx").dist_conv_mm_per_count == 0.485
    assert params_for_subclass("P3DX-SH").dist_conv_mm_per_count == 1.0
    assert params_for_subclass("p3dx").angle_conv_rad_per_unit == 2 * math.pi / 4096
    assert params_for_subclass("p3dx", dist_conv_mm_per_count=0.5).dist_conv_mm_per_count == 0.5
    assert params_for_subclass("p3dx", angle_conv_rad_per_unit=0.00153).angle_conv_rad_per_unit == 0.00153
    with pytest.raises(ArcosConfigError):
        params_for_subclass("seekurjr")
    assert params_for_subclass("seekurjr", fallback="p3dx").dist_conv_mm_per_count == 0.485
    with pytest.raises(ArcosConfigError):
        params_for_subclass("p3dx", dist_conv_mm_per_count=0.0)


def test_first_sip_is_the_origin_and_x_wraps_at_15_bits() -> None:
    tr = OdometryTracker(P3DX)
    s0 = tr.update(sip(32700, 0, 0), 0.0)
    assert (s0.x_m, s0.y_m, s0.theta_rad) == (0.0, 0.0, 0.0) and s0.rebaselined
    t = 0.0
    x = 32700
    for _ in range(100):  # 100 x 200 counts forward through the wrap
        x += 200
        t += 0.1
        s = tr.update(sip(x, 0, 0), t)
    assert s.x_m == pytest.approx(100 * 200 * 0.485 / 1000, abs=1e-12)
    assert not s.gap


def test_crawl_speed_is_not_lost_to_rounding() -> None:
    # 1 count per SIP (0.485 mm/0.1 s = 4.85 mm/s) for 10 minutes: p2os reports ~0, we must be exact
    tr = OdometryTracker(P3DX)
    for k in range(6000):
        s = tr.update(sip(k, 0, 0), k * 0.1)
    assert s.x_m == pytest.approx(5999 * 0.485e-3, abs=1e-12)


@pytest.mark.parametrize("signed", [False, True])
def test_heading_wraps_with_signed_or_unsigned_thpos(signed: bool) -> None:
    tr = OdometryTracker(P3DX)
    th = 2000
    t = 0.0
    tr.update(sip(0, 0, th), t)
    for _ in range(50):  # +40 units per SIP, 2000 units total: through 2048 and 4096
        th += 40
        t += 0.1
        sent = th % 4096
        if signed and sent >= 2048:
            sent -= 4096
        s = tr.update(sip(0, 0, sent), t)
    assert s.theta_unwrapped_rad == pytest.approx(2000 * ANGLE_CONV_RAD, abs=1e-12)
    assert s.theta_rad == pytest.approx(math.remainder(2000 * ANGLE_CONV_RAD, 2 * math.pi), abs=1e-12)


def test_pose_is_in_the_frame_of_the_first_sip() -> None:
    # raw heading 90 deg at connect; the robot then drives +1000 counts along raw y (its own forward)
    tr = OdometryTracker(params_for_subclass("p3dx-sh"))
    tr.update(sip(100, 200, 1024), 0.0)
    s = tr.update(sip(100, 1200, 1024), 0.1)
    assert (s.x_m, s.y_m, s.theta_rad) == pytest.approx((1.0, 0.0, 0.0), abs=1e-12)


def test_gap_is_flagged_never_dropped() -> None:
    tr = OdometryTracker(P3DX, sip_cycle_s=0.1, max_w_radps=math.radians(100.0))
    tr.update(sip(0, 0, 0), 0.0)
    s = tr.update(sip(10000, 0, 0), 1.0)  # 4.85 m in a 1 s gap: kept, flagged
    assert s.gap and s.missed_cycles == 9 and not s.ambiguous
    assert s.x_m == pytest.approx(10000 * 0.485e-3)
    s = tr.update(sip(10000, 0, 0), 10.0)  # so long a heading could have wrapped
    assert s.gap and s.ambiguous
    assert tr.stats.gaps == 2


def test_seto_rebaselines_to_the_controller_origin() -> None:
    tr = OdometryTracker(params_for_subclass("p3dx-sh"))
    tr.update(sip(5000, 5000, 0), 0.0)
    tr.update(sip(6000, 5000, 0), 0.1)
    tr.request_seto()
    s = tr.update(sip(6000, 5000, 0), 0.2)  # SIP already in flight: still old frame
    assert not s.rebaselined and s.x_m == pytest.approx(1.0)
    s = tr.update(sip(3, 0, 0), 0.3)
    assert s.rebaselined and (s.x_m, s.y_m, s.theta_rad) == pytest.approx((0.003, 0.0, 0.0))
    s = tr.update(sip(-10, 20, 4090), 0.4)  # negative x wraps to 32758 on the wire
    assert (s.x_m, s.y_m) == pytest.approx((-0.010, 0.020))
    assert s.theta_rad == pytest.approx(-6 * ANGLE_CONV_RAD)
    assert not tr.seto_pending


def test_restart_session_continues_from_the_last_pose() -> None:
    tr = OdometryTracker(params_for_subclass("p3dx-sh"))
    tr.update(sip(0, 0, 0), 0.0)
    tr.update(sip(1000, 0, 1024), 0.1)  # at (1 m, 0), facing +90 deg
    tr.restart_session()
    s = tr.update(sip(0, 0, 0), 5.0)  # controller reset: raw pose back to zero
    assert s.rebaselined and not s.gap
    assert (s.x_m, s.y_m, s.theta_rad) == pytest.approx((1.0, 0.0, math.pi / 2))
    s = tr.update(sip(500, 0, 0), 5.1)  # forward in the new raw frame = +y in ours
    assert (s.x_m, s.y_m) == pytest.approx((1.0, 0.5))


def test_velocities_battery_flags_and_sonar_poses() -> None:
    tr = OdometryTracker(P3DX)
    s = tr.update(
        sip(
            0,
            0,
            0,
            231,
            168,
            flags=0x21,
            stall_bumpers=0x0101,
            sonars=(SonarReading(0, 1234), SonarReading(20, 500)),
            battery_x10_dv=131,
            rotvel_decidegps=-100,
        ),
        0.0,
    )
    assert s.v_mps == pytest.approx(0.1995) and s.w_radps == pytest.approx(math.radians(-10.0))
    assert s.left_wheel_mps == pytest.approx(0.231) and s.battery_v == pytest.approx(13.1)
    assert s.motors_enabled and s.estop_pressed and s.left_stall and s.right_stall
    assert s.sonars[0].range_m == pytest.approx(1.234)
    assert s.sonars[0].pose is not None and s.sonars[0].pose.theta_rad == pytest.approx(math.pi / 2)
    assert (s.sonars[0].pose.x_m, s.sonars[0].pose.y_m) == pytest.approx((0.069, 0.136))
    assert s.sonars[1].pose is None  # index without a known pose
    # without ROTVEL the rate comes from the wheel speeds and DiffConvFactor
    s2 = tr.update(sip(0, 0, 0, -100, 100), 0.1)
    assert s2.w_radps == pytest.approx(100 * 0.0056)


@settings(max_examples=60, deadline=None)
@given(
    st.integers(0, 32767),
    st.integers(0, 32767),
    st.integers(0, 4095),
    st.lists(st.tuples(st.integers(-3000, 3000), st.integers(-3000, 3000), st.integers(-300, 300)), max_size=60),
)
def test_accumulation_equals_the_unwrapped_sum(x0: int, y0: int, th0: int, steps: list[tuple[int, int, int]]) -> None:
    """Whatever the start and the steps (each under half a range), the counts add up exactly."""
    tr = OdometryTracker(params_for_subclass("p3dx-sh"))
    tr.update(sip(x0, y0, th0), 0.0)
    x, y, th = x0, y0, th0
    s = None
    for k, (dx, dy, dth) in enumerate(steps, start=1):
        x, y, th = x + dx, y + dy, th + dth
        s = tr.update(sip(x, y, th % 4096), k * 0.1)
    if s is None:
        return
    total_th = (th - th0) * ANGLE_CONV_RAD
    c, si = math.cos(th0 * ANGLE_CONV_RAD), math.sin(th0 * ANGLE_CONV_RAD)
    ex = (c * (x - x0) + si * (y - y0)) / 1000.0
    ey = (-si * (x - x0) + c * (y - y0)) / 1000.0
    assert s.theta_unwrapped_rad == pytest.approx(total_th, abs=1e-9)
    assert (s.x_m, s.y_m) == pytest.approx((ex, ey), abs=1e-9)
