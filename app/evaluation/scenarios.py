"""Which scenarios an evaluation or a ``sim`` runs: the CLI flags, the paper's two, the suites."""

from __future__ import annotations

import argparse
from typing import Any

from hil_fakes.world import (
    PAPER_SCENARIOS,
    PARAMS,
    Scenario,
    ScenarioError,
    build_scenario,
    load_scenario_file,
    paper_params,
)
from hil_fakes.world.scenarios import REALISTIC_SUITE, check_robot_path, suite_params

from ..errors import AppError

# CLI flag -> scenario parameter (hil_fakes.world.scenarios.PARAMS)
SCENARIO_FLAGS: dict[str, str] = {
    "crossing_deg": "crossing_deg",
    "obstacle_speed": "obstacle_speed_mps",
    "obstacle_diameter": "obstacle_diameter_m",
    "obstacle_start": "obstacle_start_s",
    "robot_speed": "robot_speed_mps",
    "duration": "duration_s",
    "obstacles": "obstacles",
    "odom_noise": "odom_noise",
    "seed": "seed",
    "closest_approach": "closest_approach_m",
    "approach_time": "closest_approach_time_s",
}

# The robustness suite (``eval --scenario robustness``): the "beyond the two scenarios" cases,
# each a paper scenario with overrides; VIPSM should stay within ROBUSTNESS_FACTOR x the targets.
ROBUSTNESS_SUITE: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("crossing0", "2", {"crossing_deg": 0.0}),
    ("crossing30", "2", {"crossing_deg": 30.0}),
    ("crossing60", "2", {"crossing_deg": 60.0}),
    ("s2_speed0.5", "2", {"obstacle_speed_mps": 0.5}),
    ("s2_speed1.0", "2", {"obstacle_speed_mps": 1.0}),
    ("s1_speed1.0", "1", {"obstacle_speed_mps": 1.0}),
    ("s2_two_obstacles", "2", {"obstacles": 2}),
    ("s1_two_obstacles", "1", {"obstacles": 2}),
    ("s2_odom_noise3", "2", {"odom_noise": 3.0}),
    ("s1_odom_noise3", "1", {"odom_noise": 3.0}),
    ("s2_laser_noise3", "2", {"laser_noise_scale": 3.0}),
    ("s1_laser_noise3", "1", {"laser_noise_scale": 3.0}),
)


# ---------------------------------------------------------------------------------------- scenarios
def add_scenario_args(parser: argparse.ArgumentParser, *, with_duration: bool = True) -> None:
    """The custom-scenario flags shared by ``eval`` and the daemon's ``sim``."""
    g = parser.add_argument_group("scenario (override the chosen scenario's parameters)")
    for flag, key in SCENARIO_FLAGS.items():
        if flag == "duration" and not with_duration:
            continue
        spec = PARAMS[key]
        unit = f" ({spec.unit})" if spec.unit else ""
        g.add_argument(
            "--" + flag.replace("_", "-"),
            dest=flag,
            type=spec.kind,
            default=None,
            metavar="N" if spec.kind is int else "X",
            help=f"{spec.help}{unit}; default "
            + ("45 (scenario 1), 90 (scenario 2 and files)" if key == "crossing_deg" else f"{spec.default}"),
        )
    g.add_argument("--scenario-file", metavar="FILE.toml", default=None, help="scenario parameters from TOML")


def add_scenario_arguments(parser: argparse.ArgumentParser, *, allow_all: bool = True) -> None:
    """``--scenario`` (1, 2 and, with ``allow_all``, all) plus the custom-scenario flags and
    ``--scenario-file``: what ``eval`` and the daemon's ``sim`` accept. Turn the parsed arguments into
    scenarios with :func:`build_scenarios` (or :func:`build_scenario_from_args` for exactly one)."""
    choices = (["1", "2", "all", "robustness", "realistic"] if allow_all else ["1", "2"]) + list(REALISTIC_SUITE)
    parser.add_argument(
        "--scenario",
        choices=choices,
        default=None,
        metavar="NAME",
        help="the paper's scenario 1 (45 deg approach) or 2 (90 deg crossing)"
        + (
            ", all (both; the default), robustness (the suite of harder variants), realistic (the realistic suite)"
            if allow_all
            else " (default 1)"
        )
        + "; or one scenario of the realistic suite: "
        + ", ".join(REALISTIC_SUITE),
    )
    parser.add_argument(
        "--world",
        choices=["realistic", "ideal"],
        default="realistic",
        help="realistic (the default: the laser's artefacts, a real camera's optics and timing, odometry's "
        "systematic errors) or ideal (exact geometry, the first build's world; a regression check only)",
    )
    add_scenario_args(parser)


def build_scenario_from_args(args: argparse.Namespace, default: str = "1") -> Scenario:
    """The one scenario selected by ``--scenario`` / ``--scenario-file`` and the flags (for ``sim``)."""
    which = getattr(args, "scenario", None) or default
    if which in ("all", "robustness", "realistic"):
        raise AppError("this command runs one scenario: --scenario 1, 2 or a suite scenario's name")
    return build_scenarios(args, which)[0]


def scenario_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The scenario parameters given as flags (only those present)."""
    out: dict[str, Any] = {}
    for flag, key in SCENARIO_FLAGS.items():
        value = getattr(args, flag, None)
        if value is not None:
            out[key] = value
    return out


def scenario_param_sets(args: argparse.Namespace, which: str | None) -> list[dict[str, Any]]:
    """Parameter dicts for ``which`` ("1", "2", "all", "robustness" or None) with the file and the flags applied.

    ``--scenario-file`` replaces the paper scenarios (its name is the file's ``name`` or stem); flags
    override either. A paper scenario changed by flags gets ``_custom`` appended to its name.
    """
    overrides = scenario_overrides(args)
    world = {"world": getattr(args, "world", None) or "realistic"}
    path = getattr(args, "scenario_file", None)
    if path:
        return [{**world, **load_scenario_file(path), **overrides}]
    if which == "robustness":
        return [
            {**paper_params(base, extra), "name": label, **world, **overrides}
            for label, base, extra in ROBUSTNESS_SUITE
        ]
    if which == "realistic":
        return [suite_params(n, None, {**world, **overrides}) for n in REALISTIC_SUITE]
    if which in REALISTIC_SUITE:
        return [suite_params(which, None, {**world, **overrides})]
    names = list(PAPER_SCENARIOS) if which in (None, "all") else [which]
    sets = []
    for n in names:
        prm = paper_params(n, overrides)
        if overrides:
            prm["name"] = f"{prm['name']}_custom"
        sets.append({**prm, **world})
    return sets


def build_scenarios(args: argparse.Namespace, which: str | None) -> list[Scenario]:
    """Scenarios from the CLI; a bad parameter becomes an ``AppError`` naming the key."""
    try:
        return [build_scenario(p) for p in scenario_param_sets(args, which)]
    except ScenarioError as exc:
        raise AppError(str(exc)) from exc


def driven_scenarios(args: argparse.Namespace, which: str | None) -> list[Scenario]:
    """:func:`build_scenarios` for ``eval``, whose robot follows the scenario's own commands: a path
    that reaches a wall or the furniture is refused (``sim``'s robot follows the daemon's mission)."""
    scenarios = build_scenarios(args, which)
    try:
        for sc in scenarios:
            check_robot_path(sc)
    except ScenarioError as exc:
        raise AppError(str(exc)) from exc
    return scenarios
