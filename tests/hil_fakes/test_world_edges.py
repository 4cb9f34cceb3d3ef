"""The world's laser at depth edges pinned to the physics of a pulsed receiver, and to recorded UTM-30LX scans.

A pulsed time-of-flight receiver sees one echo per surface in the footprint; echoes closer in range than
the pulse's length merge into one peak between them (a mixed pixel), echoes farther apart stay two and
the stronger is timed. :mod:`hil_fakes.world.edges` measures recorded scans and the world's sweeps alike.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hil_fakes.world import LaserModel, ObstaclePath, RobotMount, World, build_scenario
from hil_fakes.world.edges import EdgeCriteria, classify_edges, rates, scan_edges
from hil_fakes.world.laser_effects import LaserEffects, echo_peak
from hil_fakes.world.scenarios import ScenarioError, suite_scenario, validate_params

SEP_M = LaserEffects().echo_separation_m


def _peak(near_m: float, far_m: float, n_near: int, fx: LaserEffects | None = None) -> float:
    d = np.array([[near_m] * n_near + [far_m] * (5 - n_near)])
    r, _, _ = echo_peak(d, np.ones_like(d), d <= near_m + 0.01, fx or LaserEffects())
    return float(r[0])


# ------------------------------------------------------------------------------------------ the receiver
def test_close_echoes_merge_between_the_surfaces_weighted_by_their_light() -> None:
    """Far closer than the separation the two pulses add up to one peak at their energy-weighted mean."""
    near, far = 3.0, 3.0 + 0.05 * SEP_M
    for n_near in (1, 2, 3, 4):
        e_near, e_far = n_near / near**2, (5 - n_near) / far**2
        expected = (e_near * near + e_far * far) / (e_near + e_far)
        assert _peak(near, far, n_near) == pytest.approx(expected, abs=0.002 * SEP_M)


def test_echoes_farther_apart_than_the_separation_stay_apart_and_the_stronger_is_timed() -> None:
    for gap in (2.0 * SEP_M, 3.0 * SEP_M):
        for n_near in (1, 2, 3, 4):
            far = 3.0 + gap
            stronger = 3.0 if n_near / 3.0**2 >= (5 - n_near) / far**2 else far
            assert _peak(3.0, far, n_near) == pytest.approx(stronger, abs=0.02 * gap), (gap, n_near)
    # at equal shares the nearer surface returns more light (1 / range^2) and wins
    d = np.array([[2.0, 2.0, 2.0, 2.0 + 3 * SEP_M, 2.0 + 3 * SEP_M]])
    r, _, _ = echo_peak(d, np.ones_like(d), d < 2.1, LaserEffects())
    assert float(r[0]) == pytest.approx(2.0, abs=0.01)


def test_the_merged_peak_moves_to_the_stronger_surface_as_the_gap_grows() -> None:
    """The reported point's distance from the stronger surface, as a share of the gap, falls with the gap:
    a mixed pixel mainly at small gaps, a clean edge beyond the separation."""
    shares = [(_peak(3.0, 3.0 + g, 3) - 3.0) / g for g in np.array((0.1, 0.5, 1.0, 1.5, 2.0, 3.0)) * SEP_M]
    assert all(a >= b - 1e-9 for a, b in zip(shares, shares[1:], strict=False)), shares
    assert shares[0] > 0.3 and shares[-1] < 0.01


def test_no_separation_means_the_stronger_echo_and_bad_values_are_refused() -> None:
    assert _peak(3.0, 3.2, 3, LaserEffects(echo_separation_m=0.0)) == pytest.approx(3.0)
    with pytest.raises(ValueError, match="echo_separation_m"):
        LaserEffects(echo_separation_m=-0.1)
    with pytest.raises(ScenarioError, match="laser_echo_separation_m"):
        validate_params({"laser_echo_separation_m": 11.0})


# ------------------------------------------------------------------------------------------ the measure
def test_edges_are_classified_by_what_lies_between_the_surfaces() -> None:
    wall = np.full(8, 3.0)
    post = np.full(8, 2.0)
    sig = np.full(24, 0.003)
    cases = {
        "clean": np.r_[wall, post, wall],
        "mixed": np.r_[wall[:-1], 2.5, post, wall],
        "pulled": np.r_[wall[:-1], 2.95, post, wall],
        "no_echo": np.r_[wall[:-1], np.nan, post, wall],
        "other": np.r_[wall[:-1], 1.0, post, wall],
    }
    for kind, r in cases.items():
        edges = classify_edges(r, sig)
        assert [e.kind for e in edges][0] == kind, (kind, edges)
        assert edges[0].near_m == 2.0 and edges[0].far_m == 3.0
    # an oblique wall (ranges growing 4 cm a beam) is one surface, not a staircase of edges
    assert classify_edges(2.0 + 0.04 * np.arange(30), np.full(30, 0.003)) == []
    # too few beams on a side, or too many between, or too small a gap: no edge
    assert classify_edges(np.r_[wall, 2.0, 2.0, wall], sig[:18]) == []
    assert classify_edges(np.r_[wall, np.nan, np.nan, np.nan, post], sig[:19]) == []
    assert classify_edges(np.r_[wall, wall + 0.03], sig[:16]) == []
    with pytest.raises(ValueError, match="min_run"):
        EdgeCriteria(min_run=1)


def _posts_sweeps(gaps_m: tuple[float, ...], n: int) -> list[np.ndarray]:
    """A still robot at x = 0.6 m facing the far wall (x = 8 m) with 0.15 m posts ``gaps_m`` in front of it,
    side by side across the room."""
    ys = np.linspace(-1.5, 1.5, len(gaps_m))
    posts = tuple(ObstaclePath(radius_m=0.15, waypoints=((8.0 - 0.15 - g, float(y)),), speed_mps=0.0, start_s=0.0)
                  for g, y in zip(gaps_m, ys, strict=True))
    sc = build_scenario({"odom_noise": 0.0, "robot_speed_mps": 0.0, "obstacles": 0,
                         "laser_dropout_prob": 0.0, "laser_spurious_prob": 0.0})
    world = World(replace(sc, obstacles=posts), mount=RobotMount(laser_x_m=0.0))
    return [world.sweep(float(k)).ranges_m for k in range(n)]


def test_the_worlds_mixed_pixels_fall_with_the_gap_as_the_echo_model_says() -> None:
    """Posts in front of a wall: at gaps below half the separation most edges carry a mixed pixel, at
    gaps beyond twice the separation (almost) none does."""
    edges = scan_edges(_posts_sweeps((0.2, 0.4, 2.5, 3.5), 25), LaserModel().sigma_m)
    small = [e for e in edges if e.gap_m < SEP_M / 2]
    large = [e for e in edges if e.gap_m > 2 * SEP_M]
    assert len(small) >= 30 and len(large) >= 30
    assert np.mean([e.kind == "mixed" for e in small]) > 0.5
    assert np.mean([e.kind == "mixed" for e in large]) < 0.05


# ------------------------------------------------------------------------------------------ recorded data
def _diosi_scans(shared: Path) -> list[np.ndarray]:
    """The 25 recorded UTM-30LX scans (a header line, then 1081 ranges in m per line, 10000 = invalid)."""
    path = shared / "psm_diosi_examples" / "hokuyo_utm_30lx_from_Mohsen_Akbaritabar.txt"
    if not path.exists():
        pytest.skip(f"recorded data not found: {path}")
    scans = [np.array(line.split(), float) for line in path.read_text().splitlines()[1:] if line.strip()]
    return [np.where((r > 0.0) & (r < 9999.0), r, np.nan) for r in scans]


def test_the_worlds_edges_match_the_recorded_utm30lx(shared_data: Path) -> None:
    """Measured the same way, the world's share of mixed pixels per depth gap is the recorded UTM-30LX's
    (tools/laser_edges.py: 0.69 / 0.76 / 0.06 at 0.05-0.3 / 0.3-1 / > 1 m over 678 edges)."""
    real = rates(scan_edges(_diosi_scans(shared_data), LaserModel().sigma_m))["by_gap"]
    assert [real[k]["mixed"] for k in ("0.05-0.3m", "0.3-1m", ">1m")] == pytest.approx([0.69, 0.76, 0.06], abs=0.01)
    sweeps = []
    for name in ("static_clutter", "cylinder_clutter", "cross_90"):
        sc = suite_scenario(name)
        world = World(sc)
        world.command(*sc.command_at(0.0), 0.0)
        sweeps += [world.sweep(t).ranges_m for t in np.arange(0.0, sc.duration_s, 1.0)]
    sim = rates(scan_edges(sweeps, LaserModel().sigma_m))["by_gap"]
    for k in ("0.05-0.3m", "0.3-1m"):
        assert sim[k]["edges"] >= 40 and abs(sim[k]["mixed"] - real[k]["mixed"]) < 0.15, (k, sim[k], real[k])
    assert sim[">1m"]["mixed"] < 0.12 and math.isclose(real[">1m"]["no_echo"], 0.0)
