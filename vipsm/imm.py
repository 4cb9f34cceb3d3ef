"""An interacting multiple model (IMM) filter of a person's position and velocity: standing or walking.

Two motion models on the state (x, y, vx, vy), world frame, SI units:

* **standing**: the velocity is zero (the model resets it each step); the position wanders by
  ``stand_sigma_mps`` per square root of a second (a standing person's leg-pair midpoint shuffles with
  the weight shifting from foot to foot);
* **walking**: constant velocity with white acceleration noise, one model per ``walk_accel_mps2``:
  steady walking (0.3 m/s^2: the speed wanders by ~0.1 m/s over a few seconds, and the filter averages
  the gait's wobble out) and manoeuvring (2 m/s^2: starting, stopping, turning, stepping aside take
  about half a second).

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
WALKING = slice(STANDING + 1, None)  # the walking models' rows


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

    def __post_init__(self) -> None:
        if not self.walk_accel_mps2 or min(self.stand_sigma_mps, *self.walk_accel_mps2, self.switch_per_s,
                                           self.init_speed_sigma_mps) <= 0.0:
            raise ValueError("the IMM's noise, switch rate and initial speed sigma must be positive")
        if not 0.0 < self.init_p_moving < 1.0:
            raise ValueError(f"init_p_moving must be in (0, 1), got {self.init_p_moving}")


def _mixture(means: np.ndarray, covs: np.ndarray, probs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The moment-matched Gaussian of the models ``means`` (m x 4), ``covs`` (m x 4 x 4) weighted by ``probs``."""
    w = probs / max(float(probs.sum()), 1e-300)
    mean = w @ means
    d = means - mean
    return mean, np.einsum("i,ijk->jk", w, covs + np.einsum("ij,ik->ijk", d, d))


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


_H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


class Imm:
    """One track's IMM state: per-model means (m x 4) and covariances (m x 4 x 4), model probabilities."""

    def __init__(self, x_m: float, y_m: float, pos_sigma_m: float, cfg: ImmConfig) -> None:
        self.cfg = cfg
        p = np.diag([pos_sigma_m**2, pos_sigma_m**2, cfg.init_speed_sigma_mps**2, cfg.init_speed_sigma_mps**2])
        n = 1 + len(cfg.walk_accel_mps2)
        self.means = np.tile(np.array([x_m, y_m, 0.0, 0.0]), (n, 1))
        p_stand = p.copy()
        p_stand[2:, 2:] = np.eye(2) * 1e-6
        self.covs = np.stack([p_stand] + [p] * (n - 1))
        self.probs = np.array([1.0 - cfg.init_p_moving] + [cfg.init_p_moving / (n - 1)] * (n - 1))
        self._mean: np.ndarray | None = None
        self._cov: np.ndarray | None = None
        #: the last update's measurement likelihood under each model (its predictive density at the
        #: measurement) and the model probabilities it started from (the prediction's); None before one
        self.likelihoods: np.ndarray | None = None
        self.prior_probs: np.ndarray | None = None
        #: the walking models' means, covariances and probabilities at the last update (their mixture, as
        #: :meth:`walking`, is taken only when asked for), and the time predicted since
        self._walk_seen: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._since_update_s = 0.0

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
            self._cov = _mixture(self.means, self.covs, self.probs)[1]
        return self._cov

    def walking_likelihood(self) -> float:
        """The last update's measurement likelihood given that the person walks: the walking models'
        likelihoods weighted by their predicted probabilities (0.0 before any update)."""
        if self.likelihoods is None or self.prior_probs is None:
            return 0.0
        w = self.prior_probs[WALKING]
        return float(w @ self.likelihoods[WALKING] / max(float(w.sum()), 1e-300))

    def walking(self) -> tuple[np.ndarray, np.ndarray]:
        """The state and covariance given that the person walks (the walking models' mixture): a moving
        person's velocity, not shrunk towards the standing model's zero by P(standing)."""
        return _mixture(self.means[WALKING], self.covs[WALKING], self.probs[WALKING])

    def walked_on(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The state and covariance of a person who kept walking since the last update: the walking models'
        mixture then, carried on at its velocity with steady walking's noise (the first of ``walk_accel_mps2``).
        Unlike :meth:`walking` it is not mixed with the standing model while nothing is seen (there, the walking
        models take in a restart from rest each step, and their mean falls behind a walker that walked on). None
        before any update."""
        if self._walk_seen is None:
            return None
        mean, cov = _mixture(*self._walk_seen)
        f, q = self._cv(self._since_update_s, self.cfg.walk_accel_mps2[0])
        return f @ mean, f @ cov @ f.T + q

    # ---------------------------------------------------------------- filter steps
    @staticmethod
    def _cv(dt: float, accel_mps2: float) -> tuple[np.ndarray, np.ndarray]:
        """Constant velocity over ``dt``: the transition and the white acceleration noise of ``accel_mps2``."""
        f = np.eye(4)
        f[0, 2] = f[1, 3] = dt
        g = np.array([[dt**4 / 4, 0, dt**3 / 2, 0], [0, dt**4 / 4, 0, dt**3 / 2],
                      [dt**3 / 2, 0, dt**2, 0], [0, dt**3 / 2, 0, dt**2]])
        return f, accel_mps2**2 * g

    def _models(self, dt: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
        c = self.cfg
        walks = [self._cv(dt, a) for a in c.walk_accel_mps2]
        f_stand = np.diag([1.0, 1.0, 0.0, 0.0])
        q_stand = np.diag([c.stand_sigma_mps**2 * dt] * 2 + [1e-6, 1e-6])
        return [f_stand] + [f for f, _ in walks], [q_stand] + [q for _, q in walks]

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
        fs, qs = self._models(dt)
        for j in range(n):
            means[j] = fs[j] @ means[j]
            covs[j] = fs[j] @ covs[j] @ fs[j].T + qs[j]
        self.means, self.covs, self.probs = means, covs, c
        self._mean = self._cov = None
        self._since_update_s += dt

    def innovation(self, z: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The combined prediction's innovation and its covariance for a position measurement."""
        return z - self.mean[:2], self.cov[:2, :2] + r

    def update(self, z: np.ndarray, r: np.ndarray) -> None:
        """Fold in a position measurement ``z`` (2,) with covariance ``r`` (2 x 2)."""
        like = np.empty(self.probs.size)
        for j in range(self.probs.size):
            s = self.covs[j][:2, :2] + r
            y = z - self.means[j][:2]
            k = self.covs[j][:, :2] @ np.linalg.inv(s)
            self.means[j] = self.means[j] + k @ y
            self.covs[j] = (np.eye(4) - k @ _H) @ self.covs[j]
            self.covs[j] = 0.5 * (self.covs[j] + self.covs[j].T)
            like[j] = math.exp(-0.5 * float(y @ np.linalg.solve(s, y))) / (2 * math.pi * math.sqrt(np.linalg.det(s)))
        self._mean = self._cov = None
        self.likelihoods, self.prior_probs = like, self.probs.copy()
        self._weigh(like)
        self._walk_seen = (self.means[WALKING].copy(), self.covs[WALKING].copy(), self.probs[WALKING].copy())
        self._since_update_s = 0.0

    def widen_position(self, var_m2: float) -> None:
        """Add ``var_m2`` to every model's position variance (an offset shared by the measurements folded in
        so far, which their number shrank out of the covariance: :meth:`vipsm.people.PeopleTracker._lone_offset`)."""
        for j in range(self.probs.size):
            self.covs[j][:2, :2] += np.eye(2) * var_m2
        self._mean = self._cov = None

    def weigh_walking(self, walking: float, standing: float) -> None:
        """Bayes' rule on the model probabilities for an observation other than the position, seen with
        likelihood ``walking`` under every walking model and ``standing`` under the standing model (a leg's
        step: :meth:`vipsm.people.PeopleTracker._update`). The states are unchanged."""
        like = np.full(self.probs.size, walking)
        like[STANDING] = standing
        self._weigh(like)

    def _weigh(self, like: np.ndarray) -> None:
        post = self.probs * like
        total = float(post.sum())
        if total > 0.0 and math.isfinite(total):
            self.probs = np.clip(post / total, 1e-6, 1.0 - 1e-6)
            self.probs /= self.probs.sum()
            self._mean = self._cov = None

