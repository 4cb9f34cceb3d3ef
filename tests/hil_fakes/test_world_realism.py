"""The realistic world's models pinned to physics and datasheets (never to the estimator)."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from hil_fakes.wheel_odometry import OdometryNoise, WheelOdometry
from hil_fakes.world import LaserModel, ObstaclePath, RobotMount, World, build_scenario, intrinsics
from hil_fakes.world.camera_effects import CameraEffects, distortion_maps
from hil_fakes.world.geometry import Gait
from hil_fakes.world.laser_effects import LaserEffects
from hil_fakes.world.people import leg_centres
from hil_fakes.world.scenarios import REALISTIC_SUITE, ScenarioError, suite_scenario, validate_params


def _static(obstacles: tuple[ObstaclePath, ...] = (), **params: object) -> object:
    sc = build_scenario({"odom_noise": 0.0, "robot_speed_mps": 0.0, "obstacles": 0, **params})
    return replace(sc, obstacles=obstacles)


# ------------------------------------------------------------------------------------------ laser
def _post_sweeps(x_post_m: float, radius_m: float, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Sweeps of a still robot at x = 0.6 m facing a post (centre on the laser's axis at ``x_post_m``)
    with the far wall (x = 8 m) behind it: (ranges (n, beams), the ideal post distance per beam (inf: the
    beam misses it), the far wall's distance per beam, the silhouette's bearing)."""
    post = ObstaclePath(radius_m=radius_m, waypoints=((x_post_m, 0.0),), speed_mps=0.0, start_s=0.0)
    sc = _static((post,), laser_dropout_prob=0.0, laser_spurious_prob=0.0)
    world = World(sc, mount=RobotMount(laser_x_m=0.0))
    ang = world.laser.angles_rad()
    x0 = sc.robot_start[0]
    d_post = np.full(ang.size, np.inf)
    b = (x0 - x_post_m) * np.cos(ang)
    disc = b * b - ((x0 - x_post_m) ** 2 - radius_m**2)
    hit = disc >= 0
    d_post[hit] = -b[hit] - np.sqrt(disc[hit])
    d_wall = (8.0 - x0) / np.cos(ang)
    sweeps = np.array([world.sweep(float(k)).ranges_m for k in range(n)])
    return sweeps, d_post, d_wall, math.asin(radius_m / (x_post_m - x0))


def test_mixed_pixels_lie_between_the_two_surfaces_and_only_at_depth_edges() -> None:
    """A post 0.45 m in front of the far wall (less than the echo separation: the echoes merge): every
    return off both surfaces lies between them, beside the post's silhouette."""
    sweeps, d_post, d_wall, silhouette = _post_sweeps(7.4, 0.15, 20)
    fx = LaserEffects()
    ang = LaserModel().angles_rad()
    edge_half = fx.divergence_rad / 2 + LaserModel().angle_increment_rad
    front = np.abs(ang) < 0.2
    off = np.isfinite(sweeps) & (np.abs(sweeps - d_post) > 0.03) & (np.abs(sweeps - d_wall) > 0.03) & front
    k, idx = np.nonzero(off)
    assert idx.size > 0  # merged echoes do float between the post and the wall
    assert np.all(np.abs(np.abs(ang[idx]) - silhouette) <= edge_half), ang[idx]
    r = sweeps[k, idx]
    assert np.all(r > 7.4 - 0.15 - 0.6 - 0.03) and np.all(r < d_wall[idx] + 0.03)


def test_echoes_farther_apart_than_the_separation_do_not_mix() -> None:
    """A post 4 m in front of the wall: the two echoes are resolved, the beam reports one surface (the
    stronger echo) and nothing floats between them."""
    sweeps, d_post, d_wall, _ = _post_sweeps(3.5, 0.15, 20)
    ang = LaserModel().angles_rad()
    front = np.isfinite(sweeps) & (np.abs(ang) < 0.2)
    off = front & (np.abs(sweeps - d_post) > 0.03) & (np.abs(sweeps - d_wall) > 0.03)
    assert not off.any(), sweeps[off]


def test_grazing_beams_give_no_return() -> None:
    fx = LaserEffects(dropout_prob=0.0, spurious_prob=0.0)
    sc = replace(_static(), laser_effects=fx, robot_start=(0.6, 2.0, 0.0))  # 0.45 m from the left wall
    world = World(sc, mount=RobotMount(laser_x_m=0.0))
    r = world.sweep(0.0).ranges_m
    ang = world.laser.angles_rad()
    # beams to the left at a small angle meet the left wall (y = 2.45) at incidence 90 deg - angle
    on_side = (ang > 0.0) & (np.tan(ang) * 7.4 > 0.45 + 0.05) & (ang < math.radians(60))
    incidence_deg = 90.0 - np.degrees(ang)
    grazing = on_side & (incidence_deg > fx.grazing_limit_deg + 0.5)
    assert grazing.sum() > 10
    assert np.isnan(r[grazing]).all()
    ok = on_side & (incidence_deg < fx.grazing_limit_deg - 0.5)
    assert np.isfinite(r[ok]).mean() > 0.95


def test_a_static_scene_from_a_robot_at_rest_changes_only_by_noise_and_artefacts() -> None:
    sc = _static(clutter=2)
    world = World(sc)
    sweeps = np.array([world.sweep(0.5 * k).ranges_m for k in range(40)])
    ideal = World(replace(sc, laser_effects=LaserEffects(enabled=False))).sweep(0.0).ranges_m
    filled = np.where(np.isfinite(ideal), ideal, 100.0)
    jump = np.abs(np.diff(filled)) > 0.05
    edge = np.zeros(ideal.size, bool)
    edge[:-1] |= jump
    edge[1:] |= jump
    edge = np.convolve(edge, np.ones(5), "same") > 0  # the footprint is wider than one step
    both = np.isfinite(sweeps).all(axis=0)
    dev = np.abs(sweeps - ideal)
    outlier = dev > 0.050  # beyond 5x the largest sigma inside the room (NaN compares False)
    assert edge.sum() > 20  # furniture makes many depth edges
    # away from depth edges: only the rare dropouts / spurious returns (0.1 % + 0.02 % per beam)
    assert np.mean(outlier[:, ~edge & np.isfinite(ideal)]) < 0.004
    med = np.median(sweeps[:, both], axis=0)
    dev = np.abs(sweeps[:, both] - med)
    stable = np.all(dev < 0.05, axis=0)
    std = np.std(sweeps[:, both][:, stable], axis=0)
    # the range noise of LaserModel (2.2 mm + 0.7 mm per metre: measured on a recorded UTM-30LX frame)
    expected = world.laser.sigma_m(med[stable])
    assert 0.85 < float(np.median(std / expected)) < 1.15


def test_range_noise_grows_with_range_to_the_datasheet_bound() -> None:
    lm = LaserModel()
    near, mid, ten = (float(lm.sigma_m(np.array(r))) for r in (1.0, 3.3, 10.0))
    assert 0.002 < near < mid < ten  # a weaker echo times less precisely
    assert 3 * ten <= 0.030 + 1e-9  # the datasheet's +-30 mm (0.1-10 m) holds as 3 sigma at 10 m
    assert float(lm.sigma_m(np.array(12.0))) == lm.sigma_far_m
    with pytest.raises(ValueError, match="range noise"):
        LaserModel(sigma_per_range=-0.001)


def test_the_noise_scale_multiplies_the_range_noise() -> None:
    """``laser_noise_scale`` (a pessimistic world: 3 is the datasheet's bound read as 3 sigma) scales the
    scan-to-scan spread of a static scene, nothing else."""
    fx = LaserEffects(echo_separation_m=0.0, dropout_prob=0.0, spurious_prob=0.0)
    spreads = []
    for scale in (1.0, 3.0):
        world = World(replace(_static(), laser_effects=replace(fx, noise_scale=scale)))
        sweeps = np.array([world.sweep(0.5 * k).ranges_m for k in range(30)])
        ok = np.isfinite(sweeps).all(axis=0)
        spreads.append(float(np.median(np.std(sweeps[:, ok], axis=0))))
    assert 2.6 < spreads[1] / spreads[0] < 3.4
    with pytest.raises(ValueError, match="noise_scale"):
        LaserEffects(noise_scale=-1.0)
    with pytest.raises(ScenarioError, match="laser_noise_scale"):
        validate_params({"laser_noise_scale": 11.0})


def test_dropouts_and_spurious_returns_have_the_configured_rates() -> None:
    fx = LaserEffects(echo_separation_m=0.0, dropout_prob=0.05, spurious_prob=0.05, grazing_limit_deg=90.0)
    world = World(replace(_static(), laser_effects=fx), mount=RobotMount(laser_x_m=0.0))
    ideal = World(replace(_static(), laser_effects=LaserEffects(enabled=False)), mount=RobotMount(laser_x_m=0.0))
    ref = ideal.sweep(0.0).ranges_m
    valid = np.isfinite(ref)
    drops, short = 0, 0
    n = 0
    for k in range(30):
        r = world.sweep(float(k)).ranges_m
        drops += int(np.sum(np.isnan(r[valid])))
        short += int(np.sum(r[valid] < ref[valid] - 0.1))
        n += int(valid.sum())
    assert drops / n == pytest.approx(0.05, abs=0.01)
    assert short / n == pytest.approx(0.05, abs=0.01)


# ------------------------------------------------------------------------------------------ people
def test_legs_follow_the_gait() -> None:
    gait = Gait()
    path = ObstaclePath(0.25, ((0.0, 0.0), (20.0, 0.0)), 1.3, 0.0, gait=gait)
    t = np.arange(0.0, 10.0, 0.002)
    feet = leg_centres(path, gait, t, 0.0)  # at floor level the shin section is the foot
    centre = path.positions(t)
    for k in range(2):
        v = np.hypot(*np.gradient(feet[:, k], t, axis=0).T)
        standing = v < 0.05
        assert standing.mean() == pytest.approx(gait.stance_frac, abs=0.03)  # stance ~60 % of the stride
        assert np.abs(feet[:, k, 1] - centre[:, 1]).max() == pytest.approx(gait.hip_halfwidth_m, abs=1e-9)
        # successive footprints are one stride apart
        starts = np.flatnonzero(np.diff(standing.astype(int)) == 1)
        steps = np.diff(feet[starts, k, 0])
        assert np.allclose(steps, gait.stride_m, atol=0.01)
    # the legs scissor: never both swinging, and at laser height they swing 2/3 as far as the feet
    shins = leg_centres(path, gait, t, 0.30)
    reach_feet = np.max(np.abs(feet[:, 0, 0] - centre[:, 0]))
    reach_shins = np.max(np.abs(shins[:, 0, 0] - centre[:, 0]))
    assert reach_shins / reach_feet == pytest.approx(1 - 0.30 / gait.leg_length_m, rel=1e-6)
    # a person who has not started walking stands with both feet under the pelvis
    still = ObstaclePath(0.25, ((1.0, 1.0), (5.0, 1.0)), 1.3, 5.0, gait=gait)
    legs = leg_centres(still, gait, np.array([0.0, 4.9]), 0.3)
    assert np.allclose(legs[:, :, 0], 1.0, atol=1e-9)


def test_a_person_in_the_scan_is_two_leg_arcs_and_truth_is_the_body_centre() -> None:
    sc = suite_scenario("cross_90")
    world = World(sc)
    world.command(sc.robot_speed_mps, 0.0, 0.0)
    t = sc.obstacles[0].start_s + 1.5
    truth = world.truth(t)
    person = truth.obstacles[0]
    assert person.kind == "person" and person.moving and len(person.legs) == 2
    sweep = world.sweep(t)
    assert 5 <= int(np.sum(sweep.hit_obstacle == 0)) <= 80
    legs = np.array(person.legs)
    assert np.hypot(*(legs.mean(axis=0) - (person.x_m, person.y_m))) < 0.45


# ------------------------------------------------------------------------------------------ camera
def test_the_distortion_map_inverts_opencvs_lens_model() -> None:
    w, h = 320, 240
    fx, fy, cx, cy = intrinsics(w, h, math.radians(54.0))
    k1, k2, margin = -0.15, 0.02, 38
    map_x, map_y = distortion_maps(w, h, fx, fy, cx + 3.0, cy - 2.0, k1, k2, margin)
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-0.45, 0.45, 200), rng.uniform(-0.33, 0.33, 200), np.ones(200)])
    k = np.array([[fx, 0, cx + 3.0], [0, fy, cy - 2.0], [0, 0, 1]])
    dist_px, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), k, np.array([k1, k2, 0, 0, 0]))
    pin_px, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), k, np.zeros(5))
    for (u, v), (pu, pv) in zip(dist_px[:, 0], pin_px[:, 0], strict=True):
        if not (0 <= u <= w - 1 and 0 <= v <= h - 1):
            continue
        mx = cv2.getRectSubPix(map_x[..., None], (1, 1), (float(u), float(v)))[0, 0]
        my = cv2.getRectSubPix(map_y[..., None], (1, 1), (float(u), float(v)))[0, 0]
        assert mx == pytest.approx(pu + margin, abs=0.05) and my == pytest.approx(pv + margin, abs=0.05)


def test_a_rendered_post_lands_on_the_pixel_the_lens_model_predicts() -> None:
    post = ObstaclePath(radius_m=0.4, waypoints=((4.0, 0.6),), speed_mps=0.0, start_s=0.0)
    fxc = CameraEffects(exposure_s=0.0, exposure_drift=0.0, vignetting=0.0, k1=-0.18, k2=0.0,
                        pp_offset_px=(4.0, -3.0), mount_yaw_rad=math.radians(0.8))
    sc = replace(_static((post,)), camera_effects=fxc, robot_start=(1.0, 0.0, 0.0))
    mount = RobotMount(camera_x_m=0.0, camera_y_m=0.0, camera_z_m=0.5)
    world = World(sc, mount=mount)
    fx, fy, cx, cy = intrinsics(320, 240, math.radians(54.0))
    img = world.render(0.0, 0.0, 0.0, math.radians(54.0))
    d = math.hypot(3.0, 0.6)
    bearing, half = math.atan2(0.6, 3.0), math.asin(0.4 / d)
    k = np.array([[fx, 0, cx + 4.0], [0, fy, cy - 3.0], [0, 0, 1]])
    for edge, inside in ((bearing + half, +1), (bearing - half, -1)):
        rel = edge - fxc.mount_yaw_rad
        p = np.array([[-math.sin(rel), 0.0, math.cos(rel)]]) * d  # camera frame: x right, y down, z forward
        (u, v), = cv2.projectPoints(p, np.zeros(3), np.zeros(3), k, np.array([fxc.k1, 0, 0, 0, 0]))[0][:, 0]
        row, col = int(round(v)), int(round(u))
        b_in, _, r_in = (float(c) for c in img[row, col + 3 * inside])
        b_out, _, r_out = (float(c) for c in img[row, col - 3 * inside])
        assert r_in > 1.6 * b_in and not r_out > 1.6 * b_out, (edge, u)


def test_the_camera_clock_runs_free_and_frames_arrive_late() -> None:
    sc = build_scenario({})
    clock = World(sc).camera_clock
    fx = sc.camera_effects
    assert clock.period_s == pytest.approx((1 + fx.clock_ppm * 1e-6) / fx.fps)
    lat = np.array([clock.latency_s(n) for n in range(500)])
    assert fx.latency_s[0] <= lat.min() and lat.max() <= fx.latency_s[1] and lat.std() > 0.01
    for t in np.arange(1.0, 3.0, 0.037):
        f = clock.newest(float(t))
        assert f is not None and f.delivery_s <= t and f.capture_s == clock.capture_s(f.seq)
        nxt = f.seq + 1
        assert clock.capture_s(nxt) + clock.latency_s(nxt) > t or clock.newest(float(t)).seq >= nxt


# ------------------------------------------------------------------------------------------ odometry
def test_wheelbase_error_scales_rotation_and_sip_delay_and_units_apply() -> None:
    odo = WheelOdometry(OdometryNoise(rot_scale_error=0.02))
    for _ in range(100):
        odo.step(0.0, 2 * math.pi / 100)
    assert odo.heading_unwrapped_rad == pytest.approx(2 * math.pi * 1.02)
    sc = build_scenario({"odom_noise": 0.0, "obstacles": 0})
    world = World(sc)
    world.command(0.3, 0.0, 0.0)
    x, y, th, v, _ = world.odometry(3.0)
    assert x * 1000 == pytest.approx(round(x * 1000)) and th / (2 * math.pi / 4096) == pytest.approx(
        round(th / (2 * math.pi / 4096)))
    true_then = world.state(3.0 - sc.sip_delay_s)[0]
    assert x == pytest.approx(true_then, abs=0.0006)


def test_suite_scenarios_build_with_their_seeds_and_others() -> None:
    for name in REALISTIC_SUITE:
        a, b = suite_scenario(name), suite_scenario(name, seed=7)
        assert a.world == "realistic" and a.seed != b.seed
        assert suite_scenario(name, overrides={"duration_s": 3.0}).duration_s == 3.0
    assert suite_scenario("static_clutter").obstacles == ()
    assert all(o.gait is not None for o in suite_scenario("two_people_opposite").obstacles)
    with pytest.raises(ScenarioError, match="world"):
        build_scenario({"world": "dreamy"})
    with pytest.raises(ScenarioError, match="seed"):
        build_scenario({"seed": -1})
