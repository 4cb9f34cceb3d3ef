"""tools/step_ab.py: two revisions' estimator steps timed side by side on identical inputs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _in_git() -> bool:
    proc = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, timeout=30)
    return proc.returncode == 0


needs_git = pytest.mark.skipif(not _in_git(), reason="step_ab exports a revision with git: not a git checkout")


@pytest.fixture(scope="module")
def tool(load_tool):
    return load_tool("step_ab")


@pytest.mark.parametrize("args", [["--scenes", "no_such_scene"], ["--duration", "0"], ["--scenes", ","]])
def test_bad_arguments_are_refused_before_anything_runs(tool, capsys, args) -> None:
    with pytest.raises(SystemExit) as exc:
        tool.main(["--base", "HEAD", *args])
    assert exc.value.code == 2 and "realistic suite" in capsys.readouterr().err


@needs_git
def test_a_duration_the_scenarios_refuse_is_a_clear_error(tool, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        tool.main(["--base", "HEAD", "--scenes", "door_swing", "--duration", "0.2"])
    assert exc.value.code == 2 and "duration_s" in capsys.readouterr().err


@needs_git
def test_a_revision_is_exported_as_its_own_package_with_its_leg_model(tool, tmp_path) -> None:
    base = tool.export_base("HEAD", tmp_path)
    assert base.name == "vipsm_base" and (base / "estimator.py").is_file()
    assert (base / "data" / "legs_model.npz").is_file() and not (tmp_path / "vipsm").exists()
    with pytest.raises(SystemExit, match="cannot export vipsm at 'no-such-revision'"):
        tool.export_base("no-such-revision", tmp_path / "other")


@needs_git
def test_both_estimators_are_timed_on_every_cycle_of_the_scenes() -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "step_ab.py"), "--base", "HEAD", "--scenes",
                           "door_swing,paper1", "--duration", "0.5", "--json"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout)
    assert set(out["scenes"]) == {"door_swing", "paper1"} and out["base"] == "HEAD"
    assert out["cycles"] == 2 * 5  # 0.5 s at 0.1 s: 6 cycles each, the first (no match yet) left out
    for key in ("base_ms_median", "new_ms_median", "base_ms_p99", "new_ms_p99", "paired_ratio_median"):
        assert out[key] > 0.0
    assert out["base_ms_median"] <= out["base_ms_p99"] and out["new_ms_median"] <= out["new_ms_p99"]
