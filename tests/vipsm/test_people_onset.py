"""A walk's onset in the people stage: the IMM's measurement likelihoods as evidence of "a body that moves"
(vipsm.imm ``likelihoods`` / ``walking_likelihood``, vipsm.people ``_kinematic_likelihoods``)."""

from __future__ import annotations

import numpy as np
import pytest

from app.legmodel import default_leg_model
from vipsm.imm import STANDING, Imm, ImmConfig
from vipsm.people import LegDetection, PeopleConfig, PeopleTracker

from .evidence import bayes_factor

RNG_SEED = 29


def _pair(x: float, y: float, p: float = 0.9, evidence: bool = False, occluded: bool = False) -> list[LegDetection]:
    """Two legs of a person at (x, y), 0.1 m either side of it."""
    return [LegDetection(x, y - 0.1, p, 0, 1, evidence, occluded),
            LegDetection(x, y + 0.1, p, 2, 3, evidence, occluded)]


def _track(speed_mps: float, cycles: int = 20, **kw) -> PeopleTracker:
    """One pair of legs moving along x at ``speed_mps`` (10 Hz), the places it leaves never seen empty."""
    tr = PeopleTracker(PeopleConfig(), default_leg_model())
    for k in range(cycles):
        tr.step(0.1 * k, _pair(1.0 + speed_mps * 0.1 * k, 2.0, **kw), seen_free=lambda x, y: False)
    return tr


def test_imm_keeps_each_models_likelihood_of_the_last_measurement() -> None:
    """After an update the filter holds each model's predictive density at the measurement and the model
    probabilities it started from; the walking models explain a walker's next position better than the
    standing model does, and a standing person's no better."""
    rng = np.random.default_rng(RNG_SEED)
    walker, stander = Imm(0.0, 0.0, 0.06, ImmConfig()), Imm(0.0, 0.0, 0.06, ImmConfig())
    assert walker.likelihoods is None and walker.walking_likelihood() == 0.0
    for k in range(1, 15):
        for f, x in ((walker, 0.1 * k), (stander, 0.0)):
            f.predict(0.1)
            prior = f.probs.copy()
            f.update(np.array([x, 0.0]) + rng.normal(0.0, 0.02, 2), np.eye(2) * 0.06**2)
            assert f.prior_probs == pytest.approx(prior)
    assert walker.likelihoods is not None and stander.likelihoods is not None
    assert walker.walking_likelihood() > 2.0 * walker.likelihoods[STANDING]
    assert stander.walking_likelihood() <= stander.likelihoods[STANDING]
    w = walker.prior_probs[1:] / walker.prior_probs[1:].sum()
    assert walker.walking_likelihood() == pytest.approx(float(w @ walker.likelihoods[1:]))


def test_a_walker_without_motion_evidence_is_a_body_that_moves_by_its_kinematics() -> None:
    """A pair of legs seen in full walking at 0.5 m/s for 2 s, no return where the laser saw free space and
    no place it left seen empty: its detections keep landing where the walking models predict them, which
    a static thing's (where the standing model predicts them, or another thing's anywhere in the gate)
    do not, so P(a body that moves) rises from what the person was born with, the legs' leg probability
    (before: each detection without evidence counted against it, 0.5 -> 0.05). A slow drift at a standing
    person's sway (0.05 m/s) gives no such evidence."""
    born = 0.9  # both legs' leg probability (``_pair``)
    walker = _track(0.5).tracks[0]
    assert bayes_factor(born, walker.p_dynamic) > 9.0 and walker.moving
    still = _track(0.05).tracks[0]
    assert bayes_factor(born, still.p_dynamic) < 1.2 and not still.moving


def test_a_partly_hidden_thing_sliding_with_its_occluders_edge_is_no_moving_person() -> None:
    """A wall piece beside a table leg slides along the wall as the robot drives by (0.5 m/s): partly hidden,
    its centre moves with the edge of what hides it, so its slide is no evidence of a body that moves
    (its kinematics are not weighed for P(a body that moves)): without motion evidence it is no moving
    person in 2 s, however well the walking models follow the slide."""
    tr = PeopleTracker(PeopleConfig(), default_leg_model())
    for k in range(20):
        tr.step(0.1 * k, _pair(1.0 + 0.05 * k, 2.0, occluded=True), seen_free=lambda x, y: False)
        assert not any(t.moving for t in tr.tracks)
    assert tr.tracks[0].p_moving < PeopleConfig().moving_on


def test_a_single_hop_of_a_static_leg_pair_is_no_walk() -> None:
    """A static pair seen 3 s whose detection then lands 0.25 m away once (a leg track re-locking onto a
    neighbouring thing) and stays there: another thing's detection in the gate explains the jump about as
    well as a walk's start does, so P(a body that moves) stays about where it was."""
    tr = PeopleTracker(PeopleConfig(), default_leg_model())
    rng = np.random.default_rng(RNG_SEED)
    for k in range(40):
        x = 2.0 + (0.25 if k >= 30 else 0.0)
        tr.step(0.1 * k, _pair(x + rng.normal(0, 0.005), 1.0 + rng.normal(0, 0.005), p=0.6),
                seen_free=lambda x, y: False)
        if k == 29:
            before = tr.tracks[0].p_dynamic
    (t,) = tr.tracks
    assert t.p_dynamic < before + 0.1 and not t.moving


def test_a_detection_with_motion_evidence_counts_its_displacement_once() -> None:
    """Motion evidence (a leg that left its place, a return where the laser saw free space) and the
    kinematic likelihood measure one displacement: a detection with evidence updates P(a body that moves)
    by the evidence's rates alone."""
    c = PeopleConfig()
    tr = PeopleTracker(c, default_leg_model())
    for k in range(5):
        tr.step(0.1 * k, _pair(1.0 + 0.1 * k, 2.0, evidence=k == 4), seen_free=lambda x, y: False)
        if k == 3:
            (t,) = tr.tracks
            prior, stamp = t.p_dynamic, t.updated_s
    share = tr._walking_share(t)
    e_dyn = c.evidence_standing + share * (c.evidence_moving - c.evidence_standing)
    stayed = np.exp(-(1.0 - share) * (t.updated_s - stamp) / c.stand_dwell_s)
    num = prior * e_dyn * stayed
    assert t.p_dynamic == pytest.approx(num / (num + (1.0 - prior) * c.evidence_standing))


def _half_hidden_walker(speed_mps: float, evidence_every: int) -> list[bool]:
    """A person walking away from the laser at ``speed_mps`` (10 Hz), its far leg partly hidden behind its near
    leg (each centre with a real pair's 0.015 m jitter); the near leg's returns stand where the laser saw free
    space on every ``evidence_every``-th detection. The moving flag per cycle."""
    tr = PeopleTracker(PeopleConfig(), default_leg_model())
    rng = np.random.default_rng(RNG_SEED)
    moving = []
    for k in range(15):
        x = 1.5 + speed_mps * 0.1 * k
        near = LegDetection(x + rng.normal(0, 0.015), 0.1 + rng.normal(0, 0.015), 0.9, 0, 1, k % evidence_every == 0)
        far = LegDetection(x + 0.05 + rng.normal(0, 0.015), -0.1 + rng.normal(0, 0.015), 0.9, 2, 3, False, True)
        tr.step(0.1 * k, [near, far], seen_free=lambda x, y: False)
        moving.append(tr.tracks[0].moving)
    return moving


def test_a_walker_whose_far_leg_is_partly_hidden_is_moving_within_a_second() -> None:
    """A partly hidden leg's centre lies at most a leg's radius off (its hidden part), half that in the legs'
    midpoint: the pair's midpoint follows a slow walk (0.4 m/s) as a pair seen in full does, and with motion
    evidence now and then the walker is moving within a second (the code before took the whole midpoint
    to a hip's half-width, and P(walking) was 0.34 at 0.8 s: not moving in 1.5 s). The same legs standing
    still, with the same evidence, are not."""
    walks = _half_hidden_walker(0.4, 3)
    assert any(walks[:11]) and all(walks[11:])
    assert not any(_half_hidden_walker(0.0, 3))



def test_a_person_born_of_a_leg_pair_is_a_body_that_moves_as_likely_as_its_legs_are_a_persons() -> None:
    """P(a body that moves) at birth: two legs the detector takes (0.9 and 0.7) are a person's as likely as
    the less likely of them is a leg (0.7); a lone leg-like segment (what a post or a table leg gives as
    well) starts at even odds, whatever its leg probability. A person who stood still since then needs
    that much less evidence when it walks off (a standing person's stand counts against it from there:
    ``stand_dwell_s``)."""
    tr = PeopleTracker(PeopleConfig(), default_leg_model())
    pair = [LegDetection(2.0, -0.1, 0.9, 0, 1), LegDetection(2.0, 0.1, 0.7, 2, 3)]
    tr.step(0.0, pair + [LegDetection(4.0, 2.0, 0.95, 4, 5)])
    two, one = sorted(tr.tracks, key=lambda t: len(t.leg_ids), reverse=True)
    assert len(two.leg_ids) == 2 and len(one.leg_ids) == 1
    assert two.p_dynamic == pytest.approx(0.7) and one.p_dynamic == pytest.approx(0.5)
