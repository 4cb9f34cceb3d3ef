"""The ETH/UCY path loader: format, ordering, units, typed errors; real files when present."""

from pathlib import Path

import numpy as np
import pytest

from hil_fakes.world.pedestrians import TrajectoryFileError, load_paths

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
