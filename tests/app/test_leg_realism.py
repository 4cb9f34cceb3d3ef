"""The simulated world's legs against the leg detector learned from real scans (app.evaluation.leg_realism).

The figures the bounds come from (``python -m app.evaluation.leg_realism``, docs/simulation.md "Legs
against the learned detector"): the shipped detector takes 86 % of the real labelled legs of the held-out
recording positive_6 at 1-4 m for legs, and 25 % of the real non-leg segments of the held-out second half
of the drive (negative_2) at 1-4 m (88 % and 27 % before its training also took every segment re-seen
from farther).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from app.evaluation import leg_realism as lr
from app.legmodel import default_leg_model

#: real held-out figures at 1-4 m (see the module docstring) and the margin allowed against them
REAL_LEG_SHARE = 0.86
REAL_NONLEG_SHARE = 0.25
MARGIN = 0.10
#: real held-out legs at 5-8 m: positive_6's labelled legs re-seen there (tools/train_legs.py ``by_range``,
#: 201 at 5-6.5 m taken 0.62, 185 at 6.5-8 m taken 0.48); no real leg is labelled beyond 5 m
REAL_FAR_LEG_SHARE = 0.55
#: simulated walkers' legs at 5-8 m, measured 0.11 of 37 (0.27 with the old edge model, which mixed at half
#: of all edges; the old detector: 0.00); below the real REAL_FAR_LEG_SHARE (the test's docstring): not met,
#: a floor against regression
FAR_SIM_LEG_SHARE = 0.05
WALKER_SCENES = ("cross_60", "cross_90", "two_people_opposite")


@pytest.fixture(scope="module")
def model():
    return default_leg_model()


@pytest.fixture(scope="module")
def sim_walkers() -> lr.Samples:
    return lr.sim_legs(WALKER_SCENES, "utm30lx", 0.25)


@pytest.fixture(scope="module")
def sim_furniture() -> lr.Samples:
    return lr.sim_clutter(("static_clutter",), "utm30lx", 0.25)


def test_the_detector_takes_simulated_walkers_legs_for_legs_as_often_as_real_ones(model, sim_walkers) -> None:
    n, share = lr.range_share(sim_walkers, model, 1.0, 4.0)
    assert n > 200
    # with the old range noise (10 mm at every range: the datasheet's accuracy read as random noise) this
    # was 0.74: the simulated legs looked rougher than any real leg
    assert share >= REAL_LEG_SHARE - MARGIN


def test_simulated_legs_beyond_the_labelled_range_are_taken_for_legs(model) -> None:
    """Every labelled real leg lies within 5 m; trained on them also re-seen from farther, the detector
    takes a simulated walker's leg at 5-8 m for a leg 0.11 of the time (37 legs; before: never, 0.00).
    Real held-out legs re-seen there are taken about REAL_FAR_LEG_SHARE of the time. The world's far legs
    stand 0.3-1 m before a wall (253 of 260 leg ends), where the UTM-30LX returns a mixed pixel at 0.76 of
    its recorded edges (docs/simulation.md); the real legs were recorded by another Hokuyo (0.22 at such
    edges) before open space (no echo beside 75-90 % of them), and a far leg with a mixed pixel attached is
    never taken (0 of 5)."""
    n, share = lr.range_share(lr.sim_legs(("wall_hugger", "crowd"), "utm30lx", 0.25), model, 5.0, 8.0)
    assert n > 30
    assert share >= FAR_SIM_LEG_SHARE


def test_simulated_chair_and_table_legs_are_no_more_leg_like_than_real_non_legs(model, sim_furniture) -> None:
    n, share = lr.range_share(sim_furniture, model, 1.0, 4.0, ("chair", "table"))
    assert n > 200
    assert share <= REAL_NONLEG_SHARE


def test_segments_are_labelled_by_the_worlds_truth(sim_walkers, sim_furniture) -> None:
    x = sim_walkers.matrix()
    width = x[:, lr.FEATURE_NAMES.index("width_m")]
    # a 0.12 m leg (or two touching) seen from one side: never wider than two legs side by side
    assert 0.02 < float(np.median(width)) < 0.12 and width.max() <= 0.4
    kinds = set(sim_furniture.kinds)
    assert {"chair", "table"} <= kinds <= {"chair", "table", "bin", "post", "box"}
    chair = sim_furniture.matrix()[np.array(sim_furniture.kinds) == "chair"]
    assert float(np.median(chair[:, lr.FEATURE_NAMES.index("width_m")])) < 0.04  # a 25 mm chair leg


def test_the_recordings_beam_pattern_gives_fewer_returns_per_leg() -> None:
    a = lr.sim_legs(("cross_90",), "utm30lx", 0.5).matrix()
    b = lr.sim_legs(("cross_90",), "leg_tracker", 0.5).matrix()
    n = lr.FEATURE_NAMES.index("n_points")
    r = lr.FEATURE_NAMES.index("range_m")
    # returns per metre of arc at the same range: 0.3516 deg against 0.25 deg steps
    ratio = np.median(a[:, n] * a[:, r]) / np.median(b[:, n] * b[:, r])
    assert 1.2 < ratio < 1.6
    with pytest.raises(lr.LegRealismError, match="geometry"):
        lr.sim_legs(("cross_90",), "sick", 0.5)


def test_cli_simulated_sets_only_as_json(capsys) -> None:
    assert lr.main(["--no-real", "--geometry", "utm30lx", "--step", "2.0", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert "real_legs" not in report and 0.0 < report["threshold_p"] < 1.0
    legs = report["sim_legs_utm30lx"]
    assert legs["segments"] == sum(b["segments"] for b in legs["bands"].values())
    assert set(report["sim_clutter_utm30lx"]["kinds"]) >= {"chair", "table"}


def test_cli_errors(capsys, tmp_path: Path) -> None:
    assert lr.main(["--step", "0"]) == 2
    assert "--step" in capsys.readouterr().err
    assert lr.main(["--data-dir", str(tmp_path)]) == 2
    assert "no recordings" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------ real data
@pytest.fixture(scope="module")
def real_dir(shared_data: Path) -> Path:
    path = shared_data / "real_people_laser"
    if not (path / lr.DRIVE_BAG).exists():
        pytest.skip(f"the leg_tracker recordings are not in {path} (../shared/data/real_people_laser)")
    return path


def test_against_the_real_held_out_figures_measured_now(model, real_dir: Path, sim_walkers, sim_furniture) -> None:
    """The same bounds from the real held-out sets scored by the model shipped now (a retrained model
    moves them: the constants above must then be measured again)."""
    _, legs = lr.range_share(lr.real_legs(real_dir), model, 1.0, 4.0)
    _, nonlegs = lr.range_share(lr.real_nonlegs(real_dir), model, 1.0, 4.0)
    assert legs is not None and nonlegs is not None
    assert lr.range_share(sim_walkers, model, 1.0, 4.0)[1] >= legs - MARGIN
    assert lr.range_share(sim_furniture, model, 1.0, 4.0, ("chair", "table"))[1] <= nonlegs
    stale = f"REAL_LEG_SHARE / REAL_NONLEG_SHARE are stale: measured now {legs:.2f} / {nonlegs:.2f}"
    assert abs(legs - REAL_LEG_SHARE) < 0.05 and abs(nonlegs - REAL_NONLEG_SHARE) < 0.05, stale


def test_the_simulated_range_noise_is_the_measured_utm30lx_noise(shared_data: Path) -> None:
    noise = lr.utm30lx_frame_noise(shared_data)
    if not noise:
        pytest.skip(f"the recorded UTM-30LX session is not in {shared_data / lr.UTM_SESSION}")
    for band in ("0.1-2m", "2-4m"):  # where the frame has flat surfaces enough (beyond: corners, 52 returns)
        assert noise[band]["simulated_sigma_m"] == pytest.approx(noise[band]["sigma_m"], rel=0.2)


def test_through_the_recordings_sensor_simulated_legs_have_real_legs_shape(real_dir: Path) -> None:
    real = lr.real_legs(real_dir).matrix()
    sim = lr.sim_legs(WALKER_SCENES, "leg_tracker", 0.25).matrix()
    rng = lr.FEATURE_NAMES.index("range_m")

    def median(x: np.ndarray, name: str) -> float:
        m = (x[:, rng] >= 2.0) & (x[:, rng] < 4.0)
        return float(np.median(x[m, lr.FEATURE_NAMES.index(name)]))

    # 2-4 m, the same beam spacing and range noise: width within 1 cm, circle-fit residual within 1.5 mm
    assert median(sim, "width_m") == pytest.approx(median(real, "width_m"), abs=0.01)
    assert median(sim, "circularity_m") == pytest.approx(median(real, "circularity_m"), abs=0.0015)
    assert lr.recording_noise(real_dir)["2-4m"]["sigma_m"] == pytest.approx(lr.LEG_TRACKER_SIGMA_M, abs=0.0015)
