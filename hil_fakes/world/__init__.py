"""The simulated world behind the fakes and the evaluation (see docs/simulation.md)."""

from __future__ import annotations

from .geometry import ObstaclePath, Wall
from .scenarios import (
    PAPER_SCENARIOS,
    PARAMS,
    Scenario,
    ScenarioError,
    build_scenario,
    load_scenario_file,
    paper_params,
    paper_scenario,
    validate_params,
)
from .sensors import CameraModel, LaserModel, RobotMount, intrinsics
from .world import LaserSweep, ObstacleTruth, Truth, World, WorldTimeError

__all__ = [
    "PAPER_SCENARIOS",
    "PARAMS",
    "CameraModel",
    "LaserModel",
    "LaserSweep",
    "ObstaclePath",
    "ObstacleTruth",
    "RobotMount",
    "Scenario",
    "ScenarioError",
    "Truth",
    "Wall",
    "World",
    "WorldTimeError",
    "build_scenario",
    "intrinsics",
    "load_scenario_file",
    "paper_params",
    "paper_scenario",
    "validate_params",
]
