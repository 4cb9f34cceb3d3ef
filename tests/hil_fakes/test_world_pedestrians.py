"""The ETH/UCY path loader: format, ordering, units, typed errors; real files when present."""

from pathlib import Path

import numpy as np
import pytest

from hil_fakes.world.pedestrians import (
    RecordedPath,
    TrajectoryFileError,
    annotation_stride,
    fitted_waypoints,
    load_paths,
    smoothed,
)
from hil_fakes.world.scenarios import ScenarioError, build_scenario, suite_scenario

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "pedestrian_trajectories"


def _write(tmp_path: Path, rows: list[list[float]], name: str = "t.csv") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(",".join(str(v) for v in r) for r in rows) + "\n")
    return p


def test_paths_split_by_id_and_ordered_in_time(tmp_path):
    p = _write(tmp_path, [[3, 1, 2, 1, 2, 5], [7, 7, 7, 9, 9, 9], [2.0, 0.0, 1.0, 5, 5, 5], [0, 0, 0, 1, 2, 3]])
    paths = load_paths(p, frame_rate_hz=2.0)
    assert sorted(paths) == [7, 9]
    np.testing.assert_allclose(paths[7].t_s, [0.0, 0.5, 1.0])
    np.testing.assert_allclose(paths[7].xy_m[:, 0], [0.0, 1.0, 2.0])
    assert paths[7].mean_speed_mps() == pytest.approx(2.0)
    np.testing.assert_allclose(paths[9].t_s, [0.0, 0.5, 2.0])
    assert paths[9].length_m() == pytest.approx(2.0)


def test_bad_files_raise_typed_errors(tmp_path):
    with pytest.raises(TrajectoryFileError, match="4 finite rows"):
        load_paths(_write(tmp_path, [[1, 2], [1, 1], [0, 0]]), frame_rate_hz=1.0)
    with pytest.raises(TrajectoryFileError, match="frame rate"):
        load_paths(_write(tmp_path, [[1, 2], [1, 1], [0, 0], [0, 0]], "x.csv"))
    with pytest.raises(TrajectoryFileError, match="no pedestrian"):
        load_paths(_write(tmp_path, [[1, 2], [1, 2], [0, 0], [0, 0]]), frame_rate_hz=1.0)
    with pytest.raises(TrajectoryFileError, match="cannot read"):
        load_paths(tmp_path / "absent.csv", frame_rate_hz=1.0)


@pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/pedestrian_trajectories absent")
def test_eth_hotel_walking_speeds_are_human():
    paths = load_paths(DATA / "eth_hotel.csv")
    assert len(paths) > 300
    speeds = np.array([p.mean_speed_mps() for p in paths.values() if p.t_s[-1] > 2.0])
    assert 0.4 < float(np.median(speeds)) < 1.6


def test_fitted_waypoints_keep_the_shape_between_the_new_ends():
    rec = RecordedPath(5, np.array([0.0, 1.0, 2.0]), np.array([[10.0, 10.0], [12.0, 11.0], [14.0, 10.0]]))
    pts = np.array(fitted_waypoints(rec, (1.0, 1.0), (1.0, 3.0)))
    np.testing.assert_allclose(pts[0], [1.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(pts[-1], [1.0, 3.0], atol=1e-12)
    # chord 4 m -> 2 m (scale 0.5), rotated +90 deg: the apex 1 m left of the chord is now 0.5 m to -x, and
    # the smoothed path still passes through it (an annotation), rounded on either side
    assert float(np.min(np.hypot(*(pts - [0.5, 2.0]).T))) < 1e-9
    assert float(np.min(pts[:, 0])) == pytest.approx(0.5, abs=1e-9)
    with pytest.raises(TrajectoryFileError, match="ends"):
        fitted_waypoints(RecordedPath(1, np.array([0.0, 1.0]), np.array([[0.0, 0.0], [0.1, 0.0]])), (0, 0), (1, 0))


def test_a_recorded_path_needs_a_person():
    with pytest.raises(ScenarioError, match="person_path_source"):
        build_scenario({"person_path_source": "eth_hotel", "obstacle_kind": "cylinder"})


@pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/pedestrian_trajectories absent")
@pytest.mark.parametrize("source", ["eth_hotel", "ucy_zara01"])
def test_a_person_walks_a_recorded_path_between_the_scripted_ends(source):
    scripted = suite_scenario("cross_90").obstacles[0]
    rec = suite_scenario("cross_90", overrides={"person_path_source": source}).obstacles[0]
    assert len(rec.waypoints) > 2 and rec.gait is not None
    np.testing.assert_allclose(rec.waypoints[0], scripted.waypoints[0], atol=1e-9)
    np.testing.assert_allclose(rec.waypoints[-1], scripted.waypoints[-1], atol=1e-9)
    assert rec.length_m > scripted.length_m  # a real path is never straighter than its chord
    with pytest.raises(ScenarioError, match="person_path_id"):
        suite_scenario("cross_90", overrides={"person_path_source": source, "person_path_id": 10**6})


def test_default_is_the_scripted_line():
    a = suite_scenario("cross_90").obstacles
    b = suite_scenario("cross_90", overrides={"person_path_source": "scripted"}).obstacles
    assert a == b and len(a[0].waypoints) == 2


def test_annotation_stride_and_a_smoothed_path_without_corners():
    # annotations every 4 samples, linearly interpolated: a zigzag whose heading jumps 90 deg at each
    ann = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 0.0], [3.0, 1.0], [4.0, 0.0]])
    xy = np.vstack([a + (b - a) * k / 4 for a, b in zip(ann[:-1], ann[1:], strict=True) for k in range(4)] + [ann[-1:]])
    assert annotation_stride(xy) == 4
    assert annotation_stride(ann) == 1
    out = smoothed(xy, 4)
    for a in ann:  # every annotation kept
        assert float(np.min(np.hypot(*(out - a).T))) < 1e-9
    heading = np.arctan2(*np.diff(out, axis=0).T[::-1])
    assert float(np.max(np.abs(np.diff(heading)))) < 0.25  # no corner: <= 14 deg between 5 cm steps
    lin = np.diff(np.arctan2(*np.diff(xy, axis=0).T[::-1]))
    assert float(np.max(np.abs(lin))) > 1.5  # the interpolated file turns 90 deg at once


def test_the_natural_spline_is_scipys():
    """hil_fakes may import numpy only (ARCHITECTURE.md): its own spline, checked against scipy's here."""
    from scipy.interpolate import CubicSpline

    from hil_fakes.world.pedestrians import _natural_spline

    rng = np.random.default_rng(1)
    s = np.concatenate([[0.0], np.cumsum(rng.uniform(0.2, 1.0, 11))])
    y = rng.normal(size=(12, 2))
    at = np.linspace(0.0, s[-1], 500)
    np.testing.assert_allclose(_natural_spline(s, y, at), CubicSpline(s, y, bc_type="natural")(at), atol=1e-12)
