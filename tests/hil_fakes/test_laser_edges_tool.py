"""tools/laser_edges.py: depth edges of recorded scans and of the world's sweeps, measured alike."""

from __future__ import annotations

import json
from pathlib import Path

import pytest


@pytest.fixture(scope="module")
def tool(load_tool):
    return load_tool("laser_edges")


def test_bad_arguments_are_refused(tool, capsys, tmp_path: Path) -> None:
    assert tool.main(["--only", "utm30lx_diosi,bogus", "--data-dir", str(tmp_path)]) == 2
    assert "bogus" in capsys.readouterr().err
    assert tool.main(["--step", "0", "--data-dir", str(tmp_path)]) == 2
    assert "--step" in capsys.readouterr().err
    assert tool.main(["--data-dir", str(tmp_path / "nowhere")]) == 2
    assert "no shared data folder" in capsys.readouterr().err


def test_a_source_without_its_data_is_reported_absent(tool, capsys, tmp_path: Path) -> None:
    assert tool.main(["--only", "utm30lx_frame,utm30lx_diosi,leg_tracker_drive", "--data-dir", str(tmp_path),
                      "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert all(report[s] == {"absent": True} for s in ("utm30lx_frame", "utm30lx_diosi", "leg_tracker_drive"))


def test_the_recorded_utm30lx_and_the_world(tool, capsys, shared_data: Path) -> None:
    assert tool.main(["--only", "utm30lx_frame,utm30lx_diosi,world_utm30lx", "--step", "5", "--fine",
                      "--data-dir", str(shared_data), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    frame, diosi, world = report["utm30lx_frame"], report["utm30lx_diosi"], report["world_utm30lx"]
    assert frame["scans"] == 1 and diosi["scans"] == 25
    assert sum(v["edges"] for v in diosi["by_gap"].values()) == 678
    assert diosi["by_gap"]["1-1.5m"]["mixed"] == pytest.approx(0.2, abs=0.01)
    assert world["scans"] > 20 and set(world["by_range"]) == {"0-2m", "2-4m", "4-8m", ">8m"}
    for fig in world["by_gap"].values():  # the shares of a bin add up to one
        assert fig["edges"] == 0 or sum(fig[k] for k in report["kinds"]) == pytest.approx(1.0, abs=0.01)
    assert tool.main(["--only", "utm30lx_diosi", "--data-dir", str(shared_data)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("| source | bin | edges | mixed |") and "| utm30lx_diosi (25 scans) | gap >1m | 383 |" in out
