import numpy as np
import pytest

from vipsm.distortion import distort, undistort
from vipsm.flow import _project, _rays
from vipsm.types import Intrinsics


def test_zero_distortion_is_identity():
    x = np.linspace(-0.5, 0.5, 11)
    y = np.linspace(0.4, -0.4, 11)
    xd, yd = distort(x, y, 0.0, 0.0, 0.0, 0.0)
    assert np.allclose(xd, x) and np.allclose(yd, y)
    xu, yu = undistort(x, y, 0.0, 0.0, 0.0, 0.0)
    assert np.allclose(xu, x) and np.allclose(yu, y)


@pytest.mark.parametrize("dist", [(-0.25, 0.08, 0.001, -0.0015), (0.12, -0.02, -0.002, 0.001)])
def test_undistort_inverts_distort(dist):
    x, y = np.meshgrid(np.linspace(-0.45, 0.45, 9), np.linspace(-0.35, 0.35, 7))
    xd, yd = distort(x, y, *dist)
    assert not np.allclose(xd, x)  # the lens does move points
    xu, yu = undistort(xd, yd, *dist)
    assert np.max(np.abs(xu - x)) < 1e-5 and np.max(np.abs(yu - y)) < 1e-5


def test_ray_through_distorted_pixel_projects_back_to_it():
    dist = (-0.2, 0.05, 0.001, 0.0005)
    us = np.array([10.0, 160.0, 300.0])
    vs = np.array([20.0, 120.0, 230.0])
    rx, ry, rz = _rays(us, vs, 300.0, 300.0, 159.5, 119.5, 0.3, -0.1, dist)
    u, v, f = _project(rx, ry, rz, 300.0, 300.0, 159.5, 119.5, 0.3, -0.1, dist)
    assert np.all(f > 0)
    assert np.allclose(u, us, atol=1e-3) and np.allclose(v, vs, atol=1e-3)


def test_undistortion_moves_an_edge_bearing():
    dist = (-0.25, 0.0, 0.0, 0.0)  # barrel: an edge pixel looks further out than the pinhole says
    rx0, ry0, _ = _rays(np.array([0.0]), np.array([119.5]), 300.0, 300.0, 159.5, 119.5, 0.0, 0.0)
    rx1, ry1, _ = _rays(np.array([0.0]), np.array([119.5]), 300.0, 300.0, 159.5, 119.5, 0.0, 0.0, dist)
    assert abs(np.arctan2(ry1, rx1)[0]) > abs(np.arctan2(ry0, rx0)[0]) + 1e-3


def test_intrinsics_default_is_pinhole():
    assert Intrinsics(300.0, 300.0, 159.5, 119.5, 320, 240).distortion == (0.0, 0.0, 0.0, 0.0)
