"""An interacting multiple model (IMM) filter of a person's position and velocity: standing or walking.

Two motion models on the state (x, y, vx, vy), world frame, SI units:

* **standing**: the velocity is zero (the model resets it each step); the position wanders by
  ``stand_sigma_mps`` per square root of a second (a standing person's leg-pair midpoint shuffles with
  the weight shifting from foot to foot);
* **walking**: constant velocity with white acceleration noise, one model per ``walk_accel_mps2``:
  steady walking (0.3 m/s^2: the speed wanders by ~0.1 m/s over a few seconds, and the filter averages
  the gait's wobble out) and manoeuvring (2 m/s^2: starting, stopping, turning, stepping aside take
  about half a second).

**The legs** (issue 29): the state also holds the offset ``(bx, by)`` of the person's first leg's centre
from the body's centre (the second leg's is ``-b``: the legs lie either side of the centre), so that a
person is measured at its legs themselves (:meth:`Imm.update_legs`), each to a detected leg centre's noise
``leg_noise_m``: the pair's midpoint says where the centre is, a lone leg says where the centre is *given
the offset that leg has held*. The offset is a Gauss-Markov (Ornstein-Uhlenbeck) process about zero with
correlation time ``leg_offset_tau_s`` (about a gait cycle: a leg stands while the body passes it, then
swings ahead) whose long-run spread is the gait's (issue 29): across the line of walking a leg stays within
a hip's half-width (``hip_half_width_m``), and so does it every way while the person stands (the stance's
half-width); along the line it swings with the stride, ``leg_swing_s`` times the speed more (a step's
length is about the speed times half a second, 0.3 m at 0.5 m/s to 0.7 m at 1.4 m/s, and the shin at the
laser's height swings about two thirds of the foot's half-step either side of the pelvis). So the spread
is, per model, ``hip_half_width_m**2 I + leg_swing_s**2 v v^T`` at that model's velocity ``v`` (standing:
zero). A lone leg is no longer the body's position with white noise (its offset is one value for as long
as the leg stands, and the filter took its stance for the body standing). The swing's scale is fitted by
maximum likelihood to the detected legs of the labelled walkers of the
recordings positive_1-3 (``tools/fit_person_motion.py``; positive_6 held out).

The models switch with rate ``switch_per_s`` (a Markov chain: with ``leave = 1 - exp(-rate dt)`` in a
step of ``dt``, standing starts a walk with probability ``leave``, shared by the walking models, and a
walking model stops, or changes pace to each other walking model, with ``leave`` each: standing and
walking weigh alike in the long run). The walking models' probability is P(moving); the combined
state gives position, velocity and covariance. Standard IMM (Blom and Bar-Shalom): mixing, per-model
Kalman prediction and update, model probabilities from the measurement likelihoods.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

STANDING = 0  # the first model; the others walk


@dataclass(frozen=True)
class ImmConfig:
    stand_sigma_mps: float = 0.05
    walk_accel_mps2: tuple[float, ...] = (0.3, 2.0)
    #: how readily the filter changes its mind (not a person's dwell: see ``PeopleConfig.stand_dwell_s``).
    #: The onset of a walk is set by the measurements, hardly by this rate: P(walking) >= 0.8 came 0.5 s
    #: after a 1.8 m/s^2 start at 0.1-0.5 per second alike (10 Hz, 0.06 m noise; a start moves the pelvis
    #: 1, 4, 8 cm in 0.1, 0.2, 0.3 s); a higher rate lifts a standing person's P(walking) (its largest
    #: over 30 s: 0.78 at 0.5 per second, 0.47 at 0.1), a lower one made the tracker's gate, which follows
    #: the combined covariance, lose starting walkers in the simulated scenes (docs/estimator.md, 6b)
    switch_per_s: float = 0.5
    #: speed uncertainty of a new track (a walker: up to ~1.5 m/s)
    init_speed_sigma_mps: float = 0.8
    #: P(moving) of a new track
    init_p_moving: float = 0.2
    #: the first leg's offset from the body's centre: its spread across the line of walking, and every way
    #: standing (a hip's half-width, the stance's: 0.10 m); how much more it spreads along the line per unit
    #: of walking speed (the stride: a step of ~0.5 s, the shin at the laser's height two thirds of the
    #: foot's half-step, a sinusoid's standard deviation 1/sqrt(2) of its amplitude: 0.5 * 2/3 / 2 / sqrt(2)
    #: = 0.12 s; the maximum-likelihood fit on positive_1-3's detected walkers, tools/fit_person_motion.py:
    #: 0.155 s, 2.06 nats per scan against 1.98 without the swing); how long it keeps its offset
    #: (correlation time: about a gait cycle; the isotropic fit's 1.0 s); a detected leg centre's noise: the
    #: fit says 0.030 m on walkers at 1-5 m, which made a moving person of the drive's far furniture legs
    #: (negative_2, left laser: 2 reports); 0.04 m kept it 0
    hip_half_width_m: float = 0.10
    leg_swing_s: float = 0.155
    leg_offset_tau_s: float = 1.0
    leg_noise_m: float = 0.04

    def __post_init__(self) -> None:
        if not self.walk_accel_mps2 or min(self.stand_sigma_mps, *self.walk_accel_mps2, self.switch_per_s,
                                           self.init_speed_sigma_mps, self.hip_half_width_m, self.leg_swing_s,
                                           self.leg_offset_tau_s, self.leg_noise_m) <= 0.0:
            raise ValueError("the IMM's noises, switch rate, initial speed sigma and leg offset must be positive")
        if not 0.0 < self.init_p_moving < 1.0:
            raise ValueError(f"init_p_moving must be in (0, 1), got {self.init_p_moving}")


def _transitions(n: int, leave: float) -> np.ndarray:
    """trans[i, j] = P(model j next | model i now) over a step in which a model is left with probability
    ``leave``: standing starts a walk (either walking model alike); a walking model stops (to standing)
    or changes its pace (to each other walking model) with that probability each. Standing and walking
    then weigh alike in the long run (without it, two walking models against one standing gave every
    unobserved track P(walking) 2/3, and a standing person's P(walking) hovered at a third)."""
    trans = np.zeros((n, n))
    if n == 1:
        return np.ones((1, 1))
    trans[0, 1:] = leave / (n - 1)
    trans[0, 0] = 1.0 - leave
    for j in range(1, n):
        trans[j, 0] = leave
        others = [k for k in range(1, n) if k != j]
        for k in others:
            trans[j, k] = leave / len(others)
        trans[j, j] = 1.0 - trans[j].sum()
    return trans


#: state (x, y, vx, vy, bx, by): the body's centre, its velocity, its first leg's offset from the centre
_DIM = 6
_H = np.eye(_DIM)[:2]
#: the first leg (the centre plus the offset), the second leg (the centre less it)
_H_LEG = (np.array([[1.0, 0, 0, 0, 1, 0], [0, 1, 0, 0, 0, 1]]), np.array([[1.0, 0, 0, 0, -1, 0], [0, 1, 0, 0, 0, -1]]))


class Imm:
    """One track's IMM state: per-model means (m x 6) and covariances (m x 6 x 6), model probabilities.
    ``offset``: the first leg's offset from the centre when known (a pair's half-difference), else zero
    with a walking leg's spread."""

    def __init__(self, x_m: float, y_m: float, pos_sigma_m: float, cfg: ImmConfig,
                 offset: tuple[float, float] | None = None) -> None:
        self.cfg = cfg
        b_var = cfg.leg_noise_m**2 / 2 if offset is not None else cfg.hip_half_width_m**2
        p = np.diag([pos_sigma_m**2, pos_sigma_m**2, cfg.init_speed_sigma_mps**2, cfg.init_speed_sigma_mps**2,
                     b_var, b_var])
        n = 1 + len(cfg.walk_accel_mps2)
        self.means = np.tile(np.array([x_m, y_m, 0.0, 0.0, *(offset or (0.0, 0.0))]), (n, 1))
        p_stand = p.copy()
        p_stand[2:4, 2:4] = np.eye(2) * 1e-6
        self.covs = np.stack([p_stand] + [p] * (n - 1))
        self.probs = np.array([1.0 - cfg.init_p_moving] + [cfg.init_p_moving / (n - 1)] * (n - 1))
        self._mean: np.ndarray | None = None
        self._cov: np.ndarray | None = None
        #: the last update's measurement likelihood under each model (its predictive density at the
        #: measurement) and the model probabilities it started from (the prediction's); None before one
        self.likelihoods: np.ndarray | None = None
        self.prior_probs: np.ndarray | None = None
        #: the last update's predictive log density of its whole measurement (the fit's objective)
        self.log_density = 0.0

    # ---------------------------------------------------------------- combined estimate
    @property
    def p_moving(self) -> float:
        return float(1.0 - self.probs[STANDING])

    @property
    def mean(self) -> np.ndarray:
        """The combined state (computed once per filter step)."""
        if self._mean is None:
            self._mean = self.probs @ self.means
        return self._mean

    @property
    def cov(self) -> np.ndarray:
        """The combined covariance (computed once per filter step)."""
        if self._cov is None:
            d = self.means - self.mean
            self._cov = np.einsum("i,ijk->jk", self.probs, self.covs + np.einsum("ij,ik->ijk", d, d))
        return self._cov

    def walking_likelihood(self) -> float:
        """The last update's measurement likelihood given that the person walks: the walking models'
        likelihoods weighted by their predicted probabilities (0.0 before any update)."""
        if self.likelihoods is None or self.prior_probs is None:
            return 0.0
        w = self.prior_probs[STANDING + 1 :]
        return float(w @ self.likelihoods[STANDING + 1 :] / max(float(w.sum()), 1e-300))

    def walking(self) -> tuple[np.ndarray, np.ndarray]:
        """The state and covariance given that the person walks (the walking models' mixture): a moving
        person's velocity, not shrunk towards the standing model's zero by P(standing)."""
        w = self.probs[STANDING + 1 :]
        w = w / max(float(w.sum()), 1e-300)
        means, covs = self.means[STANDING + 1 :], self.covs[STANDING + 1 :]
        mean = w @ means
        d = means - mean
        return mean, np.einsum("i,ijk->jk", w, covs + np.einsum("ij,ik->ijk", d, d))

    # ---------------------------------------------------------------- filter steps
    def _models(self, dt: float, means: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Each model's transition and process noise over ``dt`` from its (mixed) ``means``: the offset's
        noise keeps its spread at the gait's at that model's velocity (:meth:`offset_spread`)."""
        c = self.cfg
        f_walk = np.eye(_DIM)
        f_walk[0, 2] = f_walk[1, 3] = dt
        keep = math.exp(-dt / c.leg_offset_tau_s)  # the first leg's offset: Ornstein-Uhlenbeck
        f_walk[4, 4] = f_walk[5, 5] = keep
        f_stand = np.diag([1.0, 1.0, 0.0, 0.0, keep, keep])
        g = np.zeros((_DIM, _DIM))
        g[:4, :4] = [[dt**4 / 4, 0, dt**3 / 2, 0], [0, dt**4 / 4, 0, dt**3 / 2],
                     [dt**3 / 2, 0, dt**2, 0], [0, dt**3 / 2, 0, dt**2]]
        wander = c.stand_sigma_mps**2 * dt
        qs = [np.diag([wander, wander, 1e-6, 1e-6, 0.0, 0.0])] + [a**2 * g for a in c.walk_accel_mps2]
        for j, q in enumerate(qs):
            q[4:, 4:] += self.offset_spread(means[j][2:4] if j != STANDING else None) * (1.0 - keep * keep)
        return [f_stand] + [f_walk] * len(c.walk_accel_mps2), qs

    def offset_spread(self, velocity_mps: np.ndarray | None) -> np.ndarray:
        """The first leg's offset's long-run covariance (2 x 2) at a walking velocity (None: standing): a
        hip's half-width every way, and along the line of walking the stride's swing."""
        spread = np.eye(2) * self.cfg.hip_half_width_m**2
        if velocity_mps is not None:
            spread += self.cfg.leg_swing_s**2 * np.outer(velocity_mps, velocity_mps)
        return spread

    def predict(self, dt: float) -> None:
        """Mix the models and predict each ``dt`` seconds ahead."""
        if dt <= 0.0:
            return
        n = self.probs.size
        trans = _transitions(n, 1.0 - math.exp(-self.cfg.switch_per_s * dt))
        c = trans.T @ self.probs  # predicted model probabilities
        mix = trans * self.probs[:, None] / np.maximum(c[None, :], 1e-300)  # mix[i, j] = P(i | j)
        means = mix.T @ self.means
        covs = np.empty_like(self.covs)
        for j in range(n):
            d = self.means - means[j]
            covs[j] = np.einsum("i,ijk->jk", mix[:, j], self.covs + np.einsum("ij,ik->ijk", d, d))
        fs, qs = self._models(dt, means)
        for j in range(n):
            means[j] = fs[j] @ means[j]
            covs[j] = fs[j] @ covs[j] @ fs[j].T + qs[j]
        self.means, self.covs, self.probs = means, covs, c
        self._mean = self._cov = None

    def innovation(self, z: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The combined prediction's innovation and its covariance for a position measurement."""
        return z - self.mean[:2], self.cov[:2, :2] + r

    def update(self, z: np.ndarray, r: np.ndarray) -> None:
        """Fold in a measurement ``z`` (2,) of the body's centre with covariance ``r`` (2 x 2)."""
        self._update(z, r, _H, z, r)

    def update_legs(self, first: tuple[float, float] | None, second: tuple[float, float] | None,
                    first_sigma_m: float, second_sigma_m: float, centre_sigma_m: float) -> None:
        """Fold in the person's legs seen this cycle: its first leg's centre (the body's centre plus the
        offset), its second's (less it), either None when unseen (not both), each with its noise. The
        likelihoods kept (:attr:`likelihoods`, for the evidence of a body that moves against a static thing)
        are those of the legs' midpoint (a lone leg: the leg) with noise ``centre_sigma_m``: that evidence
        must hold against a detection's worst jumps (a static leg's centre jumps up to 9 cm with the part of
        it seen), which the association's noises say (``PeopleConfig.pair_sigma_m``, ``leg_sigma_m``), not
        the leg model's."""
        seen = [(xy, h, s) for xy, h, s in zip((first, second), _H_LEG, (first_sigma_m, second_sigma_m),
                                               strict=True) if xy is not None]
        z = np.concatenate([np.asarray(xy, float) for xy, _, _ in seen])
        h = np.vstack([h for _, h, _ in seen])
        r = np.diag(np.repeat([s**2 for _, _, s in seen], 2))
        mid_h = sum(hh for _, hh, _ in seen) / len(seen)
        self._update(z, r, h, z.reshape(-1, 2).mean(axis=0), np.eye(2) * centre_sigma_m**2, mid_h)

    def flip_offset(self) -> None:
        """The second leg becomes the first (the first one's track ended): the offset changes sign."""
        self.means[:, 4:] *= -1.0
        self.covs[:, 4:, :4] *= -1.0
        self.covs[:, :4, 4:] *= -1.0
        self._mean = self._cov = None

    def reset_offset(self) -> None:
        """New legs: the first leg's offset unknown again (zero, each model's gait spread), uncorrelated."""
        self.means[:, 4:] = 0.0
        self.covs[:, 4:, :] = 0.0
        self.covs[:, :, 4:] = 0.0
        for j in range(self.probs.size):
            self.covs[j, 4:, 4:] = self.offset_spread(self.means[j, 2:4] if j != STANDING else None)
        self._mean = self._cov = None

    def _update(self, z: np.ndarray, r: np.ndarray, h: np.ndarray, mid_z: np.ndarray, mid_r: np.ndarray,
                mid_h: np.ndarray = _H) -> None:
        """Kalman update of each model with ``z`` = ``h`` x + noise ``r``; the model probabilities from its
        density; :attr:`likelihoods` from the density of the centre measurement ``mid_z`` = ``mid_h`` x +
        noise ``mid_r``; :attr:`log_density` the whole measurement's predictive log density."""
        like = np.empty(self.probs.size)
        dens = np.empty(self.probs.size)
        for j in range(self.probs.size):
            m, c = self.means[j], self.covs[j]
            ym, sm = mid_z - mid_h @ m, mid_h @ c @ mid_h.T + mid_r
            like[j] = math.exp(-0.5 * float(ym @ np.linalg.solve(sm, ym))) / math.sqrt(np.linalg.det(2 * math.pi * sm))
            s, y = h @ c @ h.T + r, z - h @ m
            dens[j] = math.exp(-0.5 * float(y @ np.linalg.solve(s, y))) / math.sqrt(np.linalg.det(2 * math.pi * s))
            k = c @ h.T @ np.linalg.inv(s)
            self.means[j] = m + k @ y
            cj = (np.eye(_DIM) - k @ h) @ c
            self.covs[j] = 0.5 * (cj + cj.T)
        self._mean = self._cov = None
        self.likelihoods, self.prior_probs = like, self.probs.copy()
        post = self.probs * dens
        total = float(post.sum())
        self.log_density = math.log(total) if total > 0.0 else -math.inf
        if total > 0.0 and math.isfinite(total):
            self.probs = np.clip(post / total, 1e-6, 1.0 - 1e-6)
            self.probs /= self.probs.sum()
