"""Calibration: counts <-> radians (fact-sheet examples), zoom table, intrinsics and bearings."""

from __future__ import annotations

import math

import pytest

from drivers.ptz_cam.config import HttpConfig, PtzCalibration, ViscaConfig
from drivers.ptz_cam.errors import ViscaConfigError


def test_pan_examples_and_sign_convention() -> None:
    cal = PtzCalibration()
    # VISCA +1296 (= 90 deg to the right) is -90 deg in the left-positive API
    assert cal.pan_rad_to_counts(math.radians(-90)) == 1296
    assert cal.pan_rad_to_counts(math.radians(30)) == -432
    assert cal.pan_counts_to_rad(-432) == pytest.approx(math.radians(30))
    assert cal.tilt_rad_to_counts(math.radians(25)) == 360
    assert cal.tilt_rad_to_counts(math.radians(-90)) == -1296
    cal.check_pan_tilt(math.radians(170), math.radians(-90))
    with pytest.raises(ViscaConfigError):
        cal.check_pan_tilt(math.radians(171), 0)
    with pytest.raises(ViscaConfigError):
        cal.check_pan_tilt(0, math.radians(26))
    with pytest.raises(ViscaConfigError):
        cal.check_pan_tilt(float("nan"), 0)


def test_pan_zero_offset_is_the_mount_yaw() -> None:
    cal = PtzCalibration(pan_zero_offset_deg=10.0)
    assert cal.pan_rad_to_counts(math.radians(10)) == 0
    assert cal.pan_counts_to_rad(-144) == pytest.approx(math.radians(20))
    cal.check_pan_tilt(math.radians(180), 0)  # 170 deg from the camera's own zero
    with pytest.raises(ViscaConfigError):
        cal.check_pan_tilt(math.radians(-165), 0)


def test_zoom_table_is_log_interpolated_and_invertible() -> None:
    cal = PtzCalibration()
    assert cal.magnification(0) == 1.0
    assert cal.magnification(0x1781) == pytest.approx(2.0)
    assert cal.magnification(0x4000) == pytest.approx(26.0)
    mid = cal.magnification((0x1781 + 0x213B) // 2)
    assert 2.0 < mid < 3.0
    for m in (1.0, 1.5, 2.0, 7.0, 26.0):
        assert cal.magnification(cal.zoom_position_for(m)) == pytest.approx(m, rel=2e-3)
    assert math.degrees(cal.hfov_rad(0)) == pytest.approx(54.0)
    tele_deg = 2 * math.degrees(math.atan(math.tan(math.radians(27)) / 26))
    assert math.degrees(cal.hfov_rad(0x4000)) == pytest.approx(tele_deg)  # about 2.1 deg
    with pytest.raises(ViscaConfigError):
        cal.zoom_position_for(30.0)


def test_intrinsics_and_bearing() -> None:
    cal = PtzCalibration()
    k = cal.intrinsics(0, 640, 480)
    assert k.fx_px == pytest.approx(320 / math.tan(math.radians(27)))  # about 628 px (fact sheet: ~625)
    assert (k.cx_px, k.cy_px) == (320, 240)
    assert k.bearing_rad(640) == pytest.approx(-math.radians(27))  # right edge: right of the axis
    assert k.bearing_rad(0) == pytest.approx(math.radians(27))
    k2 = cal.intrinsics(0, 320, 240)
    assert k2.fx_px == pytest.approx(k.fx_px / 2)
    assert cal.intrinsics(0x4000, 640, 480).fx_px == pytest.approx(k.fx_px * 26, rel=1e-6)


@pytest.mark.parametrize(
    "make",
    [
        lambda: ViscaConfig(baudrate=115200),
        lambda: ViscaConfig(ack_timeout_s=0),
        lambda: ViscaConfig(inquiry_timeout_s=float("inf")),
        lambda: PtzCalibration(pan_sign=0),
        lambda: PtzCalibration(zoom_table=((0, 1.0), (0, 2.0))),
        lambda: HttpConfig(frame_rate=0),
    ],
)
def test_bad_config_is_a_typed_error(make) -> None:
    with pytest.raises(ViscaConfigError):
        make()


def test_speed_model() -> None:
    cfg = ViscaConfig()
    assert cfg.speed_dps(0x18, 0x18, 300.0) == 300.0
    assert cfg.speed_dps(1, 0x18, 300.0) == cfg.min_speed_dps
