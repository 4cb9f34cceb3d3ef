"""The drive's reference (``eval --data real``, negative_2): the lasers' rigid-mount agreement (a 2-D hand-eye
fit of one laser's mount in another's frame from their paths) and the configured kiss-icp reference (the
robot's reach left out, each sweep de-skewed), on made-up paths whose answers are known and on the
recorded drive's first scans (skipped without the data or kiss-icp)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.evaluation.real_data import (
    Cycle,
    Run,
    _moved_by_twist,
    _twist,
    as_mounted,
    end_vs_loop,
    fit_mount,
    laser_agreement,
    loop_closure,
)

#: the three mounts (phi, x, y) in the robot's frame: two front corners looking out, one looking back
MOUNTS = {"left": (math.radians(45), 0.3, 0.25), "rear": (math.radians(180), -0.6, 0.0),
          "right": (math.radians(-45), 0.3, -0.25)}


def _compose(a: np.ndarray, b: tuple[float, float, float]) -> np.ndarray:
    """Poses ``a`` ((n, 3)) times one fixed pose ``b``."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    return np.stack([a[:, 0] + c * b[0] - s * b[1], a[:, 1] + s * b[0] + c * b[1], a[:, 2] + b[2]], axis=1)


def _robot_path(n: int = 600, dt_s: float = 0.1) -> np.ndarray:
    """A drive with turns both ways: (n, 3) robot poses every ``dt_s``."""
    t = np.arange(n) * dt_s
    w = 0.6 * np.sin(t / 3.0) + 0.3 * np.sin(t / 1.3)
    v = 0.5 + 0.2 * np.cos(t / 2.0)
    th = np.concatenate([[0.0], np.cumsum(w[:-1] * dt_s)])
    x = np.concatenate([[0.0], np.cumsum(v[:-1] * np.cos(th[:-1]) * dt_s)])
    y = np.concatenate([[0.0], np.cumsum(v[:-1] * np.sin(th[:-1]) * dt_s)])
    return np.stack([x, y, th], axis=1)


def _laser_path(robot: np.ndarray, mount: tuple[float, float, float]) -> np.ndarray:
    """The laser's poses in its own first pose's frame (as a registration of its scans gives them)."""
    world = _compose(robot, (mount[1], mount[2], mount[0]))
    return as_mounted(world, (0.0, 0.0, 0.0))


def test_fit_mount_recovers_the_mount_between_two_lasers() -> None:
    robot = _robot_path()
    left, rear = _laser_path(robot, MOUNTS["left"]), _laser_path(robot, MOUNTS["rear"])
    rng = np.random.default_rng(3)
    noisy = rear + rng.normal(0.0, [0.005, 0.005, 0.001], rear.shape)
    phi, x, y = fit_mount(left, noisy, lag=20)
    # the rear laser in the left laser's frame: 135 deg turned, the mounts' offset seen from the left laser
    d = np.array([-0.9, -0.25])
    c, s = math.cos(-MOUNTS["left"][0]), math.sin(-MOUNTS["left"][0])
    assert math.degrees(phi) == pytest.approx(135.0, abs=0.5)
    assert (x, y) == pytest.approx((c * d[0] - s * d[1], s * d[0] + c * d[1]), abs=0.02)
    mapped = as_mounted(noisy, (phi, x, y))
    assert np.hypot(*(mapped[:, :2] - left[:, :2]).T).max() < 0.05  # the rear's path, seen from the left mount


def test_fit_mount_needs_more_poses_than_its_lag() -> None:
    with pytest.raises(ValueError, match="too few poses"):
        fit_mount(np.zeros((5, 3)), np.zeros((5, 3)), lag=10)


def _paths(robot: np.ndarray, turn_scale: dict[str, float]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each laser's path as a registration that turns ``turn_scale`` times the true turn would give it; the
    robot's path every 0.01 s, each laser's every 0.1 s, their stamps 0.03 s apart (as three lasers' are)."""
    out = {}
    for k, (name, mount) in enumerate(MOUNTS.items()):
        p = _laser_path(robot[3 * k::10], mount)
        steps = as_mounted(p, (0.0, 0.0, 0.0))
        rel = np.diff(steps[:, 2])
        th = np.concatenate([[0.0], np.cumsum(rel * turn_scale.get(name, 1.0))])
        # rebuild the positions from the laser's own steps along the scaled headings
        c, s = np.cos(steps[:-1, 2]), np.sin(steps[:-1, 2])
        dx, dy = np.diff(steps[:, 0]), np.diff(steps[:, 1])
        fwd, side = c * dx + s * dy, -s * dx + c * dy
        x = np.concatenate([[0.0], np.cumsum(np.cos(th[:-1]) * fwd - np.sin(th[:-1]) * side)])
        y = np.concatenate([[0.0], np.cumsum(np.sin(th[:-1]) * fwd + np.cos(th[:-1]) * side)])
        out[name] = (np.arange(len(p)) * 0.1 + 0.03 * k, np.stack([x, y, th], axis=1))
    return out


def test_the_lasers_of_one_robot_agree_and_the_one_that_slips_stands_out() -> None:
    robot = _robot_path(6000, 0.01)
    agree = laser_agreement(_paths(robot, {}))
    assert set(agree) == set(MOUNTS)
    assert max(a["max_offset_m"] for a in agree.values()) < 0.01  # interpolation only
    slip = laser_agreement(_paths(robot, {"rear": 1.02}))  # the rear's registration turns 2 % too far
    assert slip["rear"]["max_offset_m"] > 1.5 * max(slip["left"]["max_offset_m"], slip["right"]["max_offset_m"])
    assert slip["rear"]["final_heading_deg"] > 0 > slip["left"]["final_heading_deg"]
    assert laser_agreement({"left": _paths(robot, {})["left"]}) == {}  # one laser: nothing to compare


def test_a_sweep_is_moved_to_the_laser_pose_at_the_stamp() -> None:
    """A wall seen while the laser turns and drives: each return, moved by the laser's motion over its beam's
    time, lands where the laser at the stamp would have seen it (to first order over the 50 ms sweep)."""
    bearings = np.linspace(-1.0, 1.0, 200)
    tau = np.arange(200) * 2.5e-4
    v = np.array([0.5, 0.0, 0.8])  # body twist: 0.5 m/s forward, 0.8 rad/s
    # the laser at tau: turned by w tau and moved (first order) by v tau; the wall is x = 3 at the stamp
    th = v[2] * tau
    ox = v[0] * tau  # v[1] = 0: no sideways travel
    # the ray from (ox, 0) at angle th + bearing hits x = 3
    ang = th + bearings
    r = (3.0 - ox) / np.cos(ang)
    x, y = r * np.cos(bearings), r * np.sin(bearings)  # as the laser reported them, in its frame at tau
    mx, my = _moved_by_twist(x, y, tau, v)
    assert np.abs(mx - 3.0).max() < 1e-9
    assert np.abs(x - 3.0).max() > 0.05  # uncorrected, the wall was bent by the turn
    assert _twist((0.0, 0.0, 0.0), (0.1, 0.0, 0.2), 0.0).tolist() == [0.0, 0.0, 0.0]  # no time: no motion
    assert _twist((1.0, 1.0, math.pi / 2), (1.0, 1.1, math.pi / 2 + 0.1), 0.1) == pytest.approx([1.0, 0.0, 1.0])


def _room_ranges(pose: tuple[float, float, float], bearings: np.ndarray) -> np.ndarray:
    """Ranges of a laser at ``pose`` in a 6 x 4 m room with a pillar (0.4 m square at (1, 0.8))."""
    x0, y0, th = pose
    out = np.full(bearings.size, np.inf)
    d = np.stack([np.cos(bearings + th), np.sin(bearings + th)], axis=1)
    for (ax, ay), (bx, by) in [((-3, -2), (3, -2)), ((3, -2), (3, 2)), ((3, 2), (-3, 2)), ((-3, 2), (-3, -2)),
                               ((0.8, 0.6), (1.2, 0.6)), ((1.2, 0.6), (1.2, 1.0)), ((1.2, 1.0), (0.8, 1.0)),
                               ((0.8, 1.0), (0.8, 0.6))]:
        e = np.array([bx - ax, by - ay])
        den = d[:, 0] * (-e[1]) - d[:, 1] * (-e[0])
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((ax - x0) * (-e[1]) - (ay - y0) * (-e[0])) / den
            u = (d[:, 0] * (ay - y0) - d[:, 1] * (ax - x0)) / den
        hit = np.isfinite(t) & (t > 0) & (u >= 0) & (u <= 1)
        out = np.where(hit & (t < out), t, out)
    return np.where(np.isfinite(out), out, np.nan)


def test_icp_pose_and_the_loop_closure_find_where_the_laser_ended() -> None:
    bearings = np.radians(np.arange(-135.0, 135.0, 0.35))
    start, end = (-1.0, -0.5, 0.2), (-0.6, -0.6, 0.25)  # the drive ended 0.41 m and 2.9 deg from its start
    rng = np.random.default_rng(5)
    first = [_room_ranges(start, bearings) + rng.normal(0, 0.01, bearings.size) for _ in range(3)]
    last = [_room_ranges(end, bearings) + rng.normal(0, 0.01, bearings.size) for _ in range(3)]
    # the robot's own part at 0.3 m on a few beams in every scan: left out (the robot's reach)
    for r in first + last:
        r[:12] = 0.3
    run = Run("/laser", [Cycle(float(k), (0.0, 0.0, 0.0), [], False, None) for k in range(10)],
              first + [first[0]] * 4 + last, bearings)
    loop = loop_closure(run)
    c, s = math.cos(start[2]), math.sin(start[2])
    dx, dy = end[0] - start[0], end[1] - start[1]
    truth = (c * dx + s * dy, -s * dx + c * dy, end[2] - start[2])
    assert loop is not None and loop[:2] == pytest.approx(truth[:2], abs=0.01)
    assert math.degrees(loop[2]) == pytest.approx(math.degrees(truth[2]), abs=0.1)
    path = np.array([[0.0, 0.0, 0.0], [truth[0] + 0.3, truth[1] + 0.4, truth[2] + math.radians(2.0)]])
    figs = end_vs_loop(path, loop)
    assert figs["end_vs_loop_closure_m"] == pytest.approx(0.5, abs=0.01)
    assert figs["end_heading_vs_loop_closure_deg"] == pytest.approx(2.0, abs=0.1)
    assert loop_closure(Run("/laser", run.cycles[:5], run.ranges[:5], bearings)) is None  # too short: no loop
