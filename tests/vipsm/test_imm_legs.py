"""The people filter's leg model (vipsm.imm: the first leg's offset from the body's centre in the state;
vipsm.people: which leg the offset belongs to as leg tracks come and go)."""

from __future__ import annotations

import numpy as np
import pytest

from app.legmodel import default_leg_model
from vipsm.imm import Imm, ImmConfig
from vipsm.people import LegDetection, PeopleConfig, PeopleTracker


def test_a_leg_pair_measures_the_centre_and_the_first_legs_offset() -> None:
    cfg = ImmConfig()
    f = Imm(1.0, 1.0, 0.15, cfg)
    for _ in range(5):
        f.predict(0.1)
        f.update_legs((2.0, 0.1), (2.0, -0.1), cfg.leg_noise_m, cfg.leg_noise_m, 0.06)
    assert f.mean[:2] == pytest.approx([2.0, 0.0], abs=0.02)
    assert f.mean[4:] == pytest.approx([0.0, 0.1], abs=0.01)
    # the second leg alone now says where the centre is given the offset: the centre stays put
    f.predict(0.1)
    f.update_legs(None, (2.0, -0.1), cfg.leg_noise_m, cfg.leg_noise_m, 0.15)
    assert f.mean[:2] == pytest.approx([2.0, 0.0], abs=0.02)


def test_flipping_the_offset_makes_the_second_leg_the_first() -> None:
    cfg = ImmConfig()
    f = Imm(0.0, 0.0, 0.1, cfg, offset=(0.05, 0.1))
    f.predict(0.1)
    f.update_legs((0.05, 0.1), (-0.05, -0.1), cfg.leg_noise_m, cfg.leg_noise_m, 0.06)
    before_mean, before_cov = f.means.copy(), f.covs.copy()
    f.flip_offset()
    assert np.allclose(f.means[:, 4:], -before_mean[:, 4:]) and np.allclose(f.means[:, :4], before_mean[:, :4])
    assert np.allclose(f.covs[:, 4:, 4:], before_cov[:, 4:, 4:])
    assert np.allclose(f.covs[:, :4, 4:], -before_cov[:, :4, 4:])
    f.reset_offset()
    assert np.allclose(f.means[:, 4:], 0.0) and np.allclose(f.covs[:, :4, 4:], 0.0)
    assert np.allclose(f.covs[:, 4, 4], cfg.hip_half_width_m**2)


def test_a_standing_person_seen_by_one_leg_stays_at_its_centre() -> None:
    """Both legs seen 2 s, then only one (the other's track ends after ``leg_memory_s``): the person is
    measured at the leg left, given the offset that leg held, and stays near its centre (before, the
    filter took the lone leg for the centre with white noise and was 7 cm from the centre, 0.1 m from the
    leg, a second after the other leg's track ended)."""
    tr = PeopleTracker(PeopleConfig(), default_leg_model())
    rng = np.random.default_rng(1)
    for k in range(35):
        dets = [LegDetection(2.0 + rng.normal(0, 0.005), 0.1 + rng.normal(0, 0.005), 0.9, 2, 3)]
        if k < 20:
            dets.append(LegDetection(2.0 + rng.normal(0, 0.005), -0.1 + rng.normal(0, 0.005), 0.9, 0, 1))
        tr.step(0.1 * k, dets)
    (p,) = tr.tracks
    assert len(p.leg_ids) == 1 and p.offset_leg == p.leg_ids[0]
    assert p.filt.mean[4:] == pytest.approx([0.0, 0.1], abs=0.04)  # the leg left is the first leg now
    assert abs(float(p.filt.mean[1])) < 0.04 and not p.moving


@pytest.mark.parametrize("key", ["hip_half_width_m", "leg_swing_s", "leg_offset_tau_s", "leg_noise_m"])
def test_the_leg_model_rejects_nonsense(key: str) -> None:
    with pytest.raises(ValueError):
        ImmConfig(**{key: 0.0})


def test_the_offset_spreads_along_the_walk_with_the_stride_and_across_a_hips_half_width() -> None:
    cfg = ImmConfig()
    f = Imm(0.0, 0.0, 0.1, cfg)
    assert np.allclose(f.offset_spread(None), np.eye(2) * cfg.hip_half_width_m**2)  # standing: the stance's
    walk = f.offset_spread(np.array([0.0, 1.4]))
    assert walk[0, 0] == pytest.approx(cfg.hip_half_width_m**2) and walk[0, 1] == pytest.approx(0.0)
    assert walk[1, 1] == pytest.approx(cfg.hip_half_width_m**2 + (1.4 * cfg.leg_swing_s) ** 2)
    # a walker along y, its legs seen 3 s: the walking models' offset spreads along y, the standing one's not
    for k in range(30):
        f.predict(0.1)
        y = 0.14 * (k + 1)
        f.update_legs((0.1, y), (-0.1, y), cfg.leg_noise_m, cfg.leg_noise_m, 0.06)
    f.predict(0.1)
    assert f.p_moving > 0.9
    for j in (1, 2):
        assert f.covs[j][5, 5] > 1.3 * f.covs[j][4, 4]
    assert f.covs[0][5, 5] == pytest.approx(f.covs[0][4, 4], rel=0.1)
