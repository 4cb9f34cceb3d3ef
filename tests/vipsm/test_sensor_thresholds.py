"""Sensor-derived thresholds: the geometry and period come from the scan, and the matcher's minimum valid
beams, its search windows and the scanner-stall age follow them (a 180-degree 10 Hz URG-04LX-class
scanner and a 270-degree 7.5 Hz one, besides the UTM-30LX whose values stay as they were)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.config import LoopConfig
from app.daemon import scan_age_limit_s
from vipsm.estimator import Estimator, EstimatorConfig
from vipsm.psm import PsmConfig
from vipsm.sensor import scan_geometry, scan_period_from_stamps
from vipsm.types import EstimateFlag, Odometry, Scan

STEP_1024 = 2 * math.pi / 1024  # 0.3516 deg: URG-04LX and the leg_tracker recordings' scanners

#: (beams, first bearing, step, period): the three geometries
UTM = (1081, math.radians(-135.0), math.radians(0.25), 0.025)
URG_180_10HZ = (512, -math.pi / 2, STEP_1024, 0.1)
WIDE_270_7HZ = (768, math.radians(-135.0), STEP_1024, 1 / 7.5)


def make_scan(geom: tuple[int, float, float, float], pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
              stamp_s: float = 0.0, max_range_m: float = 5.6) -> Scan:
    """A 7 m x 5 m room with two pillars, ray-cast from ``pose``; returns beyond ``max_range_m`` are
    missing (as on a 5.6 m URG-04LX)."""
    n, first, step, period = geom
    b = first + step * np.arange(n)
    x0, y0, th = pose
    ang = th + b
    c, s = np.cos(ang), np.sin(ang)
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(c > 0, (4.0 - x0) / c, (-3.0 - x0) / c)
        ty = np.where(s > 0, (2.5 - y0) / s, (-2.5 - y0) / s)
    r = np.minimum(np.where(tx > 0, tx, np.inf), np.where(ty > 0, ty, np.inf))
    for px, py, pr in ((1.5, 1.0, 0.15), (-1.0, -1.2, 0.2)):
        dx, dy = px - x0, py - y0
        proj = dx * c + dy * s
        d2 = dx * dx + dy * dy - proj * proj
        hit = (proj > 0) & (d2 < pr * pr)
        r = np.where(hit, np.minimum(r, proj - np.sqrt(np.maximum(pr * pr - d2, 0.0))), r)
    r = np.where(r <= max_range_m, r, np.nan)
    return Scan(r, b, stamp_s, 0, period / (2 * math.pi / step))


@pytest.mark.parametrize(("geom", "fov_deg", "rate_hz"), [(UTM, 270.0, 40.0), (URG_180_10HZ, 179.6, 10.0),
                                                           (WIDE_270_7HZ, 269.6, 7.5)])
def test_geometry_and_period_come_from_the_scan(geom: tuple[int, float, float, float], fov_deg: float,
                                                rate_hz: float) -> None:
    g = scan_geometry(make_scan(geom))
    assert g.n_beams == geom[0]
    assert math.degrees(g.fov_rad) == pytest.approx(fov_deg, abs=0.1)
    assert g.rate_hz == pytest.approx(rate_hz)
    assert scan_period_from_stamps(np.arange(5) * geom[3]) == pytest.approx(geom[3])


def test_utm30lx_counts_stay_as_tuned() -> None:
    psm = EstimatorConfig().psm.for_scan(1081, math.radians(0.25))
    assert (psm.search_window_first_beams, psm.search_window_beams) == (30, 10)
    assert psm.required_beams(1000) == 300  # a UTM-30LX in a room offers ~1000: the count it was tuned at


@pytest.mark.parametrize(("geom", "first_window"), [(URG_180_10HZ, 21), (WIDE_270_7HZ, 21)])
def test_counts_follow_the_sensor(geom: tuple[int, float, float, float], first_window: int) -> None:
    psm = EstimatorConfig().psm.for_scan(geom[0], geom[2])
    assert psm.search_window_first_beams == first_window  # +-7.5 deg whatever the step
    # the beams a match needs follow what the two scans offer, not the scanner's beam count: a 5.6 m
    # URG-04LX with 170 valid beams of 512 needs 51, and never fewer than the floor
    assert psm.required_beams(170) == 51
    assert psm.required_beams(10) == psm.min_valid_floor_beams == 20
    assert PsmConfig(min_valid_beams=120).for_scan(geom[0], geom[2]).required_beams(1000) == 120  # a count set stays


@pytest.mark.parametrize("geom", [URG_180_10HZ, WIDE_270_7HZ], ids=["180deg_10Hz", "270deg_7.5Hz"])
def test_matcher_accepts_a_scanner_with_fewer_beams(geom: tuple[int, float, float, float]) -> None:
    """A still laser whose range limit leaves 36 % of its beams valid (far fewer than the UTM-30LX's
    300; the URG-04LX's 5.6 m gives 140-220 of 512 in the leg_tracker recording): matched on every scan,
    never refused, the pose held."""
    reach_m = float(np.nanquantile(make_scan(geom, max_range_m=np.inf).ranges_m, 0.36))
    first = make_scan(geom, max_range_m=reach_m)
    valid = int(np.count_nonzero(np.isfinite(first.ranges_m)))
    assert valid < 300
    est = Estimator(EstimatorConfig())
    period = geom[3]
    for k in range(12):
        stamp = k * period
        e = est.step(make_scan(geom, stamp_s=stamp, max_range_m=reach_m), Odometry(0.0, 0.0, 0.0, 0.0, 0.0, stamp))
        if k > 0:
            assert not e.flags & EstimateFlag.ODOMETRY_FALLBACK, (k, e.flags, e.quality)
            assert e.quality.beams_used >= 0.5 * valid
    assert math.hypot(e.pose.x_m, e.pose.y_m) < 0.02 and abs(e.pose.theta_rad) < math.radians(0.5)


def test_matcher_tracks_motion_on_a_180_degree_scanner() -> None:
    est = Estimator(EstimatorConfig())
    e = None
    for k in range(10):
        stamp, x = k * 0.1, 0.03 * k
        e = est.step(make_scan(URG_180_10HZ, (x, 0.0, 0.0), stamp), Odometry(0.0, 0.0, 0.0, 0.0, 0.0, stamp))
    assert e is not None and e.pose.x_m == pytest.approx(0.27, abs=0.05)


@pytest.mark.parametrize(("geom", "limit_s"), [(UTM, 0.25), (URG_180_10HZ, 0.7), (WIDE_270_7HZ, 0.9)])
def test_scanner_stall_age_is_counted_in_scan_periods(geom: tuple[int, float, float, float], limit_s: float) -> None:
    loop = LoopConfig()
    assert scan_age_limit_s(loop, make_scan(geom)) == pytest.approx(limit_s)
    # a 7.5 Hz scanner's scan is normally up to two periods old when a cycle samples it: not stalled
    assert scan_age_limit_s(loop, make_scan(geom)) > 2 * geom[3] + loop.period_s


def test_scanner_stall_age_fixed_or_without_timing() -> None:
    assert scan_age_limit_s(LoopConfig(max_scan_age_s=0.5), make_scan(WIDE_270_7HZ)) == 0.5
    untimed = Scan(np.ones(10), np.linspace(0.0, 1.0, 10), 0.0)  # no beam timing: the loop's period stands in
    assert scan_age_limit_s(LoopConfig(), untimed) == pytest.approx(7 * LoopConfig().period_s)


def test_period_from_stamps_when_the_bearing_step_is_not_the_mirrors() -> None:
    """A recording whose beams are every 2nd mirror step (0.5 deg of a 0.25 deg, 40 Hz mirror) but whose
    beam time is one mirror step's (25 ms / 1440): the beam timing alone gives half the period; the stamps'
    spacing gives the true one and wins wherever it is known, also for the scanner-stall age."""
    n, step = 541, math.radians(0.5)
    skipped = Scan(np.full(n, 3.0), math.radians(-135.0) + step * np.arange(n), 0.0, 0, 0.025 / 1440)
    assert scan_geometry(skipped).period_s == pytest.approx(0.0125)  # beam timing: 2x too short
    measured = scan_period_from_stamps(0.025 * np.arange(8))
    g = scan_geometry(skipped, measured)
    assert g.period_s == pytest.approx(0.025) and g.rate_hz == pytest.approx(40.0)
    loop = LoopConfig()
    assert scan_age_limit_s(loop, skipped, measured) == pytest.approx(loop.max_scan_age_periods * 0.025 + loop.period_s)
    assert scan_age_limit_s(loop, skipped, measured) > scan_age_limit_s(loop, skipped)
    # an unknown or invalid measured period leaves the beam timing
    for bad in (None, 0.0, float("nan"), -1.0):
        assert scan_geometry(skipped, bad).period_s == pytest.approx(0.0125)


def test_period_from_stamps_when_only_every_other_turn_is_delivered() -> None:
    """The leg_tracker recordings: 768 beams at 0.3516 deg, 65.1 us a beam (a 15 Hz mirror), a scan every
    133 ms. Beam timing says 66.7 ms; the stamps say 133 ms, and the stall age follows them (counted in
    delivered periods, not in mirror turns)."""
    n, first, step, _ = WIDE_270_7HZ
    scan = Scan(np.full(n, 3.0), first + step * np.arange(n), 0.0, 0, 6.510417e-05)
    assert scan_geometry(scan).period_s == pytest.approx(1 / 15, rel=1e-4)
    measured = scan_period_from_stamps(np.arange(6) / 7.5)
    assert scan_geometry(scan, measured).rate_hz == pytest.approx(7.5)
    loop = LoopConfig()
    assert scan_age_limit_s(loop, scan, measured) == pytest.approx(loop.max_scan_age_periods / 7.5 + loop.period_s)
    assert scan_age_limit_s(loop, scan) == pytest.approx(loop.max_scan_age_periods / 15 + loop.period_s, rel=1e-4)
