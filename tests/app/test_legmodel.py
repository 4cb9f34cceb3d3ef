"""A real segment re-seen from farther (app.legmodel.reseen_farther: the leg detector's training
augmentation) and the shipped detector over the scanner's range."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.legmodel import default_leg_model, leg_candidates, prefiltered, range_sigma_m, reseen_farther
from vipsm.legs import FEATURE_NAMES

SEED = 29
ROOT = Path(__file__).resolve().parents[2]
STEP_RAD = math.radians(0.25)  # the UTM-30LX
RECORDED_STEP_RAD = math.radians(360.0 / 1024.0)  # the recordings' laser


def _f(row: np.ndarray, name: str) -> float:
    return float(row[FEATURE_NAMES.index(name)])


def _scan(leg_range_m: float, wall_behind_m: float, step_rad: float, rng: np.random.Generator,
          leg_radius_m: float = 0.06, noise: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """A scan of a round leg on the x axis in front of a wall across the beams (x = leg + behind)."""
    b = np.arange(-0.6, 0.6, step_rad)
    wall = leg_range_m + wall_behind_m
    r = wall / np.cos(b)
    # ray-circle intersection: |t e - c|^2 = rho^2
    proj = leg_range_m * np.cos(b)
    disc = proj**2 - (leg_range_m**2 - leg_radius_m**2)
    hit = disc > 0.0
    r[hit] = np.minimum(r[hit], proj[hit] - np.sqrt(disc[hit]))
    if noise:
        r = r + rng.standard_normal(r.size) * range_sigma_m(r)
    return r, b


def _leg_span(r: np.ndarray, b: np.ndarray, leg_range_m: float) -> tuple[int, int, np.ndarray]:
    kept, x = leg_candidates(r, b)
    for (a, z, pts), row in zip(kept, x, strict=True):
        if abs(float(pts.mean(axis=0)[0]) - leg_range_m) < 0.1:
            return a, z, row
    raise AssertionError("no leg candidate")


def test_reseen_at_its_own_range_and_step_is_the_same_segment() -> None:
    rng = np.random.default_rng(SEED)
    r, b = _scan(2.0, 0.5, RECORDED_STEP_RAD, rng)
    a, z, row = _leg_span(r, b, 2.0)
    again = reseen_farther(prefiltered(r, b)[0], b, (a, z), _f(row, "range_m"), RECORDED_STEP_RAD, rng)
    assert again is not None
    assert abs(_f(again, "n_points") - _f(row, "n_points")) <= 1
    for name, tol in (("width_m", 0.02), ("range_m", 0.005), ("front_left_m", 0.02), ("front_right_m", 0.02)):
        assert _f(again, name) == pytest.approx(_f(row, name), abs=tol)


def test_reseen_farther_has_the_beams_a_leg_gets_there_and_keeps_what_lies_behind() -> None:
    rng = np.random.default_rng(SEED)
    r, b = _scan(2.0, 0.3, RECORDED_STEP_RAD, rng)
    a, z, row = _leg_span(r, b, 2.0)
    rr = prefiltered(r, b)[0]
    counts = []
    for _ in range(40):
        far = reseen_farther(rr, b, (a, z), 7.0, STEP_RAD, rng)
        if far is None:
            counts.append(0)
            continue
        counts.append(_f(far, "n_points"))
        assert _f(far, "range_m") == pytest.approx(7.0, abs=0.03)
        # the wall moved with the leg: still 0.3 m behind its centre, 0.36 m behind its nearest return
        assert _f(far, "front_left_m") == pytest.approx(0.36, abs=0.04)
        assert _f(far, "front_right_m") == pytest.approx(0.36, abs=0.04)
        assert _f(far, "width_m") < 0.12
    # the visible chord of a 0.12 m leg at 7 m spans about 3.5 beams of 0.25 deg: 3 or 4 returns
    assert 3.0 <= np.mean(counts) <= 4.5 and max(counts) <= 5


def test_reseen_returns_carry_the_range_noise_of_their_new_range() -> None:
    rng = np.random.default_rng(SEED)
    b = np.arange(-0.3, 0.3, RECORDED_STEP_RAD)
    r = np.full(b.size, 12.0)
    flat = np.abs(b) < 0.12  # a flat board 0.24 m wide, 1 m away, recorded without noise
    r[flat] = 1.0 / np.cos(b[flat])
    span = _leg_span(r, b, 1.0)[:2]
    res = []
    for _ in range(60):
        far = reseen_farther(r, b, span, 3.0, RECORDED_STEP_RAD, rng)
        if far is not None:
            res.append(_f(far, "linearity_m"))
    # rms distance from the fitted line of k returns with range noise sigma: sigma * sqrt((k - 2) / k)
    assert len(res) > 40
    assert float(np.sqrt(np.mean(np.square(res)))) == pytest.approx(float(range_sigma_m(3.0)) * 0.9, rel=0.25)


def test_reseen_nearer_is_refused() -> None:
    rng = np.random.default_rng(SEED)
    r, b = _scan(3.0, 0.5, STEP_RAD, rng)
    a, z, _ = _leg_span(r, b, 3.0)
    with pytest.raises(ValueError, match="range"):
        reseen_farther(r, b, (a, z), 2.0, STEP_RAD, rng)


def test_a_leg_too_far_for_three_beams_is_no_candidate() -> None:
    rng = np.random.default_rng(SEED)
    r, b = _scan(2.0, 0.5, RECORDED_STEP_RAD, rng)
    a, z, _ = _leg_span(r, b, 2.0)
    # 0.12 m at 20 m spans 1.4 beams of 0.25 deg
    assert all(reseen_farther(prefiltered(r, b)[0], b, (a, z), 20.0, STEP_RAD, rng) is None for _ in range(10))


@pytest.mark.parametrize("leg_range_m", [2.5, 5.5, 7.0])
def test_the_shipped_detector_takes_a_leg_before_a_wall_for_a_leg_over_the_scanners_range(leg_range_m) -> None:
    """A 0.12 m leg 0.3 m in front of a wall (a person walking along it), seen by the UTM-30LX: the
    labelled real legs all lie within 5 m, the re-seen copies teach the detector the rest."""
    model = default_leg_model()
    rng = np.random.default_rng(SEED)
    p = []
    for _ in range(30):
        r, b = _scan(leg_range_m, 0.3, STEP_RAD, rng)
        p.append(float(model.predict(_leg_span(r, b, leg_range_m)[2][None])[0]))
    assert np.mean(np.array(p) >= model.threshold_p) >= 0.5


def test_a_non_leg_is_no_more_leg_like_far_than_near() -> None:
    """The augmentation moves non-legs out as it moves legs: range alone makes nothing a leg. A flat
    board of a leg's width 0.3 m in front of a wall (leg-like to the detector near, as it was before the
    augmentation) is taken for a leg at 7 m no more often than at 2.5 m."""
    model = default_leg_model()
    rng = np.random.default_rng(SEED)
    share = {}
    for rng_m in (2.5, 7.0):
        hits = []
        for _ in range(20):
            b = np.arange(-0.6, 0.6, STEP_RAD)
            r = np.full(b.size, rng_m + 0.3) / np.cos(b)
            board = np.abs(b * rng_m) < 0.06
            r[board] = rng_m / np.cos(b[board])
            r = r + rng.standard_normal(r.size) * range_sigma_m(r)
            hits.append(model.predict(_leg_span(r, b, rng_m)[2][None])[0] >= model.threshold_p)
        share[rng_m] = float(np.mean(hits))
    assert share[7.0] <= share[2.5] + 0.1


def _train_legs():
    spec = importlib.util.spec_from_file_location("train_legs", ROOT / "tools" / "train_legs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _leg_samples(tl: Any, ranges_m: tuple[float, ...], gap_m: float) -> Any:
    """Training samples of one leg per scan at each of ``ranges_m`` (``_scan``'s layout, ``gap_m``)."""
    rng = np.random.default_rng(SEED)
    smp = tl.Samples()
    for leg_range_m in ranges_m:
        r, b = _scan(leg_range_m, gap_m, RECORDED_STEP_RAD, rng)
        smp.add_scan(r, b, lambda pts, c=leg_range_m: abs(float(pts.mean(axis=0)[0]) - c) < 0.1)
    return smp


def test_training_copies_each_sample_farther_alike_and_keeps_its_source() -> None:
    tl = _train_legs()
    smp = _leg_samples(tl, (1.5, 3.0), 0.4)
    assert len(smp.rows) == 2
    x, src = tl.farther(smp, 4, np.random.default_rng(SEED))
    assert x.shape[1] == len(FEATURE_NAMES) and set(src.tolist()) <= {0, 1} and len(src) == len(x) >= 4
    rng_m = x[:, FEATURE_NAMES.index("range_m")]
    assert np.all(rng_m >= smp.matrix()[src, FEATURE_NAMES.index("range_m")] - 0.02)
    assert np.all(rng_m <= tl.FAR_RANGE_M + 0.05)
    again, _ = tl.farther(smp, 4, np.random.default_rng(SEED))
    np.testing.assert_array_equal(x, again)  # deterministic for a seed


def test_banded_shares_count_rows_per_range_band() -> None:
    tl = _train_legs()
    x = np.zeros((4, len(FEATURE_NAMES)))
    x[:, FEATURE_NAMES.index("range_m")] = [1.0, 1.5, 6.0, 20.0]
    out = tl.banded(np.array([0.9, 0.1, 0.9, 0.0]), x, 0.5)
    assert out["0-2"] == {"n": 2, "share": 0.5} and out["5-6.5"] == {"n": 1, "share": 1.0}
    assert out["10-inf"] == {"n": 1, "share": 0.0} and out["2-3.5"] == {"n": 0, "share": None}


def test_a_damaged_model_file_is_a_typed_error(tmp_path) -> None:
    """Truncated, not a zip at all, or a member's compressed bytes flipped: a ModelError, never a zip error."""
    from app.legmodel import default_model_path, load_leg_model
    from vipsm.legs import ModelError

    data = default_model_path().read_bytes()
    (tmp_path / "half.npz").write_bytes(data[: len(data) // 2])
    (tmp_path / "junk.npz").write_bytes(b"PK\x03\x04" + bytes(100))
    flipped = bytearray(data)
    mid = len(flipped) // 3
    flipped[mid : mid + 64] = bytes(b ^ 0xFF for b in flipped[mid : mid + 64])
    (tmp_path / "flipped.npz").write_bytes(bytes(flipped))
    for name in ("half.npz", "junk.npz", "flipped.npz"):
        with pytest.raises(ModelError):
            load_leg_model(tmp_path / name)


def test_train_legs_refuses_a_bad_baseline_before_training(tmp_path, capsys) -> None:
    tl = _train_legs()
    (tmp_path / "bad.npz").write_bytes(b"not a model")
    assert tl.main(["--baseline", str(tmp_path / "bad.npz"), "--out", str(tmp_path / "m.npz")]) == 2
    assert "--baseline" in capsys.readouterr().err and not (tmp_path / "m.npz").exists()
    assert tl.main(["--data-dir", str(tmp_path), "--out", str(tmp_path / "m.npz")]) == 2
    assert "no recordings" in capsys.readouterr().err
    # another recording held out is a leave-one-out model: never written over the packaged one
    assert tl.main(["--held-out", "positive_1", "--data-dir", str(tmp_path)]) == 2
    assert "needs --out" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        tl.main(["--held-out", "positive_9", "--out", str(tmp_path / "m.npz")])
    assert "invalid choice" in capsys.readouterr().err and not (tmp_path / "m.npz").exists()


def test_validation_reports_each_model_per_band_on_the_same_rows() -> None:
    """``--baseline``'s table: the same held-out rows scored by two models, band by band."""
    tl = _train_legs()
    from app.legmodel import default_leg_model

    model = default_leg_model()
    rng = np.random.default_rng(SEED)
    r, b = _scan(2.5, 0.4, RECORDED_STEP_RAD, rng)
    leg = _leg_span(r, b, 2.5)[2]
    far = leg.copy()
    far[FEATURE_NAMES.index("range_m")] = 7.0
    rows = np.stack([leg, far])
    out = tl.validation(model, "positive_2", (rows, rows), (rows, rows))
    rec = out["recorded"]["recall_positive_2"]  # named for the recording held out
    assert rec["0-2"]["n"] == 0 and rec["2-3.5"]["n"] == 1 and rec["6.5-8"]["n"] == 1
    p = model.predict(rows)
    assert rec["2-3.5"]["share"] == float(p[0] >= model.threshold_p)
    assert out["reseen_farther"]["false_positive_rate_drive_second_half"]["6.5-8"]["share"] == float(
        p[1] >= model.threshold_p)


# ---------------------------------------------------------------------------------------------
# before a wall, with the UTM-30LX's depth edges (app.legmodel.before_wall)

def _open_leg(leg_range_m: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, int, int]:
    """A leg before open space (no return beside it), as the recordings' laser saw most legs."""
    r, b = _scan(leg_range_m, 40.0, RECORDED_STEP_RAD, rng)
    r[r > leg_range_m + 1.0] = np.nan
    a, z, _ = _leg_span(r, b, leg_range_m)
    return prefiltered(r, b)[0], b, a, z


def _between(w: np.ndarray, r: np.ndarray, a: int, z: int, wall_m: float) -> tuple[int, int]:
    """Per end of the leg [a, z) in ``w`` (``r`` before the wall): a return the wall put between the leg's
    end and the wall, in the gap's middle 80 % (mixed), or 1.5-11 cm behind the leg's end (pulled)."""
    mixed = pulled = 0
    for beams, end in ((np.arange(a - 3, a + 1), a), (np.arange(z - 1, z + 3), z - 1)):
        gap = wall_m - r[end]
        new = w[beams][~np.isclose(w[beams], r[beams], atol=1e-12, equal_nan=True)]
        mixed += int(np.any((new > r[end] + 0.1 * gap) & (new < wall_m - 0.1 * gap)))
        pulled += int(np.any((new > r[end] + 0.015) & (new < r[end] + 0.11)))
    return mixed, pulled


@pytest.mark.parametrize(("depth_m", "mixed_rate", "pulled_rate"), [(0.45, 0.80, 0.11), (1.75, 0.02, 0.44)])
def test_before_a_wall_the_edges_come_at_the_recorded_utm30lx_rates(depth_m, mixed_rate, pulled_rate) -> None:
    from app.legmodel import Wall, before_wall

    rng = np.random.default_rng(SEED)
    r, b, a, z = _open_leg(2.0, rng)
    mixed = pulled = 0
    n = 400
    for _ in range(n):
        w = before_wall(r, b, (a, z), Wall(depth_m), rng)
        near = float(np.nanmin(r[a:z]))
        # the wall fills the beams beside the leg where there was nothing, square to the beam at the depth
        assert np.nanmedian(w[a - 8 : a - 3]) == pytest.approx(near + depth_m, abs=0.03)
        assert np.array_equal(w[a + 1 : z - 1], r[a + 1 : z - 1], equal_nan=True)  # its inside unchanged
        m, p = _between(w, r, a, z, near + depth_m)
        mixed, pulled = mixed + m, pulled + (p if depth_m > 1.0 else 0)
    assert mixed / (2 * n) == pytest.approx(mixed_rate, abs=0.06)
    if depth_m > 1.0:
        assert pulled / (2 * n) == pytest.approx(pulled_rate * 0.7, abs=0.06)  # near-side pulls


def test_before_a_wall_a_nearer_return_beside_the_segment_stays() -> None:
    from app.legmodel import Wall, before_wall

    rng = np.random.default_rng(SEED)
    r, b, a, z = _open_leg(2.0, rng)
    r = r.copy()
    r[a - 3 : a] = 1.2  # something nearer beside the leg on one side: it hides the wall there
    w = before_wall(r, b, (a, z), Wall(0.5), rng)
    assert np.array_equal(w[a - 3 : a], r[a - 3 : a])
    assert np.all(np.isfinite(w[z : z + 8]))


def test_a_wall_is_checked() -> None:
    from app.legmodel import Wall

    for depth, slant in ((0.0, 0.0), (0.5, 1.6), (-1.0, 0.0)):
        with pytest.raises(ValueError):
            Wall(depth, slant)


def test_reseen_farther_before_a_wall_has_the_wall_beside_it() -> None:
    from app.legmodel import Wall

    rng = np.random.default_rng(SEED)
    r, b, a, z = _open_leg(2.0, rng)
    fronts = []
    for _ in range(20):
        far = reseen_farther(r, b, (a, z), 5.0, STEP_RAD, rng, Wall(0.6))
        if far is not None:
            assert _f(far, "range_m") == pytest.approx(5.0, abs=0.1)
            fronts += [_f(far, "front_left_m"), _f(far, "front_right_m")]
    # 0.6 m behind the leg's nearest return (a mixed pixel on the beam beside it is dropped by the pre-filter)
    assert len(fronts) >= 20 and np.median(fronts) == pytest.approx(0.6, abs=0.05)
    assert all(reseen_farther(r, b, (a, z), 5.0, STEP_RAD, rng) is not None for _ in range(3))


def test_training_puts_each_sample_before_walls_and_keeps_its_source() -> None:
    tl = _train_legs()
    rng = np.random.default_rng(SEED)
    smp = tl.Samples()
    for leg_range_m in (1.5, 3.0):
        r, b = _scan(leg_range_m, 40.0, RECORDED_STEP_RAD, rng)
        r[r > leg_range_m + 1.0] = np.nan
        smp.add_scan(r, b, lambda pts, c=leg_range_m: abs(float(pts.mean(axis=0)[0]) - c) < 0.1)
    x, src = tl.walled(smp, 3, np.random.default_rng(SEED))
    assert x.shape[1] == len(FEATURE_NAMES) and set(src.tolist()) <= {0, 1} and len(src) == len(x) >= 3
    fronts = x[:, [FEATURE_NAMES.index("front_left_m"), FEATURE_NAMES.index("front_right_m")]]
    assert np.all(fronts <= tl.WALL_DEPTH_M[1] + 0.1)  # no longer open space beside it
    again, _ = tl.walled(smp, 3, np.random.default_rng(SEED))
    np.testing.assert_array_equal(x, again)


@pytest.mark.parametrize("leg_range_m", [1.2, 2.5])
def test_the_shipped_detector_takes_a_leg_before_a_wall_as_before_open_space(leg_range_m) -> None:
    """A 0.12 m leg seen by the UTM-30LX before open space, and before a wall 0.2-1.5 m behind with the
    UTM-30LX's depth edges (mixed pixels, pulled returns at their recorded rates): what stands behind a
    leg changes its leg probability little. Measured: open / walled 1.0 / 0.825 at 1.2 m, 1.0 / 0.975 at
    2.5 m (the model trained without walls: 0.95 / 0.675 at 1.2 m); not met at 4 m (1.0 / 0.75; before:
    1.0 / 0.8)."""
    from app.legmodel import Wall, before_wall

    model = default_leg_model()
    rng = np.random.default_rng(SEED)
    open_hits, wall_hits = [], []
    for k in range(40):
        r, b = _scan(leg_range_m, 40.0, STEP_RAD, rng)
        r[r > leg_range_m + 2.0] = np.nan
        a, z, row = _leg_span(r, b, leg_range_m)
        open_hits.append(model.predict(row[None])[0] >= model.threshold_p)
        walled = before_wall(prefiltered(r, b)[0], b, (a, z), Wall(0.2 + 1.3 * k / 39), rng)
        kept, x = leg_candidates(walled, b)
        near = [row for (_, _, pts), row in zip(kept, x, strict=True)
                if abs(float(pts.mean(axis=0)[0]) - leg_range_m) < 0.1]
        wall_hits.append(bool(near) and model.predict(near[0][None])[0] >= model.threshold_p)
    assert np.mean(open_hits) >= 0.8
    assert np.mean(wall_hits) >= np.mean(open_hits) - 0.2


# ---------------------------------------------------------------------------------------------
# a URG-04LX-class scanner's reporting (app.legmodel.Reporting)


def test_urg_class_holds_a_range_on_one_surface_and_never_across_an_edge() -> None:
    from app.legmodel import HOLD_TOL_M, Reporting

    rng = np.random.default_rng(SEED)
    front = 3.2 + np.array([0.008, 0.003, 0.0, 0.003, 0.008])  # a leg's front at 3.2 m: 8 mm deep
    r = np.concatenate([[4.3, 4.3], front, [4.3, 4.3]])
    out = Reporting(sigma_per_range=0.0, hold_share=1.0, edge_loss_share=0.0).apply(r, rng)
    np.testing.assert_allclose(out[2:7], np.full(5, 3.208), atol=1e-9)  # one range over the leg's 5 steps
    np.testing.assert_allclose(out[[0, 1, 7, 8]], np.full(4, 4.3), atol=1e-9)  # the background is not the leg's
    assert np.all(np.abs(np.diff(front)) < HOLD_TOL_M)
    none = Reporting(sigma_per_range=0.0, hold_share=0.0, edge_loss_share=0.0).apply(r, rng)
    np.testing.assert_allclose(none, np.round(r, 3))


def test_urg_class_loses_edge_beams_only_and_rounds_to_its_resolution() -> None:
    from app.legmodel import Reporting

    rng = np.random.default_rng(SEED)
    r = np.array([np.nan, 3.2004, 3.1957, 3.1912, 3.1968, 3.2031, 4.5, 4.5, 4.5, 4.5])
    out = Reporting(sigma_per_range=0.0, hold_share=0.0, edge_loss_share=1.0).apply(r, rng)
    # edge beams: beside no return (1, and the scan's last) or a jump (5, 6); the leg's inside and the
    # background's stay
    assert np.isnan(out[[0, 1, 5, 6, 9]]).all()
    np.testing.assert_allclose(out[[2, 3, 4, 7, 8]], [3.196, 3.191, 3.197, 4.5, 4.5], atol=1e-9)
    kept = Reporting(sigma_per_range=0.0, hold_share=0.0, edge_loss_share=0.0).apply(r, rng)
    assert np.isfinite(kept[1:]).all()
    mm = Reporting(sigma_per_range=0.004, hold_share=0.3, edge_loss_share=0.3).apply(r, rng)
    fin = mm[np.isfinite(mm)]
    np.testing.assert_allclose(fin * 1000.0, np.round(fin * 1000.0), atol=1e-6)


def test_urg_class_range_error_is_common_to_neighbouring_steps_and_grows_with_range() -> None:
    from app.legmodel import Reporting

    rng = np.random.default_rng(SEED)
    rep = Reporting(sigma_per_range=0.005, hold_share=0.0, edge_loss_share=0.0, resolution_m=1e-6)
    for range_m in (1.0, 4.0):
        r = range_m + np.linspace(0.0, 0.05, 8)  # a sloped surface, no jump
        outs = np.array([rep.apply(r, rng) for _ in range(3000)])
        offsets = outs - r
        np.testing.assert_allclose(offsets.std(axis=1), 0.0, atol=1e-5)  # one offset over the steps: no shape
        assert float(offsets[:, 0].std()) == pytest.approx(0.005 * float(np.median(r)), rel=0.08)


@pytest.mark.parametrize("bad", [{"sigma_per_range": -0.1}, {"hold_share": 1.5}, {"edge_loss_share": -0.1},
                                 {"resolution_m": 0.0}])
def test_urg_class_reporting_is_checked(bad) -> None:
    from app.legmodel import Reporting

    with pytest.raises(ValueError, match="need"):
        Reporting(**bad)


def test_urg_class_draws_span_the_class() -> None:
    from app.legmodel import EDGE_LOSS_SHARE, HOLD_SHARE, URG04LX_SIGMA_PER_RANGE, Reporting

    rng = np.random.default_rng(SEED)
    drawn = [Reporting.drawn(rng) for _ in range(200)]
    holds = np.array([d.hold_share for d in drawn])
    losses = np.array([d.edge_loss_share for d in drawn])
    sig = np.array([d.sigma_per_range for d in drawn])
    assert HOLD_SHARE[0] <= holds.min() < 0.1 and HOLD_SHARE[1] - 0.1 < holds.max() <= HOLD_SHARE[1]
    assert EDGE_LOSS_SHARE[0] <= losses.min() < 0.05 and EDGE_LOSS_SHARE[1] - 0.05 < losses.max() <= EDGE_LOSS_SHARE[1]
    assert 0.0 <= sig.min() and sig.max() <= URG04LX_SIGMA_PER_RANGE


def test_training_reports_each_sample_as_a_urg_class_scanner_and_keeps_its_source() -> None:
    tl = _train_legs()
    from app.legmodel import URG04LX_MAX_RANGE_M

    smp = _leg_samples(tl, (1.5, 3.0, 6.0), 0.5)
    assert len(smp.rows) == 3
    x, src = tl.urg_class(smp, 4, np.random.default_rng(SEED))
    assert x.shape[1] == len(FEATURE_NAMES) and set(src.tolist()) <= {0, 1} and len(src) == len(x) >= 4
    rng_m = x[:, FEATURE_NAMES.index("range_m")]
    assert np.all(rng_m >= smp.matrix()[src, FEATURE_NAMES.index("range_m")] - 0.03)
    assert np.all(rng_m <= URG04LX_MAX_RANGE_M + 0.05)  # the leg beyond the scanner's range gets no copy
    again, _ = tl.urg_class(smp, 4, np.random.default_rng(SEED))
    np.testing.assert_array_equal(x, again)


@pytest.mark.parametrize("leg_range_m, share", [(2.0, 0.9), (3.0, 0.7)])
def test_the_shipped_detector_takes_a_leg_a_urg_class_scanner_holds_in_part(leg_range_m, share) -> None:
    """A 0.12 m leg before open space seen by a URG-04LX-class scanner at its step, 0.6 of its same-surface
    steps holding their neighbour's range and half its edge beams lost: still a leg to the shipped detector
    (measured 0.97 / 0.78 at 2 / 3 m). Not met, and not claimed (docs/estimator.md stage 1): a leg whose every
    step is held and both edge beams lost is one range over 5-8 steps, no shape left (taken 0.02 / 0.05)."""
    from app.legmodel import URG04LX_STEP_RAD, Reporting

    model = default_leg_model()
    rep = Reporting(sigma_per_range=0.002, hold_share=0.6, edge_loss_share=0.5)
    rng = np.random.default_rng(SEED)
    hits = []
    for _ in range(40):
        r, b = _scan(leg_range_m, 40.0, URG04LX_STEP_RAD, rng)
        r[r > leg_range_m + 2.0] = np.nan
        kept, x = leg_candidates(rep.apply(r, rng), b)
        near = [row for (_, _, pts), row in zip(kept, x, strict=True)
                if abs(float(pts.mean(axis=0)[0]) - leg_range_m) < 0.1]
        hits.append(bool(near) and model.predict(near[0][None])[0] >= model.threshold_p)
    assert np.mean(hits) >= share


def test_train_legs_refuses_negative_urg_copies(capsys) -> None:
    tl = _train_legs()
    assert tl.main(["--urg-copies", "-1"]) == 2
    assert "--urg-copies" in capsys.readouterr().err
