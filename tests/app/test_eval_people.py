"""Issue 29's per-person metrics (app/evaluation/person_metrics.py) on constructed runs."""

from __future__ import annotations

from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from app.evaluation import metrics
from app.evaluation.person_metrics import PERSON_BEAMS_IN_VIEW, PeopleScore, summary
from hil_fakes.world import ObstaclePath, ObstacleTruth, Truth
from hil_fakes.world.geometry import Gait, Wall
from hil_fakes.world.scenes import walk_profile

GAIT = Gait()


def _walker(y_m: float = 0.0) -> ObstaclePath:
    """Walks 1 m/s along x from t = 1 s, stops at 2 m for 2 s (3-5 s), walks on."""
    knots = walk_profile(10.0, 1.0, 1.0, 0.0, stop_at_m=2.0, stop_duration_s=2.0)
    return ObstaclePath(0.25, ((0.0, y_m), (10.0, y_m)), 1.0, 1.0, gait=GAIT, profile=knots)


def _truth(t: float, paths: list[ObstaclePath]) -> Truth:
    obs = []
    for i, p in enumerate(paths):
        (x, y), (vx, vy) = p.positions(t), p.velocities(t)
        obs.append(ObstacleTruth(i, float(x), float(y), float(vx), float(vy), 0.25, bool(vx or vy), "person"))
    return Truth(t, 0.0, 0.0, 0.0, 0.0, 0.0, tuple(obs))


def _obstacle(x: float, y: float, vx: float = 1.0, age: int = 20) -> Any:
    return SimpleNamespace(x_m=x, y_m=y, vx_mps=vx, vy_mps=0.0, age_cycles=age)


def _person(x: float, y: float, moving: bool, track_id: int = 1) -> Any:
    return SimpleNamespace(x_m=x, y_m=y, moving=moving, track_id=track_id)


def _run(paths: list[ObstaclePath], report: Callable[[float, Truth], tuple[list[Any], list[Any]]],
         view: Callable[[float], bool] = lambda t: True, until_s: float = 7.0, walls: tuple[Wall, ...] = ()
         ) -> list[dict[str, Any]]:
    score = PeopleScore(SimpleNamespace(obstacles=tuple(paths), walls=walls))
    for t in np.round(np.arange(0.0, until_s, 0.1), 3):
        truth = _truth(float(t), paths)
        obstacles, people = report(float(t), truth)
        hits = np.full(len(paths), PERSON_BEAMS_IN_VIEW if view(float(t)) else PERSON_BEAMS_IN_VIEW - 1)
        score.update(float(t), SimpleNamespace(obstacles=obstacles, people=people), truth, hits)
    return score.results()


def test_first_report_per_walk_start_and_moving_while_standing() -> None:
    def report(t: float, truth: Truth) -> tuple[list[Any], list[Any]]:
        o = truth.obstacles[0]
        walking_seen = (1.3 <= t < 3.0) or (5.2 <= t) or (3.0 <= t < 3.45) or (3.75 <= t < 3.85)
        obstacles = [_obstacle(o.x_m + 0.05, o.y_m, vx=1.1)] if walking_seen else []
        return obstacles, [_person(o.x_m, o.y_m + 0.02, walking_seen)]

    (p,) = _run([_walker()], report)
    assert p["first_report_s"] == [pytest.approx(0.3), pytest.approx(0.2)]  # from each start at 1 s and 5 s
    assert p["moving_while_standing_cycles"] == 1  # 3.0-3.5 s is within 0.5 s of the stop; 3.8 s is not
    assert p["located_fraction"] == 1.0 and p["err_mean_m"] == pytest.approx(0.02)
    assert p["moving_err_mean_m"] == pytest.approx(0.05)
    assert p["velocity_err_mean_mps"] == pytest.approx(0.1)
    walking = 19 + 20  # 1.1-2.9 s and 5.0-6.9 s (speed > 0 at the cycle's instant)
    assert p["cycles_walking_in_view"] == walking
    assert p["located_moving_fraction"] == pytest.approx((17 + 18) / walking, abs=1e-4)


def test_id_switches_count_changes_of_the_located_people_entry() -> None:
    """The walker's entry is track 1 while it stands, then track 2 from its walk (one switch); an entry
    too far to locate it (> 0.5 m) and cycles with none are no switch; track 2 found again after them is
    the same id."""
    def report(t: float, truth: Truth) -> tuple[list[Any], list[Any]]:
        o = truth.obstacles[0]
        if 2.0 <= t < 2.5:
            return [], []
        if 2.5 <= t < 3.0:
            return [], [_person(o.x_m + 0.8, o.y_m, False, track_id=7)]
        return [], [_person(o.x_m, o.y_m, o.moving, track_id=1 if t < 1.5 else 2)]

    (p,) = _run([_walker()], report, until_s=5.0)
    assert p["id_switches"] == 1
    assert summary([p, {**p, "id_switches": 2}])["person_id_switches"] == 3


def test_a_walker_coming_into_view_is_timed_from_its_first_cycle_in_view() -> None:
    def report(t: float, truth: Truth) -> tuple[list[Any], list[Any]]:
        o = truth.obstacles[0]
        return ([_obstacle(o.x_m, o.y_m)] if t >= 2.2 and o.moving else []), []

    (p,) = _run([_walker()], report, view=lambda t: t >= 1.95, until_s=3.0)
    assert p["first_report_s"] == [pytest.approx(0.2)]  # in view from 2.0 s, reported at 2.2 s
    assert p["cycles_in_view"] == 10 and p["located_fraction"] == 0.0  # no people entries at all


def test_a_walker_whose_body_overlaps_a_wall_is_not_in_view() -> None:
    """The crowd's walkers pass through walls drawn unbroken (doorways the world does not model): while the
    body's centre is nearer to a wall than its radius (0.25 m) the cycle is not scored."""
    def report(t: float, truth: Truth) -> tuple[list[Any], list[Any]]:
        return [], []

    wall = Wall(1.5, -2.0, 1.5, 2.0)  # across the walk
    (free,) = _run([_walker()], report, until_s=3.0)
    (walled,) = _run([_walker()], report, until_s=3.0, walls=(wall,))
    # x = t - 1 from 1 s: 1.25 < x < 1.75 at t = 2.3 ... 2.7 s (5 cycles); before 1 s it stands at 0
    assert free["cycles_in_view"] - walled["cycles_in_view"] == 5


def test_one_report_cannot_locate_two_people_side_by_side() -> None:
    paths = [_walker(0.0), _walker(0.4)]

    def report(t: float, truth: Truth) -> tuple[list[Any], list[Any]]:
        a, b = truth.obstacles
        mid = (0.5 * (a.x_m + b.x_m), 0.5 * (a.y_m + b.y_m))
        return [_obstacle(*mid)], [_person(*mid, True)]

    a, b = _run(paths, report, until_s=3.0)
    assert a["located_moving_fraction"] + b["located_moving_fraction"] == pytest.approx(1.0)
    assert a["located_fraction"] + b["located_fraction"] == pytest.approx(1.0)
    worst = summary([a, b])
    assert worst["person_located_moving_min"] == 0.0 and worst["first_reports_missing"] == 1
    assert worst["first_report_max_s"] is None  # a walk never reported is a miss, not a zero


def test_issue29_targets_apply_to_its_scenes_only() -> None:
    hard = metrics.targets_for({"world": "realistic", "targets": "issue29", "obstacle_kind": "person",
                                "scene": "crossing", "obstacles": 1})
    assert hard["first_report_max_s"] == (0.3, "max") and hard["person_located_min"] == (0.9, "min")
    assert "pose_err_final_m" not in hard
    door = metrics.targets_for({"world": "realistic", "targets": "issue29", "scene": "door", "obstacles": 0})
    assert set(door) == {"false_tracks_per_min", "false_stop_cycles"}
    old = metrics.targets_for({"world": "realistic", "obstacle_kind": "person", "obstacles": 1})
    assert "first_report_max_s" not in old and old["obstacle_detected_fraction"] == (0.95, "min")


def test_the_table_lists_every_person_of_issue29_scenes(capsys: pytest.CaptureFixture[str]) -> None:
    from app.evaluation.report import print_people_table

    person = {"index": 3, "cycles_in_view": 40, "cycles_walking_in_view": 30, "located_fraction": 0.5,
              "located_moving_fraction": 0.75, "err_mean_m": 0.05, "moving_err_mean_m": 0.04,
              "velocity_err_mean_mps": 0.2, "first_report_s": [0.4, None], "moving_while_standing_cycles": 2,
              "id_switches": 1}
    results = [{"name": "stop_and_go", "params": {"targets": "issue29"}, "vipsm": {"people": [person]}},
               {"name": "cross_90", "params": {"targets": "issue11"}, "vipsm": {"people": [person]}}]
    print_people_table(results)
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith(("stop_and_go", "cross_90"))]
    assert len(rows) == 1 and "50.0%" in rows[0] and "75.0%" in rows[0] and rows[0].endswith("0.4, never")
