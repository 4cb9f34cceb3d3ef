"""tools/velocity_bound.py: the velocity error causal filters reach on a scene's true walking paths."""

from __future__ import annotations

import json

import numpy as np
import pytest


@pytest.fixture(scope="module")
def tool(load_tool):
    return load_tool("velocity_bound")


def _start(n: int = 60, accel_mps2: float = 1.8, top_mps: float = 1.1,
           start: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """A person standing for ``start`` cycles, then walking along x: speed up at ``accel_mps2`` to ``top_mps``."""
    t = np.arange(n) * 0.1
    v = np.clip((t - start * 0.1) * accel_mps2, 0.0, top_mps)
    x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * 0.1)])
    return np.stack([x, np.zeros(n)], 1), np.stack([v, np.zeros(n)], 1)


def test_filters_follow_a_steady_walk_and_lag_a_start(tool) -> None:
    pos, vel = _start()
    z = pos + np.random.default_rng(3).normal(0.0, 0.01, pos.shape)
    for est in (tool.imm_velocities(z, 0.01), tool.cv_velocities(z, 1.0, 0.01)):
        err = np.hypot(*(est - vel).T)
        assert err[50:].mean() < 0.1  # walking steadily: the filter has the speed
        assert err[20:26].mean() > 2.0 * err[50:].mean()  # the first half second of the start: it lags
    standing = tool.imm_velocities(pos[:20] + np.random.default_rng(4).normal(0.0, 0.01, (20, 2)), 0.01)
    assert np.hypot(*standing.T).max() < 0.2


def test_more_noise_more_error_and_the_run_is_reproducible(tool, capsys) -> None:
    assert tool.main(["--scenario", "stop_and_go", "--repeats", "2", "--noise-m", "0.01,0.06", "--json"]) == 0
    first = json.loads(capsys.readouterr().out)
    (person,) = first["persons"]
    assert person["scored_cycles"] > 20
    low, high = person["bounds"]
    assert (low["noise_m"], high["noise_m"]) == (0.01, 0.06)
    assert 0.0 < low["imm_mps"] < high["imm_mps"] and 0.0 < low["cv_best_mps"] < high["cv_best_mps"]
    assert low["cv_best_accel_mps2"] in tool.CV_ACCEL_MPS2
    assert tool.main(["--scenario", "stop_and_go", "--repeats", "2", "--noise-m", "0.01,0.06", "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == first
    assert tool.main(["--scenario", "stop_and_go", "--repeats", "1", "--noise-m", "0.02"]) == 0
    assert "stop_and_go person 0" in capsys.readouterr().out


@pytest.mark.parametrize(("args", "said"), [
    (["--scenario", "bogus"], "--scenario must be one of"),
    (["--scenario", "paper1"], "has no person"),
    (["--scenario", "stop_and_go", "--noise-m", "x"], "--noise-m"),
    (["--scenario", "stop_and_go", "--noise-m", "0.02,-1"], "--noise-m"),
    (["--scenario", "stop_and_go", "--noise-m", "nan"], "--noise-m"),
    (["--scenario", "stop_and_go", "--repeats", "0"], "--repeats"),
])
def test_bad_arguments_are_refused(tool, capsys, args: list[str], said: str) -> None:
    assert tool.main(args) == 2
    assert said in capsys.readouterr().err
