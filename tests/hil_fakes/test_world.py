"""The simulated world: scenario geometry, laser ray casting, camera rendering, odometry, adapters."""

from __future__ import annotations

import math
import threading
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil_fakes.wheel_odometry import OdometryNoise, WheelOdometry
from hil_fakes.world import (
    LaserModel,
    ObstaclePath,
    RobotMount,
    ScenarioError,
    World,
    WorldTimeError,
    build_scenario,
    intrinsics,
    load_scenario_file,
    paper_scenario,
)
from hil_fakes.world.scenarios import (
    ROBOT_START,
    ROOM_LENGTH_M,
    ROOM_WIDTH_M,
    check_robot_path,
    default_params,
    robot_path,
    robot_x_at,
)

HALF_W = ROOM_WIDTH_M / 2
NOISELESS = LaserModel(sigma_near_m=0.0, sigma_per_range=0.0, sigma_far_m=0.0)


IDEAL = {"world": "ideal"}


def static_scenario(obstacles: tuple[ObstaclePath, ...] = (), **params: float):
    sc = build_scenario({"world": "ideal", "odom_noise": 0.0, **params})
    return replace(sc, obstacles=obstacles)


# ------------------------------------------------------------------------------------------ scenarios
@pytest.mark.parametrize("crossing_deg", [0.0, 20.0, 45.0, 70.0, 90.0, 120.0])
def test_obstacle_path_crosses_the_robot_path_at_the_asked_angle(crossing_deg: float) -> None:
    sc = build_scenario({"world": "ideal", "crossing_deg": crossing_deg, "odom_noise": 0.0})
    ob = sc.obstacles[0]
    (x0, y0), (x1, y1) = ob.waypoints
    # direction of travel against the robot's heading (+x): the angle between the two paths
    angle = math.degrees(math.atan2(abs(y1 - y0), -(x1 - x0)))
    assert angle == pytest.approx(crossing_deg, abs=1e-6)
    world = World(sc)
    world.command(sc.robot_speed_mps, 0.0, 0.0)
    t_ca = sc.params["closest_approach_time_s"]
    truth = world.truth(t_ca)
    o = truth.obstacles[0]
    assert math.hypot(o.x_m - truth.x_m, o.y_m - truth.y_m) == pytest.approx(sc.params["closest_approach_m"], abs=0.02)
    assert abs(truth.y_m) < 1e-9  # the robot drives straight along y = 0
    if crossing_deg > 0:
        # the obstacle's line meets the robot's path ahead of the robot (it passes in front); from
        # 45 deg on this happens inside the room (at shallow angles a safe pass needs a crossing far
        # ahead, beyond the far wall, and the obstacle passes alongside inside the room)
        s = -y0 / (y1 - y0)
        if crossing_deg >= 45.0:
            assert 0.0 < s < 1.0, "the obstacle crosses the robot's path inside the room"
        t_cross = ob.start_s + s * math.hypot(x1 - x0, y1 - y0) / ob.speed_mps
        x_cross = x0 + s * (x1 - x0)
        assert x_cross > robot_x_at(max(t_cross, 0.0), sc.robot_start[0], sc.robot_speed_mps) + 0.5
    # the whole path stays inside the room
    r = ob.radius_m
    for x, y in ob.waypoints:
        assert r <= x <= ROOM_LENGTH_M - r and -HALF_W + r <= y <= HALF_W - r


def test_no_obstacle_comes_closer_than_asked_over_the_robustness_grid() -> None:
    built = 0
    for angle in range(0, 181, 15):
        for speed in (0.15, 0.5, 1.0):
            for n in (1, 2):
                try:
                    sc = build_scenario(
                        {"world": "ideal", "crossing_deg": angle, "obstacle_speed_mps": speed, "obstacles": n}
                    )
                except ScenarioError as exc:  # a typed refusal naming the key, never a bad world
                    assert exc.key in ("obstacles", "closest_approach_time_s")
                    continue
                built += 1
                t = np.linspace(0.0, sc.duration_s, 1501)
                rx = np.array([robot_x_at(tt, sc.robot_start[0], sc.robot_speed_mps) for tt in t])
                for ob in sc.obstacles:
                    p = ob.positions(t)
                    assert np.min(np.hypot(p[:, 0] - rx, p[:, 1])) >= sc.params["closest_approach_m"] - 1e-6
    assert built >= 70


def test_paper_scenarios_match_the_paper_and_fill_the_scan() -> None:
    for which, angle in (("1", 45.0), ("2", 90.0)):
        sc = paper_scenario(which, IDEAL)
        assert sc.robot_speed_mps == 0.20 and sc.duration_s == 30.0
        (ob,) = sc.obstacles
        assert ob.radius_m == pytest.approx(0.40) and ob.speed_mps == pytest.approx(0.15)
        assert ob.start_s == pytest.approx(5.0)
        assert sc.params["crossing_deg"] == angle
        world = World(sc, laser=NOISELESS)
        world.command(sc.robot_speed_mps, 0.0, 0.0)
        beams = [int(np.sum(world.sweep(t).hit_obstacle >= 0)) for t in np.arange(0.0, 30.0, 1.0)]
        assert max(beams) > 180, beams  # a sixth of the 1081 beams or more near the closest approach
        # standing still before 5 s
        p = ob.positions(np.array([0.0, 4.9, 5.0]))
        assert np.allclose(p[0], p[2])


def test_two_obstacles_never_touch_and_come_from_both_sides() -> None:
    sc = build_scenario({"world": "ideal", "obstacles": 2, "crossing_deg": 90.0})
    a, b = sc.obstacles
    t = np.linspace(0, sc.duration_s, 600)
    d = np.hypot(*(a.positions(t) - b.positions(t)).T)
    assert d.min() > a.radius_m + b.radius_m
    assert np.sign(a.waypoints[0][1]) == -np.sign(b.waypoints[0][1])


def test_fast_obstacle_starts_where_its_path_enters_the_room() -> None:
    sc = build_scenario({"world": "ideal", "obstacle_speed_mps": 1.0, "crossing_deg": 45.0})
    ob = sc.obstacles[0]
    assert ob.start_s > 5.0 and sc.notes
    x, y = ob.waypoints[0]
    assert ob.radius_m <= x <= ROOM_LENGTH_M - ob.radius_m and abs(y) <= HALF_W - ob.radius_m + 1e-9


def test_a_robot_path_through_a_wall_or_the_furniture_is_refused() -> None:
    """A run in which the commanded robot drives through the far wall (0.45 m/s for 25 s in the 8 m
    room) or turns into a piece of furniture measures nothing: the scenario names the key. (Only the
    commanded path is checked: ``sim``'s robot is driven by the daemon's mission.)"""
    with pytest.raises(ScenarioError, match="'robot_speed_mps'.*reaches a wall at 16.5 s"):
        check_robot_path(build_scenario({"obstacles": 0, "robot_speed_mps": 0.45, "duration_s": 25.0}))
    check_robot_path(build_scenario({"obstacles": 0, "robot_speed_mps": 0.45, "duration_s": 15.0}))  # short of it
    with pytest.raises(ScenarioError, match="'robot_yaw_rate_radps'.*runs into a"):
        check_robot_path(build_scenario({"obstacles": 0, "clutter": 3, "duration_s": 25.0, "robot_yaw_rate_radps": 0.3,
                                         "robot_turn_start_s": 3.0, "seed": 401}))
    with pytest.raises(ScenarioError, match="'robot_yaw_rate_radps'.*reaches a wall"):
        check_robot_path(build_scenario({"obstacles": 0, "robot_yaw_rate_radps": 0.1, "robot_turn_start_s": 2.0}))
    path = robot_path({**default_params(), "robot_speed_mps": 0.2, "duration_s": 10.0})
    assert path[-1, 1] == pytest.approx(robot_x_at(10.0, ROBOT_START[0], 0.2), abs=0.01)


def test_scenario_errors_name_the_key(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="'crossing_deg'"):
        build_scenario({"world": "ideal", "crossing_deg": 200.0})
    with pytest.raises(ScenarioError, match="'obstacles'"):
        build_scenario({"world": "ideal", "obstacles": 1.5})
    with pytest.raises(ScenarioError, match="'bogus'"):
        build_scenario({"world": "ideal", "bogus": 1})
    with pytest.raises(ScenarioError, match="'robot_speed_mps'"):
        build_scenario({"world": "ideal", "robot_speed_mps": "fast"})
    with pytest.raises(ScenarioError, match="'closest_approach_m'"):
        build_scenario({"world": "ideal", "closest_approach_m": 0.3})
    # a built scenario's params (unset optional terms included) build the same scenario again
    sc = build_scenario({"world": "ideal", "crossing_deg": 30.0, "odom_scale_error": 0.03})
    assert build_scenario(sc.params) == sc
    assert sc.odometry_noise.scale_error == 0.03 and sc.odometry_noise.sigma_trans_frac == 0.01
    with pytest.raises(ScenarioError, match="'odom_scale_error'"):
        build_scenario({"world": "ideal", "odom_scale_error": 0.9})
    good = tmp_path / "mine.toml"
    good.write_text("crossing_deg = 30\nobstacle_speed_mps = 0.5\nobstacles = 2\n")
    prm = load_scenario_file(good)
    assert prm["name"] == "mine" and build_scenario(prm).params["obstacles"] == 2
    bad = tmp_path / "bad.toml"
    bad.write_text("[scenario]\ncrossing_deg = 30\nspeed = 3\n")
    with pytest.raises(ScenarioError, match="'speed'"):
        load_scenario_file(bad)
    broken = tmp_path / "broken.toml"
    broken.write_text("crossing_deg = = 3\n")
    with pytest.raises(ScenarioError, match="scenario_file"):
        load_scenario_file(broken)


# ------------------------------------------------------------------------------------------ laser
def analytic_room_range(x: float, y: float, ang: float) -> float:
    """Distance from (x, y) inside the room along ang to the three walls (the x = 0 end is open)."""
    c, s = math.cos(ang), math.sin(ang)
    best = math.inf
    if c > 1e-12:
        t = (ROOM_LENGTH_M - x) / c
        if abs(y + t * s) <= HALF_W:
            best = min(best, t)
    if abs(s) > 1e-12:
        t = ((HALF_W if s > 0 else -HALF_W) - y) / s
        if 0.0 <= x + t * c <= ROOM_LENGTH_M:
            best = min(best, t)
    return best


@settings(max_examples=25, deadline=None)
@given(
    x=st.floats(0.5, 7.5),
    y=st.floats(-2.2, 2.2),
    th=st.floats(-math.pi, math.pi),
)
def test_ray_casting_matches_analytic_ranges(x: float, y: float, th: float) -> None:
    sc = replace(static_scenario(), robot_start=(x, y, th))
    mount = RobotMount(laser_x_m=0.0)
    world = World(sc, laser=NOISELESS, mount=mount)
    sw = world.sweep(0.0)
    angles = NOISELESS.angles_rad()
    expected = np.array([analytic_room_range(x, y, th + a) for a in angles])
    expected[(expected > 30.0) | ~np.isfinite(expected)] = np.nan
    assert np.array_equal(np.isnan(sw.ranges_m), np.isnan(expected))
    ok = ~np.isnan(expected)
    assert np.allclose(sw.ranges_m[ok], expected[ok], atol=1e-9)


def test_laser_geometry_noise_and_no_return_into_the_open() -> None:
    lm = LaserModel()
    a = lm.angles_rad()
    assert a.size == 1081 and a[0] == pytest.approx(-0.75 * math.pi) and a[-1] == pytest.approx(0.75 * math.pi)
    assert a[540] == 0.0 and lm.beam_dt_s == pytest.approx(0.025 / 1440)
    # robot near the open end looking backwards-left: those beams see nothing
    sc = replace(static_scenario(), robot_start=(0.3, 0.0, 0.0))
    world = World(sc, mount=RobotMount(laser_x_m=0.0))
    sw = world.sweep(0.0)
    assert np.isnan(sw.ranges_m[:20]).all() and np.isnan(sw.ranges_m[-20:]).all()
    noiseless = World(sc, laser=NOISELESS, mount=RobotMount(laser_x_m=0.0)).sweep(0.0)
    resid = (sw.ranges_m - noiseless.ranges_m)[np.isfinite(sw.ranges_m)]
    assert resid.size > 700
    fin = np.isfinite(sw.ranges_m)
    z = resid / lm.sigma_m(noiseless.ranges_m[fin])  # the noise in units of its modelled sigma at that range
    assert 0.9 < float(np.std(z)) < 1.1 and abs(float(np.mean(resid))) < 0.001
    assert (sw.intensities[np.isfinite(sw.ranges_m)] > 0).all() and (sw.intensities[np.isnan(sw.ranges_m)] == 0).all()


def test_beyond_max_range_is_no_return() -> None:
    short = LaserModel(sigma_near_m=0.0, sigma_per_range=0.0, sigma_far_m=0.0, max_range_m=3.0)
    sc = replace(static_scenario(), robot_start=(4.0, 0.0, 0.0))
    sw = World(sc, laser=short, mount=RobotMount(laser_x_m=0.0)).sweep(0.0)
    assert np.isnan(sw.ranges_m[540])  # front wall 4 m away
    assert sw.ranges_m[540 + 360] == pytest.approx(HALF_W)  # left wall at +90 deg


def test_obstacle_range_and_each_beam_at_its_own_time() -> None:
    ob = ObstaclePath(radius_m=0.4, waypoints=((3.0, 0.0),), speed_mps=0.0, start_s=0.0)
    sc = replace(static_scenario(obstacles=(ob,)), robot_start=(1.0, 0.0, 0.0))
    world = World(sc, laser=NOISELESS, mount=RobotMount(laser_x_m=0.0))
    sw = world.sweep(0.0)
    assert sw.ranges_m[540] == pytest.approx(2.0 - 0.4, abs=1e-9)
    assert sw.hit_obstacle[540] == 0 and sw.hit_obstacle[0] == -1
    half = math.degrees(math.asin(0.4 / 2.0))
    n_hit = int(np.sum(sw.hit_obstacle == 0))
    assert abs(n_hit - 2 * half / 0.25) <= 2
    # a spinning robot: beam i is cast from the heading the robot has at t0 + i*dt
    spin = World(
        replace(static_scenario(), robot_start=(4.0, 0.0, 0.0)), laser=NOISELESS, mount=RobotMount(laser_x_m=0.0)
    )
    spin._robot.w_radps = spin._robot.w_cmd_radps = 3.0
    sw = spin.sweep(0.0)
    dt = NOISELESS.beam_dt_s
    for i in (100, 540, 1000):
        heading = 3.0 * i * dt + NOISELESS.angles_rad()[i]
        assert sw.ranges_m[i] == pytest.approx(analytic_room_range(4.0, 0.0, heading), abs=1e-6)


def test_moving_obstacle_is_seen_where_it_is_at_the_beam_time() -> None:
    ob = ObstaclePath(radius_m=0.3, waypoints=((3.0, -1.0), (3.0, 1.0)), speed_mps=1.0, start_s=0.0)
    sc = replace(static_scenario(obstacles=(ob,)), robot_start=(1.0, 0.0, 0.0))
    world = World(sc, laser=NOISELESS, mount=RobotMount(laser_x_m=0.0))
    sw = world.sweep(1.0)  # the obstacle crosses y = 0 at t = 1 s, i.e. at the sweep's first beams
    hit = np.flatnonzero(sw.hit_obstacle == 0)
    t_hit = 1.0 + hit * NOISELESS.beam_dt_s
    centres = ob.positions(t_hit)
    ang = NOISELESS.angles_rad()[hit]
    px, py = 1.0 + sw.ranges_m[hit] * np.cos(ang), sw.ranges_m[hit] * np.sin(ang)
    assert np.allclose(np.hypot(px - centres[:, 0], py - centres[:, 1]), 0.3, atol=1e-9)


# ------------------------------------------------------------------------------------------ camera
def _reddish(px: np.ndarray) -> bool:
    b, _, r = (float(v) for v in px)
    return r > 1.6 * b


def test_rendering_puts_known_points_on_the_predicted_pixels() -> None:
    ob = ObstaclePath(radius_m=0.4, waypoints=((4.0, 0.6),), speed_mps=0.0, start_s=0.0)
    sc = replace(static_scenario(obstacles=(ob,)), robot_start=(1.0, 0.0, 0.0))
    mount = RobotMount(camera_x_m=0.0, camera_y_m=0.0, camera_z_m=0.5)
    world = World(sc, mount=mount)
    hfov = math.radians(54.0)
    fx, fy, cx, cy = intrinsics(320, 240, hfov)
    img = world.render(0.0, 0.0, 0.0, hfov)
    assert img.shape == (240, 320, 3) and img.dtype == np.uint8
    # the obstacle's left and right silhouette edges (tangent rays from the camera)
    d = math.hypot(3.0, 0.6)
    bearing, half = math.atan2(0.6, 3.0), math.asin(0.4 / d)
    row = int(round(cy))
    for edge, inside_dir in ((bearing + half, +1), (bearing - half, -1)):
        u = cx - fx * math.tan(edge)  # left (CCW) bearing -> smaller u
        ui = int(round(u))
        assert _reddish(img[row, ui + 2 * inside_dir]), (edge, u)
        assert not _reddish(img[row, ui - 2 * inside_dir]), (edge, u)
    # the foot of the far wall (x = 8 m, 7 m ahead) in a column clear of the obstacle
    col = 200
    az = -math.atan((col - cx) / fx)
    dist = (ROOM_LENGTH_M - 1.0) / math.cos(az)
    v = cy + fy * 0.5 * math.sqrt(1 + ((col - cx) / fx) ** 2) / dist
    vi = int(round(v))

    def blue_ratio(p: np.ndarray) -> float:
        return float(p[0]) / max(float(p[2]), 1.0)

    assert blue_ratio(img[vi - 2, col]) > 0.85  # wall: neutral grey
    assert blue_ratio(img[vi + 2, col]) < 0.78  # floor: brown
    # panning left by 10 deg moves the obstacle's edges right by the predicted amount
    pan = math.radians(10.0)
    img2 = world.render(0.0, pan, 0.0, hfov)
    u = cx - fx * math.tan(bearing + half - pan)
    assert _reddish(img2[row, int(round(u)) + 2]) and not _reddish(img2[row, int(round(u)) - 2])


def test_tilted_rendering_matches_the_level_fast_path_at_zero_tilt() -> None:
    sc = paper_scenario("2", IDEAL)
    a = World(sc)
    b = World(sc)
    a.camera = b.camera = replace(a.camera, noise_sigma=0.0)
    img_level = a.render(8.0, 0.1, 0.0, math.radians(40))
    img_generic = b.render(8.0, 0.1, 1e-12, math.radians(40))
    diff = np.abs(img_level.astype(int) - img_generic.astype(int))
    assert np.mean(diff) < 1.0 and np.percentile(diff, 99) <= 8
    tilted = b.render(8.0, 0.0, math.radians(-15), math.radians(54))
    assert tilted.shape == (240, 320, 3)


def test_rendering_has_texture_and_noise() -> None:
    world = World(paper_scenario("1", IDEAL))
    a = world.render(6.0).astype(float)
    b = world.render(6.0).astype(float)  # same scene, fresh sensor noise
    noise = (a - b)[..., 1]
    assert 2.5 < np.std(noise) < 5.0  # two independent noise draws: sqrt(2) * sigma * tint
    grad = np.abs(np.diff(a[..., 1], axis=1))
    assert np.mean(grad) > 3.0  # textured, not flat


# ------------------------------------------------------------------------------------------ odometry
def test_odometry_through_the_world_has_the_asked_statistics() -> None:
    base = build_scenario({"world": "ideal", "odom_noise": 0.0, "duration_s": 10.0})
    sys_noise = OdometryNoise(scale_error=0.02, heading_drift_rad_per_m=0.01)
    world = World(replace(base, odometry_noise=sys_noise))
    world.command(0.5, 0.0, 0.0)
    truth = world.truth(6.0)
    ox, oy, oth, ov, _ = world.odometry(6.0)
    dist_true = truth.x_m - base.robot_start[0]
    assert dist_true > 2.5
    assert oth == pytest.approx(0.01 * dist_true, rel=1e-6)
    # odometry = exact arc integration of the same increments with ds scaled by 1.02
    ref = WheelOdometry(OdometryNoise(scale_error=0.02, heading_drift_rad_per_m=0.01), *base.robot_start)
    ref.step(dist_true, 0.0)
    assert math.hypot(ox - base.robot_start[0], oy) == pytest.approx(1.02 * dist_true, rel=2e-3)
    assert ov == pytest.approx(0.5 * 1.02)
    # random noise: the distance error after D metres has std sigma * sqrt(D)
    errs = []
    for seed in range(40):
        sc = replace(base, odometry_noise=OdometryNoise(sigma_trans_frac=0.05, seed=seed))
        w = World(sc, step_s=0.02)
        w.command(1.0, 0.0, 0.0)
        t = w.truth(4.0)
        x, _, _, _, _ = w.odometry(4.0)
        errs.append(x - t.x_m)
    d = 4.0 - 1.0 / (2 * 0.3)  # distance driven with the 0.3 m/s^2 ramp
    assert abs(np.mean(errs)) < 3 * 0.05 * math.sqrt(d) / math.sqrt(40) + 1e-3
    assert 0.6 * 0.05 * math.sqrt(d) < np.std(errs) < 1.5 * 0.05 * math.sqrt(d)


# ------------------------------------------------------------------------------------------ adapters
def test_adapters_answer_concurrent_queries_consistently() -> None:
    sc = paper_scenario("2", IDEAL)
    world = World(sc, start_s=100.0)
    plant, rs, sonar, rend = world.plant(), world.range_source(), world.sonar(), world.renderer(160, 120)
    plant.command(0.2, 0.0, 100.0)
    assert rend.width_px == 160 and rend.height_px == 120
    errors: list[BaseException] = []
    seen: dict[float, tuple[float, ...]] = {}
    lock = threading.Lock()

    def worker(seed: int) -> None:
        rng = np.random.default_rng(seed)
        try:
            for k in range(40):
                t = 100.0 + 0.05 * k + float(rng.uniform(-0.3, 0.0))
                t = round(max(t, 100.0), 3)
                st_ = plant.state(t)
                with lock:
                    if t in seen:
                        assert np.allclose(seen[t], st_, atol=1e-9), (t, seen[t], st_)
                    seen[t] = st_
                if k % 8 == 0:
                    r, inten = rs.sweep(t, LaserModel().angles_rad(), LaserModel().beam_dt_s)
                    assert r.shape == (1081,) and inten.shape == (1081,)
                    assert rend.render(t, 0.0, 0.0, math.radians(54)).shape == (120, 160, 3)
                rng_ = sonar.ray_range_m(st_[0], st_[1], st_[2], 5.0)
                assert math.isnan(rng_) or 0 < rng_ <= 5.0
        except BaseException as exc:  # noqa: BLE001 - collected and re-raised in the main thread
            errors.append(exc)

    threads = [threading.Thread(target=worker, args=(i,)) for i in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(timeout=60)
    assert not errors, errors[0]
    x, y, th_, v, w = plant.state(101.5)
    assert v == pytest.approx(0.2) and y == pytest.approx(0.0) and x > sc.robot_start[0]
    # a past query interpolates the history; the truth agrees with the plant
    past = plant.state(101.0)
    tr = world.truth(101.0)
    assert past[0] == pytest.approx(tr.x_m) and past[3] == pytest.approx(tr.v_mps)
    t_stop = world.now_s + 0.1
    plant.e_stop(t_stop)
    assert plant.state(t_stop)[3] == 0.0
    assert plant.state(t_stop + 0.5)[0] == pytest.approx(plant.state(t_stop)[0])


def test_history_is_bounded_and_old_queries_are_refused() -> None:
    world = World(paper_scenario("1", IDEAL), history_s=1.0)
    world.command(0.2, 0.0, 0.0)
    world.advance_to(20.0)
    assert world._n < 1.0 / world.step_s + 10
    with pytest.raises(WorldTimeError):
        world.state(10.0)
    with pytest.raises(WorldTimeError, match="wrong clock"):
        world.state(1.7e9)  # e.g. time.time() where time.monotonic() was meant
    with pytest.raises(WorldTimeError):
        world.state(math.inf)
    assert world.state(19.5)[0] > 0
    # before the start, the robot stands at its start pose
    fresh = World(paper_scenario("1", IDEAL), start_s=5.0)
    assert fresh.state(4.0)[:3] == pytest.approx(paper_scenario("1", IDEAL).robot_start)


def test_sonar_ranges_walls_and_obstacles() -> None:
    ob = ObstaclePath(radius_m=0.5, waypoints=((3.0, 1.0),), speed_mps=0.0, start_s=0.0)
    world = World(static_scenario(obstacles=(ob,)))
    sonar = world.sonar()
    assert sonar.ray_range_m(1.0, 0.0, math.pi / 2, 5.0) == pytest.approx(HALF_W)
    assert sonar.ray_range_m(3.0, -1.0, math.pi / 2, 5.0) == pytest.approx(1.5)
    assert math.isnan(sonar.ray_range_m(1.0, 0.0, 0.0, 5.0))  # far wall 7 m away
    assert math.isnan(sonar.ray_range_m(1.0, 0.0, math.pi, 5.0))  # the open end


STRESS_FILES = sorted((Path(__file__).resolve().parents[2] / "docs" / "scenarios").glob("*.toml"))


@pytest.mark.parametrize("path", STRESS_FILES, ids=[p.stem for p in STRESS_FILES])
def test_the_documented_stress_scenarios_build(path: Path) -> None:
    """docs/scenarios: the stress checks beyond the realistic suite (docs/evaluation.md) stay valid."""
    from hil_fakes.world.pedestrians import PEDESTRIAN_DATA_DIR

    prm = load_scenario_file(path)
    if prm.get("person_path_source", "scripted") != "scripted" and not PEDESTRIAN_DATA_DIR.is_dir():
        pytest.skip("../shared/data/pedestrian_trajectories absent")
    sc = build_scenario(prm)
    check_robot_path(sc)
    assert sc.world == "realistic" and sc.name == path.stem


def test_there_are_stress_scenarios() -> None:
    assert len(STRESS_FILES) >= 10
