"""vipsm.static_map: free-space violations happen only where the laser saw free floor."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vipsm.static_map import FreeSpaceGrid, StaticMapConfig
from vipsm.types import Pose2D

from .sim import UTM_BEARINGS, Circle, box_room


def _fill(grid: FreeSpaceGrid, world, pose: Pose2D, n: int, t0: float = 0.0) -> None:
    for k in range(n):
        scan = world.scan(pose, t_s=t0 + 0.1 * k)
        grid.integrate(t0 + 0.1 * k, (pose.x_m, pose.y_m), pose.theta_rad, scan.ranges_m, scan.bearings_rad)


def test_space_seen_free_is_violated_surfaces_and_unknown_space_are_not() -> None:
    world = box_room(8.0, 6.0)
    grid = FreeSpaceGrid()
    _fill(grid, world, Pose2D(0.0, 0.0, 0.0), 10)
    pts = np.array([[2.0, 0.5], [5.9, 0.0], [-3.0, 0.0], [8.0, 0.0]])
    # open floor / the far wall (x = 6) / behind the left wall (never seen) / outside the grid's view
    assert grid.violates(pts).tolist() == [True, False, False, False]
    # no point (NaN) and far outside the grid: no violation; the grid's first cell: its neighbours clamp
    edge = grid.origin + 0.01
    odd = np.array([[np.nan, 0.5], [2.0, np.inf], [1e9, 0.0], [-1e300, 1e300], edge])
    assert grid.violates(odd).tolist() == [False] * 5 and grid.violates(np.zeros((0, 2))).size == 0


def test_a_static_post_is_never_a_violation_from_any_viewpoint() -> None:
    world = box_room(8.0, 6.0)
    world.circles = [Circle(2.5, 1.0, 0.02)]  # a chair leg
    grid = FreeSpaceGrid()
    for k, x in enumerate(np.linspace(-1.0, 3.0, 30)):
        pose = Pose2D(float(x), -1.0, 0.3)
        scan = world.scan(pose)
        ang = pose.theta_rad + scan.bearings_rad
        pts = np.stack([x + scan.ranges_m * np.cos(ang), -1.0 + scan.ranges_m * np.sin(ang)], 1)
        on_post = np.isfinite(scan.ranges_m) & (np.hypot(pts[:, 0] - 2.5, pts[:, 1] - 1.0) < 0.05)
        if k > 3:
            assert not grid.violates(pts[on_post]).any()
        grid.integrate(0.1 * k, (float(x), -1.0), 0.3, scan.ranges_m, scan.bearings_rad)


def test_a_body_walking_into_free_space_violates_it() -> None:
    world = box_room(8.0, 6.0)
    grid = FreeSpaceGrid()
    pose = Pose2D(0.0, 0.0, 0.0)
    _fill(grid, world, pose, 10)
    world.circles = [Circle(3.0, 1.0, 0.06)]
    scan = world.scan(pose)
    ang = scan.bearings_rad
    pts = np.stack([scan.ranges_m * np.cos(ang), scan.ranges_m * np.sin(ang)], 1)
    leg = np.isfinite(scan.ranges_m) & (np.hypot(pts[:, 0] - 3.0, pts[:, 1] - 1.0) < 0.1)
    assert leg.sum() >= 3 and grid.violates(pts[leg]).all()


def test_evidence_decays_and_the_grid_follows_the_robot_with_bounded_memory() -> None:
    world = box_room(30.0, 6.0, x0=-2.0)
    cfg = StaticMapConfig(memory_s=1.0)
    grid = FreeSpaceGrid(cfg)
    _fill(grid, world, Pose2D(0.0, 0.0, 0.0), 5)
    assert grid.violates(np.array([[2.0, 0.5]]))[0]
    grid.integrate(10.0, (0.0, 0.0), 0.0, np.full(UTM_BEARINGS.size, np.nan), UTM_BEARINGS)
    assert not grid.violates(np.array([[2.0, 0.5]]))[0]  # forgotten after 10 memory constants
    shape = grid.free.shape
    _fill(grid, world, Pose2D(15.0, 0.0, 0.0), 3, t0=11.0)
    assert grid.free.shape == shape and grid.violates(np.array([[17.0, 0.5]]))[0]
    assert math.isclose(float(grid.origin[0] + grid.n * cfg.cell_m / 2), 15.0, abs_tol=cfg.cell_m)


def test_occupied_counts_the_scans_that_ended_in_a_cell_decayed() -> None:
    world = box_room(8.0, 6.0)
    world.circles = [Circle(2.5, 1.0, 0.05)]
    grid = FreeSpaceGrid()
    _fill(grid, world, Pose2D(0.0, 0.0, 0.0), 20)
    on, floor, outside = grid.occupied(np.array([[2.45, 1.0], [1.5, 0.0], [50.0, 0.0]])).tolist()
    k = math.exp(-0.1 / grid.config.memory_s)
    assert on == pytest.approx(sum(k**i for i in range(20)), rel=1e-4)  # the post's front cell, 20 scans
    assert floor == 0.0 and outside == 0.0


def test_occupied_cells_around_lists_long_occupied_cells_in_the_ring_only() -> None:
    world = box_room(8.0, 6.0)
    world.circles = [Circle(2.5, 1.0, 0.05), Circle(2.5, 1.4, 0.05)]  # two posts 0.4 m apart
    grid = FreeSpaceGrid()
    _fill(grid, world, Pose2D(0.0, 0.0, 0.0), 20)
    cells = grid.occupied_cells_around(2.45, 1.0, 0.2, 0.65, 15.0)
    assert cells.shape[0] >= 1 and np.all(np.hypot(cells[:, 0] - 2.45, cells[:, 1] - 1.4) < 0.15)  # the other post
    assert grid.occupied_cells_around(2.45, 1.0, 0.2, 0.65, 30.0).shape == (0, 2)  # not that long
    assert grid.occupied_cells_around(2.45, 1.0, 0.2, 0.3, 15.0).shape == (0, 2)  # out of reach


def test_held_is_what_the_laser_saw_in_a_cell_when_it_last_saw_it() -> None:
    """``held``: the last scan that saw a cell ended a beam there (a post stands there now), not a scan
    that passed through it after the thing in it left; open floor and cells outside the grid are not held."""
    world = box_room(8.0, 6.0)
    world.circles = [Circle(2.5, 1.0, 0.05)]
    grid = FreeSpaceGrid()
    _fill(grid, world, Pose2D(0.0, 0.0, 0.0), 5)
    post, floor, outside = [2.45, 1.0], [1.5, 0.0], [50.0, 0.0]
    assert grid.held(np.array([post, floor, outside])).tolist() == [True, False, False]
    world.circles = []  # the post is carried away: the next scan passes through its cell
    _fill(grid, world, Pose2D(0.0, 0.0, 0.0), 1, t0=0.5)
    assert grid.occupied(np.array([post]))[0] > grid.config.max_occupied  # its decayed count lingers
    assert not grid.held(np.array([post]))[0]
    world.circles = [Circle(2.5, 1.0, 0.05)]
    _fill(grid, world, Pose2D(0.0, 0.0, 0.0), 1, t0=0.6)
    assert grid.held(np.array([post]))[0]
    _fill(grid, world, Pose2D(12.0, 0.0, 0.0), 1, t0=0.7)  # re-centred: the stamps move with their cells
    assert grid.held(np.array([post]))[0] and not grid.held(np.array([floor]))[0]
