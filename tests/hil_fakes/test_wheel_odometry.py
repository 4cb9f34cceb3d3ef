"""The wheel-odometry error model: exact without noise, the configured bias and spread with it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil_fakes.kinematics import Unicycle
from hil_fakes.wheel_odometry import OdometryNoise, WheelOdometry


def _drive(odo: WheelOdometry, plant: Unicycle, commands: list[tuple[float, float, float]], dt_s: float) -> None:
    for v, w, seconds in commands:
        plant.command(v, w)
        for _ in range(round(seconds / dt_s)):
            plant.advance(dt_s)
            odo.step(plant.v_mps * dt_s, plant.w_radps * dt_s)


def test_zero_noise_reproduces_the_plant_exactly() -> None:
    plant = Unicycle()
    odo = WheelOdometry(OdometryNoise())
    script = [(0.4, 0.0, 3.0), (0.3, 0.5, 4.0), (0.0, -1.0, 2.0), (-0.2, 0.2, 3.0), (0.0, 0.0, 2.0)]
    _drive(odo, plant, script, 0.01)
    x, y, th = odo.pose()
    assert plant.distance_m > 1.0  # it really moved
    assert x == pytest.approx(plant.x_m, abs=1e-9)
    assert y == pytest.approx(plant.y_m, abs=1e-9)
    assert math.remainder(th - plant.theta_rad, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_start_pose_is_respected_and_motion_is_in_that_frame() -> None:
    odo = WheelOdometry(OdometryNoise(), x_m=1.0, y_m=2.0, theta_rad=math.pi / 2)
    odo.step(0.5, 0.0)
    x, y, th = odo.pose()
    assert (x, y, th) == pytest.approx((1.0, 2.5, math.pi / 2), abs=1e-12)


def test_scale_error_reports_more_distance() -> None:
    odo = WheelOdometry(OdometryNoise(scale_error=0.01))
    for _ in range(100):
        odo.step(0.01, 0.0)
    x, y, _ = odo.pose()
    assert x == pytest.approx(1.01, abs=1e-12)
    assert y == pytest.approx(0.0, abs=1e-12)
    assert odo.distance_m == pytest.approx(1.01, abs=1e-12)


def test_heading_drift_follows_signed_distance() -> None:
    drift = 0.02
    odo = WheelOdometry(OdometryNoise(heading_drift_rad_per_m=drift))
    for _ in range(200):
        odo.step(0.01, 0.0)
    assert odo.pose()[2] == pytest.approx(2.0 * drift, abs=1e-12)
    # the drift bends the path to the left by about drift * D^2 / 2
    assert odo.pose()[1] == pytest.approx(drift * 2.0**2 / 2, rel=1e-3)
    for _ in range(200):
        odo.step(-0.01, 0.0)
    assert odo.pose()[2] == pytest.approx(0.0, abs=1e-12)


def _spread(noise_kwargs: dict[str, float], ds_m: float, dth_rad: float, steps: int, trials: int) -> np.ndarray:
    out = np.empty((trials, 3))
    for i in range(trials):
        odo = WheelOdometry(OdometryNoise(seed=1000 + i, **noise_kwargs))
        for _ in range(steps):
            odo.step(ds_m, dth_rad)
        out[i] = (odo.pose()[0], odo.pose()[1], odo.heading_unwrapped_rad)
    return out


def test_translation_noise_has_the_configured_std_per_metre() -> None:
    sigma = 0.02
    # 1 m driven in 50 steps, 400 trials: std of the distance error should be sigma (std-of-std ~3.5 %)
    poses = _spread({"sigma_trans_frac": sigma}, 0.02, 0.0, 50, 400)
    err = poses[:, 0] - 1.0
    assert abs(float(np.mean(err))) < 4 * sigma / math.sqrt(400)
    assert float(np.std(err)) == pytest.approx(sigma, rel=0.15)
    # no rotation noise configured: heading stays exact
    assert np.all(poses[:, 2] == 0.0)


def test_translation_noise_does_not_depend_on_step_size() -> None:
    sigma = 0.02
    coarse = _spread({"sigma_trans_frac": sigma}, 0.25, 0.0, 4, 400)[:, 0] - 1.0
    assert float(np.std(coarse)) == pytest.approx(sigma, rel=0.15)


def test_rotation_noise_per_radian_turned() -> None:
    sigma = 0.05
    poses = _spread({"sigma_rot_rad_per_rad": sigma}, 0.0, 0.02, 50, 400)  # 1 rad turned in place
    err = poses[:, 2] - 1.0
    assert float(np.std(err)) == pytest.approx(sigma, rel=0.15)
    assert np.allclose(poses[:, :2], 0.0)


def test_rotation_noise_per_metre_driven() -> None:
    sigma = 0.03
    poses = _spread({"sigma_rot_rad_per_m": sigma}, 0.02, 0.0, 50, 400)
    assert float(np.std(poses[:, 2])) == pytest.approx(sigma, rel=0.15)
    assert abs(float(np.mean(poses[:, 2]))) < 4 * sigma / math.sqrt(400)


def test_fixed_seed_is_reproducible() -> None:
    a = _spread({"sigma_trans_frac": 0.05, "sigma_rot_rad_per_m": 0.05}, 0.01, 0.01, 30, 2)
    b = _spread({"sigma_trans_frac": 0.05, "sigma_rot_rad_per_m": 0.05}, 0.01, 0.01, 30, 2)
    assert np.array_equal(a, b)
    assert not np.array_equal(a[0], a[1])


@pytest.mark.parametrize(
    "kwargs",
    [{"sigma_trans_frac": -0.1}, {"sigma_rot_rad_per_m": math.nan}, {"scale_error": -1.0}, {"scale_error": math.inf}],
)
def test_bad_parameters_are_rejected(kwargs: dict[str, float]) -> None:
    with pytest.raises(ValueError):
        OdometryNoise(**kwargs)
