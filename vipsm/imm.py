"""An interacting multiple model (IMM) filter of a person's position and velocity: standing or walking.

Two motion models on the state (x, y, vx, vy), world frame, SI units:

* **standing**: the velocity is zero (the model resets it each step); the position wanders by
  ``stand_sigma_mps`` per square root of a second (a standing person's leg-pair midpoint shuffles with
  the weight shifting from foot to foot);
* **walking**: constant velocity with white acceleration noise ``walk_accel_mps2`` (a walker's speed
  and heading change within about a second: starting, stopping, turning).

The models switch with rate ``switch_per_s`` (a Markov chain: the probability of a switch in one
step of ``dt`` is ``1 - exp(-rate dt)``). The walking model's probability is P(moving); the combined
state gives position, velocity and covariance. Standard IMM (Blom and Bar-Shalom): mixing, per-model
Kalman prediction and update, model probabilities from the measurement likelihoods.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

STANDING, WALKING = 0, 1


@dataclass(frozen=True)
class ImmConfig:
    stand_sigma_mps: float = 0.05
    walk_accel_mps2: float = 1.5
    switch_per_s: float = 0.5
    #: speed uncertainty of a new track (a walker: up to ~1.5 m/s)
    init_speed_sigma_mps: float = 0.8
    #: P(moving) of a new track
    init_p_moving: float = 0.2

    def __post_init__(self) -> None:
        if min(self.stand_sigma_mps, self.walk_accel_mps2, self.switch_per_s, self.init_speed_sigma_mps) <= 0.0:
            raise ValueError("the IMM's noise, switch rate and initial speed sigma must be positive")
        if not 0.0 < self.init_p_moving < 1.0:
            raise ValueError(f"init_p_moving must be in (0, 1), got {self.init_p_moving}")


_H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


class Imm:
    """One track's IMM state: per-model means (2 x 4) and covariances (2 x 4 x 4), model probabilities."""

    def __init__(self, x_m: float, y_m: float, pos_sigma_m: float, cfg: ImmConfig) -> None:
        self.cfg = cfg
        p = np.diag([pos_sigma_m**2, pos_sigma_m**2, cfg.init_speed_sigma_mps**2, cfg.init_speed_sigma_mps**2])
        self.means = np.tile(np.array([x_m, y_m, 0.0, 0.0]), (2, 1))
        self.means[STANDING, 2:] = 0.0
        p_stand = p.copy()
        p_stand[2:, 2:] = np.eye(2) * 1e-6
        self.covs = np.stack([p_stand, p])
        self.probs = np.array([1.0 - cfg.init_p_moving, cfg.init_p_moving])

    # ---------------------------------------------------------------- combined estimate
    @property
    def p_moving(self) -> float:
        return float(self.probs[WALKING])

    @property
    def mean(self) -> np.ndarray:
        return self.probs @ self.means

    @property
    def cov(self) -> np.ndarray:
        m = self.mean
        d = self.means - m
        return np.einsum("i,ijk->jk", self.probs, self.covs + np.einsum("ij,ik->ijk", d, d))

    # ---------------------------------------------------------------- filter steps
    def _models(self, dt: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
        c = self.cfg
        f_walk = np.eye(4)
        f_walk[0, 2] = f_walk[1, 3] = dt
        f_stand = np.diag([1.0, 1.0, 0.0, 0.0])
        q = c.walk_accel_mps2**2
        q_walk = q * np.array([[dt**4 / 4, 0, dt**3 / 2, 0], [0, dt**4 / 4, 0, dt**3 / 2],
                               [dt**3 / 2, 0, dt**2, 0], [0, dt**3 / 2, 0, dt**2]])
        q_stand = np.diag([c.stand_sigma_mps**2 * dt] * 2 + [1e-6, 1e-6])
        return [f_stand, f_walk], [q_stand, q_walk]

    def predict(self, dt: float) -> None:
        """Mix the models and predict each ``dt`` seconds ahead."""
        if dt <= 0.0:
            return
        stay = math.exp(-self.cfg.switch_per_s * dt)
        trans = np.array([[stay, 1.0 - stay], [1.0 - stay, stay]])
        c = trans.T @ self.probs  # predicted model probabilities
        mix = trans * self.probs[:, None] / np.maximum(c[None, :], 1e-300)  # mix[i, j] = P(i | j)
        means = mix.T @ self.means
        covs = np.empty_like(self.covs)
        for j in range(2):
            d = self.means - means[j]
            covs[j] = np.einsum("i,ijk->jk", mix[:, j], self.covs + np.einsum("ij,ik->ijk", d, d))
        fs, qs = self._models(dt)
        for j in range(2):
            means[j] = fs[j] @ means[j]
            covs[j] = fs[j] @ covs[j] @ fs[j].T + qs[j]
        self.means, self.covs, self.probs = means, covs, c

    def innovation(self, z: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The combined prediction's innovation and its covariance for a position measurement."""
        return z - self.mean[:2], self.cov[:2, :2] + r

    def update(self, z: np.ndarray, r: np.ndarray) -> None:
        """Fold in a position measurement ``z`` (2,) with covariance ``r`` (2 x 2)."""
        like = np.empty(2)
        for j in range(2):
            s = self.covs[j][:2, :2] + r
            y = z - self.means[j][:2]
            k = self.covs[j][:, :2] @ np.linalg.inv(s)
            self.means[j] = self.means[j] + k @ y
            self.covs[j] = (np.eye(4) - k @ _H) @ self.covs[j]
            self.covs[j] = 0.5 * (self.covs[j] + self.covs[j].T)
            like[j] = math.exp(-0.5 * float(y @ np.linalg.solve(s, y))) / (2 * math.pi * math.sqrt(np.linalg.det(s)))
        post = self.probs * like
        total = float(post.sum())
        if total > 0.0 and math.isfinite(total):
            self.probs = np.clip(post / total, 1e-6, 1.0 - 1e-6)
            self.probs /= self.probs.sum()
