"""The keyframe policy: when the reference scan is replaced."""

from __future__ import annotations

import numpy as np

from vipsm.estimator import EstimatorConfig
from vipsm.keyframes import KeyframeMatcher
from vipsm.psm import prepare_scan
from vipsm.types import Pose2D

from .sim import box_room


def _replacements(cfg: EstimatorConfig, cycles: int = 12) -> list[bool]:
    """Drive 2 cm per cycle through a static room; whether each match replaced the keyframe."""
    world = box_room(9.0, 6.0, x0=-1.0, y0=-3.0)
    rng = np.random.default_rng(3)
    matcher = KeyframeMatcher(cfg)
    last = None
    out = []
    for k in range(cycles):
        truth = Pose2D(0.02 * k, 0.0, 0.0)
        scan = world.scan(truth, noise_m=0.01, rng=rng)
        cur = prepare_scan(scan.ranges_m, scan.bearings_rad, cfg.psm)
        n = int(np.count_nonzero(cur.good))
        guess = Pose2D(truth.x_m * 1.02, 0.0, 0.0)  # the odometry 2 % long
        res = matcher.match(cur, n, guess, last, np.zeros((3, 3)), True, False)
        last = res.pose
        if k:
            out.append(res.keyframe_replaced)
    return out


def test_a_converged_match_keeps_the_keyframe_until_keyframe_dist_m() -> None:
    assert not any(_replacements(EstimatorConfig()))  # 0.22 m < keyframe_dist_m

