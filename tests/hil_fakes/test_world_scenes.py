"""The hard people scenes (issue 29): each builds, and its physics and truth are what the scene says."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil_fakes.world import World, build_scenario
from hil_fakes.world.camera_effects import CameraEffects, light_and_gain
from hil_fakes.world.geometry import ObstaclePath, RigidBox
from hil_fakes.world.people import leg_centres
from hil_fakes.world.scenarios import (
    REALISTIC_SUITE,
    ROOM_WIDTH_M,
    ScenarioError,
    check_robot_path,
    suite_scenario,
)
from hil_fakes.world.scenes import CART_REACH_M, walk_profile

NEW = ("crowd", "stop_and_go", "wall_hugger", "turn_in_place", "cart_pusher", "lights_off", "door_swing")
RECORDED = {"crowd", "stop_and_go", "turn_in_place", "cart_pusher"}


def _scene(name: str, shared_data: object, seed: int | None = None) -> object:
    del shared_data  # the fixture skips when ../shared/data is absent (recorded walking paths)
    return suite_scenario(name, seed)


@pytest.mark.parametrize("name", NEW)
def test_each_scene_builds_on_two_seeds_and_keeps_its_robot_off_the_walls(name: str, request: pytest.FixtureRequest
                                                                         ) -> None:
    if name in RECORDED:
        request.getfixturevalue("shared_data")
    assert name in REALISTIC_SUITE and REALISTIC_SUITE[name]["targets"] == "issue29"
    for seed in (None, 7):
        sc = suite_scenario(name, seed)
        check_robot_path(sc)
        assert sc.world == "realistic"


def test_crowd_eight_recorded_walkers_two_side_by_side_0_4_m_apart(shared_data: object) -> None:
    sc = _scene("crowd", shared_data)
    people = [o for o in sc.obstacles if o.kind == "person"]
    assert len(people) == 8
    a, b = people[0], people[1]
    t = np.linspace(0.0, sc.duration_s, 801)
    d = a.positions(t) - b.positions(t)
    assert np.allclose(np.hypot(d[:, 0], d[:, 1]), 0.4, atol=2e-3)
    v = a.velocities(t)
    walking = np.hypot(v[:, 0], v[:, 1]) > 0.3
    across = np.abs(np.sum(d * v, axis=1)) / np.maximum(np.hypot(v[:, 0], v[:, 1]), 1e-9)
    # side by side, not one behind: beside the line of walking over a stride, so the walker's own sway
    # (a few deg within a stride) puts it at most 0.4 m x sin 15 deg ahead or behind
    assert walking.sum() > 50 and np.percentile(across[walking], 90) < 0.1
    # and not swinging its speed with each sway: steady beside a steady walker
    both = walking & (np.hypot(*b.velocities(t).T) > 0.3)
    assert float(np.std(np.hypot(*b.velocities(t)[both].T) - np.hypot(*v[both].T))) < 0.1
    legs_a = leg_centres(a, a.gait, t, 0.3)
    legs_b = leg_centres(b, b.gait, t, 0.3)
    gap = min(float(np.min(np.hypot(*(legs_a[:, i] - legs_b[:, j]).T))) for i in range(2) for j in range(2))
    assert gap > 2 * a.gait.leg_radius_m  # legs 0.1 m apart never touch
    inside = np.abs(np.stack([p.positions(t)[:, 1] for p in people])) < ROOM_WIDTH_M / 2
    for i in range(2, 8):  # the others keep a body's distance (0.1 m between bodies) while in the room
        for j in range(i):
            both = inside[i] & inside[j]
            dd = np.hypot(*(people[i].positions(t) - people[j].positions(t)).T)
            assert not np.any(both & (dd < 0.5))


def test_stop_and_go_stands_walks_stops_stands_walks_on(shared_data: object) -> None:
    sc = _scene("stop_and_go", shared_data)
    (p,) = sc.obstacles
    starts = p.walk_starts_s()
    assert len(starts) == 2 and starts[0] > 0.5
    t = np.arange(0.0, sc.duration_s, 0.01)
    speed = p.speeds(t)
    assert np.all(speed[t < starts[0]] == 0)
    stopped = (t > starts[0] + 1.0) & (t < starts[1]) & (speed == 0)
    assert stopped.sum() * 0.01 >= sc.params["stop_duration_s"] - 0.02
    assert np.max(speed) == pytest.approx(sc.params["obstacle_speed_mps"], rel=1e-6)
    t_k = np.array([k[0] for k in p.profile])
    speed_k = p.speeds(0.5 * (t_k[1:] + t_k[:-1]))  # one speed per 20 ms knot interval
    accel = np.abs(np.diff(speed_k)) / np.diff(0.5 * (t_k[1:] + t_k[:-1]))
    assert np.max(accel) <= sc.params["obstacle_speed_mps"] / sc.params["walk_accel_s"] * 1.05
    world = World(sc)
    mid = starts[1] - 1.0
    assert not world.truth(mid).obstacles[0].moving and world.truth(starts[1] + 0.3).obstacles[0].moving
    legs = leg_centres(p, p.gait, np.array([mid - 1.0, mid]), 0.3)
    assert np.allclose(legs[0], legs[1])  # a person standing still keeps their feet where they are


def test_walk_profile_is_one_step_to_speed_and_stop() -> None:
    knots = np.array(walk_profile(4.0, 1.0, 1.2, 0.6, stop_at_m=1.5, stop_duration_s=2.0))
    assert knots[0, 0] == 1.0 and knots[-1, 1] == pytest.approx(4.0)
    path = ObstaclePath(0.25, ((0.0, 0.0), (4.0, 0.0)), 1.2, 1.0, profile=tuple(map(tuple, knots)))
    assert path.walk_starts_s()[0] == 1.0 and len(path.walk_starts_s()) == 2
    assert path.positions(1.3)[0] == pytest.approx(0.5 * 2.0 * 0.3**2, abs=1e-3)  # a = 1.2 / 0.6 m/s^2


def test_wall_hugger_walks_0_2_m_from_the_wall() -> None:
    sc = suite_scenario("wall_hugger")
    (p,) = sc.obstacles
    t = np.linspace(p.start_s, p.end_s, 200)
    legs = leg_centres(p, p.gait, t, 0.3)
    gap = ROOM_WIDTH_M / 2 - (np.max(legs[..., 1], axis=1) + p.gait.leg_radius_m)
    assert np.allclose(gap, 0.2, atol=1e-9)
    world = World(sc)
    world.command(*sc.command_at(0.0), 0.0)
    hits = world.sweep(5.0).hit_obstacle
    assert int(np.sum(hits == 0)) >= 5  # the laser sees the walker beside the wall


def test_turn_in_place_turns_at_0_5_rad_s_while_a_person_crosses(shared_data: object) -> None:
    sc = _scene("turn_in_place", shared_data)
    world = World(sc)
    world.command(*sc.command_at(0.0), 0.0)
    a, b = world.truth(4.0), world.truth(6.0)
    assert math.hypot(b.x_m - a.x_m, b.y_m - a.y_m) < 1e-9
    turned = math.atan2(math.sin(b.theta_rad - a.theta_rad), math.cos(b.theta_rad - a.theta_rad))
    assert turned == pytest.approx(1.0 - 2 * math.pi if turned < 0 else 1.0, abs=0.02)
    (p,) = sc.obstacles
    assert p.positions(p.start_s)[1] * p.positions(p.end_s)[1] < 0  # crosses from one side to the other


def test_cart_moves_with_its_pusher_and_the_laser_sees_its_faces(shared_data: object) -> None:
    sc = _scene("cart_pusher", shared_data)
    pusher, cart = sc.obstacles
    assert isinstance(cart, RigidBox) and (cart.length_m, cart.width_m) == (0.8, 0.5)
    t = np.linspace(0.0, sc.duration_s, 401)
    pose = cart.poses(t)
    u = np.stack([np.cos(pose[:, 2]), np.sin(pose[:, 2])], axis=1)
    rear = pose[:, :2] - 0.4 * u
    assert np.allclose(np.hypot(*(rear - pusher.positions(t)).T), CART_REACH_M, atol=1e-3)
    walking = np.hypot(*pusher.velocities(t).T) > 0
    cart_moving = np.hypot(*cart.velocities(t).T) > 0
    assert np.mean(walking == cart_moving) > 0.98  # moves when its pusher does (20 ms knots aside)
    world = World(sc)
    world.command(*sc.command_at(0.0), 0.0)
    t_mid = 0.5 * (pusher.start_s + pusher.end_s)
    sweep = world.sweep(t_mid)
    on = np.flatnonzero(sweep.hit_obstacle == 1)
    assert on.size >= 10
    _assert_on_box_faces(world, sweep, on, cart, t_mid, tol_m=0.08)


def _assert_on_box_faces(world: World, sweep: object, beams: np.ndarray, box: RigidBox, t0: float, tol_m: float
                         ) -> None:
    """Every return on the box lies on its outline (laser noise and mixed pixels aside: the median)."""
    times = t0 + beams * sweep.beam_dt_s
    x, y, th = world.robot_pose(times)
    m = world.mount
    ang = th + m.laser_theta_rad + world.laser.angles_rad()[beams]
    px = x + np.cos(th) * m.laser_x_m + sweep.ranges_m[beams] * np.cos(ang)
    py = y + np.sin(th) * m.laser_x_m + sweep.ranges_m[beams] * np.sin(ang)
    pose = box.poses(times)
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    lx = c * (px - pose[:, 0]) + s * (py - pose[:, 1])
    ly = -s * (px - pose[:, 0]) + c * (py - pose[:, 1])
    outside = np.maximum(np.abs(lx) - box.length_m / 2, np.abs(ly) - box.width_m / 2)
    assert np.median(np.abs(outside)) < 0.03 and np.percentile(np.abs(outside), 80) < tol_m


def test_door_rotates_about_its_hinge_and_opens_the_doorway() -> None:
    sc = suite_scenario("door_swing")
    (door,) = sc.obstacles
    assert isinstance(door, RigidBox) and door.kind == "door"
    t = np.linspace(0.0, sc.duration_s, 1001)
    pose = door.poses(t)
    hinge = pose[:, :2] - 0.5 * door.length_m * np.stack([np.cos(pose[:, 2]), np.sin(pose[:, 2])], axis=1)
    assert np.allclose(hinge, hinge[0], atol=1e-9)  # the hinge stays put
    assert hinge[0, 1] == pytest.approx(ROOM_WIDTH_M / 2)
    assert pose[0, 2] == pytest.approx(math.pi) and np.max(pose[:, 2]) == pytest.approx(1.5 * math.pi)  # 90 deg in
    assert pose[-1, 2] == pytest.approx(math.pi)  # closed again
    rate = np.abs(door.rates(t)[:, 2])
    assert np.max(rate) == pytest.approx(math.pi / 2 * math.pi / 2 / sc.params["door_swing_s"], rel=0.02)
    world = World(sc)
    world.command(*sc.command_at(0.0), 0.0)
    closed = world.sweep(3.0)
    assert int(np.sum(closed.hit_obstacle == 0)) >= 10  # the closed leaf fills the doorway
    sweep = world.sweep(9.0)  # open
    on = np.flatnonzero(sweep.hit_obstacle == 0)
    assert on.size >= 10
    _assert_on_box_faces(world, sweep, on, door, 9.0, tol_m=0.05)
    x, y, th = world.robot_pose(9.0)
    m = world.mount
    lx, ly = x + math.cos(th) * m.laser_x_m, y + math.sin(th) * m.laser_x_m
    mid = sc.params["door_hinge_x_m"] - 0.45  # the doorway's middle
    bearing = math.atan2(ROOM_WIDTH_M / 2 + 0.5 - ly, mid - lx) - th
    k = int(np.argmin(np.abs(world.laser.angles_rad() - bearing)))
    assert sweep.ranges_m[k] > math.hypot(mid - lx, ROOM_WIDTH_M / 2 - ly) + 0.5  # through the open doorway



def test_lights_off_raise_gain_and_noise_threefold_in_auto_exposure_steps() -> None:
    fx = CameraEffects(lights=((5.0, 1.0 / 3.0), (15.0, 1.0)))
    assert light_and_gain(4.9, fx) == (1.0, 1.0)
    level, gain = light_and_gain(5.05, fx)
    assert level == pytest.approx(1 / 3) and gain == 1.0  # the exposure jump: a third as bright
    gains = [light_and_gain(5.0 + 0.2 * k + 0.01, fx)[1] for k in range(8)]
    steps = np.diff(20 * np.log10(gains))
    assert np.all(steps <= fx.ae_step_db + 1e-9) and gains[-1] == pytest.approx(3.0)
    assert light_and_gain(16.5, fx) == (1.0, pytest.approx(1.0))
    sc = suite_scenario("lights_off")
    assert sc.obstacles == () and sc.camera_effects.lights == ((5.0, pytest.approx(1 / 3)), (15.0, 1.0))
    world = World(sc)
    noise, mean = {}, {}
    for t in (3.0, 10.0):  # two renders of the same instant differ by the sensor noise only
        a, b = (world.render(t).astype(float) for _ in range(2))
        noise[t] = float(np.std(a - b) / math.sqrt(2))
        mean[t] = float(np.mean(a))
    assert noise[10.0] / noise[3.0] == pytest.approx(3.0, rel=0.15)
    assert mean[10.0] == pytest.approx(mean[3.0], rel=0.1)  # the gain restores the brightness


def test_bad_hard_scene_keys_are_scenario_errors() -> None:
    for bad, key in (
        ({"lights_off_s": 5.0, "lights_on_s": 4.0}, "lights_on_s"),
        ({"scene": "door", "door_open_s": 6.0, "door_close_s": 6.5}, "door_close_s"),
        ({"scene": "crowd"}, "scene"),
        ({"scene": "hall"}, "scene"),
        ({"obstacle_kind": "person", "companion_offset_m": 0.25}, "companion_offset_m"),
    ):
        with pytest.raises(ScenarioError) as err:
            build_scenario(bad)
        assert err.value.key == key
