"""The protective field (issue 32, "stop for what is in the path"): geometry on synthetic scans, the
mixed-pixel rule, the hold and resume, and the control loop's use of it on a simulated clock."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from app.config import Config
from app.daemon import ControlLoop, ScanSample
from app.protective_field import FieldParams, ProtectiveField, evaluate
from tests.app.loop_fakes import FakeBase, SimClock
from vipsm.estimator import Estimator
from vipsm.types import Scan

ROOT = Path(__file__).resolve().parents[2]
BEARINGS = np.linspace(-0.75 * math.pi, 0.75 * math.pi, 1081)  # the UTM-30LX's 0.25 deg beams
PARAMS = FieldParams(corridor_width_m=0.625, front_m=0.256, deceleration_mps2=0.3, latency_s=0.3, margin_m=0.2,
                     cluster_gap_m=0.1, min_returns=2)
AT_ORIGIN = (0.0, 0.0, 0.0)
V = 0.2  # field at 0.2 m/s: 0.256 + 0.067 + 0.06 + 0.2 = 0.583 m ahead of the origin


def cast(circles: list[tuple[float, float, float]] = (), wall_x_m: float = 3.0,
         origin: tuple[float, float, float] = AT_ORIGIN) -> np.ndarray:
    """Ranges from a laser at ``origin`` (robot frame) to a wall x = wall_x_m and circles (x, y, r)."""
    ox, oy, oth = origin
    c, s = np.cos(BEARINGS + oth), np.sin(BEARINGS + oth)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(c > 1e-9, (wall_x_m - ox) / c, np.inf)
    for cx, cy, rad in circles:
        dx, dy = cx - ox, cy - oy
        along = dx * c + dy * s
        perp2 = dx * dx + dy * dy - along * along
        hit = (along > 0) & (perp2 <= rad * rad)
        t = along - np.sqrt(np.maximum(rad * rad - perp2, 0.0))
        r = np.where(hit & (t < r), t, r)
    return np.where(np.isfinite(r) & (r <= 30.0), r, np.nan)


def legs(x_m: float, y_m: float) -> list[tuple[float, float, float]]:
    """A standing person: two 0.12 m legs 0.2 m apart, side by side across the path."""
    return [(x_m, y_m - 0.1, 0.06), (x_m, y_m + 0.1, 0.06)]


def beam_towards(x_m: float, y_m: float) -> int:
    return int(np.argmin(np.abs(BEARINGS - math.atan2(y_m, x_m))))


def test_stopping_distance_is_braking_plus_latency_plus_margin() -> None:
    assert PARAMS.stopping_distance_m(0.0) == pytest.approx(0.2)
    assert PARAMS.stopping_distance_m(0.2) == pytest.approx(0.04 / 0.6 + 0.06 + 0.2)
    assert PARAMS.length_m(1.0) == pytest.approx(0.256 + 1 / 0.6 + 0.3 + 0.2)


def test_a_wall_ahead_stops() -> None:
    res = evaluate(cast(wall_x_m=0.5), BEARINGS, AT_ORIGIN, PARAMS, V)
    assert res.intrusion and res.nearest_m == pytest.approx(0.5, abs=1e-6)
    assert not evaluate(cast(wall_x_m=0.7), BEARINGS, AT_ORIGIN, PARAMS, V).intrusion  # beyond the field


def test_a_standing_person_ahead_stops() -> None:
    res = evaluate(cast(legs(0.5, 0.0)), BEARINGS, AT_ORIGIN, PARAMS, V)
    assert res.intrusion and res.nearest_m == pytest.approx(0.44, abs=0.01)


def test_a_person_beside_the_corridor_does_not_stop() -> None:
    # legs from y = 0.34 to 0.66: the corridor ends at 0.3125
    res = evaluate(cast(legs(0.45, 0.5)), BEARINGS, AT_ORIGIN, PARAMS, V)
    assert not res.intrusion and res.unconfirmed == 0
    assert evaluate(cast(legs(0.45, 0.4)), BEARINGS, AT_ORIGIN, PARAMS, V).intrusion  # a leg in the corridor


def test_a_mixed_pixel_in_the_corridor_for_one_scan_does_not_stop() -> None:
    """One beam near a person beside the path returns a point floating in front of the far wall, inside the
    corridor (a mixed echo of the person's edge and the wall): an isolated return."""
    ranges = cast(legs(0.45, 0.5))
    i = beam_towards(0.45, 0.3)
    ranges[i] = math.hypot(0.45, 0.3)
    res = evaluate(ranges, BEARINGS, AT_ORIGIN, PARAMS, V)
    assert not res.intrusion and res.unconfirmed == 1
    field = ProtectiveField(PARAMS, AT_ORIGIN, resume_after_clear_s=1.0)
    assert field.update(0.0, ranges, BEARINGS, V, seq=1) is False
    # the rule is what keeps it from stopping: with min_returns = 1 the same return stops the robot
    single = dataclasses.replace(PARAMS, min_returns=1)
    assert evaluate(ranges, BEARINGS, AT_ORIGIN, single, V).intrusion


def test_the_field_grows_with_speed() -> None:
    ranges = cast(legs(1.2, 0.0))
    assert not evaluate(ranges, BEARINGS, AT_ORIGIN, PARAMS, 0.2).intrusion
    assert evaluate(ranges, BEARINGS, AT_ORIGIN, PARAMS, 1.0).intrusion


def test_the_laser_mount_is_applied() -> None:
    """A laser 0.2 m ahead of the origin, turned 90 deg to the left: a person beside the path is ahead of the
    laser's zero bearing, one ahead of the robot is on the laser's right."""
    mount = (0.2, 0.0, math.pi / 2)
    assert evaluate(cast(legs(0.5, 0.0), origin=mount), BEARINGS, mount, PARAMS, V).intrusion
    beside = cast(legs(0.45, 0.5), origin=mount)
    assert not evaluate(beside, BEARINGS, mount, PARAMS, V).intrusion
    assert evaluate(beside, BEARINGS, AT_ORIGIN, PARAMS, V).intrusion  # read without the mount: in the path


def test_motion_resumes_only_after_the_field_stayed_clear() -> None:
    field = ProtectiveField(PARAMS, AT_ORIGIN, resume_after_clear_s=1.0)
    blocked, clear = cast(legs(0.5, 0.0)), cast()
    assert field.update(0.0, blocked, BEARINGS, V, seq=1)
    assert field.update(0.5, clear, BEARINGS, V, seq=2)  # clear since 0.5 s
    assert field.update(1.0, blocked, BEARINGS, V, seq=3)  # back: the clock restarts
    assert field.update(1.5, clear, BEARINGS, V, seq=4)
    assert field.update(2.4, clear, BEARINGS, V, seq=5)
    assert not field.update(2.5, clear, BEARINGS, V, seq=6)
    assert field.intrusion_scans == 2


@settings(max_examples=200, deadline=None)
@given(beam=st.integers(0, 1080), frac=st.floats(0.05, 0.95))
def test_any_single_spurious_return_never_stops(beam: int, frac: float) -> None:
    ranges = cast(wall_x_m=2.0)
    true = ranges[beam] if math.isfinite(ranges[beam]) else 30.0
    ranges[beam] = 0.02 + frac * (true - 0.02)  # a short return anywhere between the minimum range and the truth
    assert not evaluate(ranges, BEARINGS, AT_ORIGIN, PARAMS, V).intrusion


@settings(max_examples=200, deadline=None)
@given(x=st.floats(0.1, 0.55), y=st.floats(-0.3, 0.3), radius=st.floats(0.01, 0.3))
def test_any_object_whose_centre_is_in_the_field_stops(x: float, y: float, radius: float) -> None:
    """From a 20 mm post to a 0.6 m drum: its centre in the corridor, its near side seen by adjacent beams."""
    assume(math.hypot(x, y) > radius + 0.03)  # in front of the laser, not around it
    assert evaluate(cast([(x, y, radius)], wall_x_m=3.0), BEARINGS, AT_ORIGIN, PARAMS, V).intrusion


# ---------------------------------------------------------------------------------------------
# the control loop: cruise stops for what is in the path, on a simulated clock


class _Scanner:
    """A fresh scan of ``ranges`` at every poll (the test sets what the laser sees)."""

    def __init__(self, clock: SimClock) -> None:
        self.clock, self.seq, self.ranges = clock, 0, cast()

    def state(self) -> str:
        return "ok"

    def poll(self) -> list[ScanSample]:
        self.seq += 1
        return [ScanSample(Scan(self.ranges.copy(), BEARINGS, self.clock.now_s - 0.02, seq=self.seq))]

    def wait_scan(self, timeout_s: float) -> bool:
        return True

    def counters(self) -> dict[str, int]:
        return {}

    def close(self) -> None:
        pass


def _loop(mode: str = "cruise", **safety: object) -> tuple[ControlLoop, SimClock, _Scanner, FakeBase]:
    clock = SimClock()
    c = Config()
    config = dataclasses.replace(c, mission=dataclasses.replace(c.mission, mode=mode, resume_after_clear_s=1.0),
                                 safety=dataclasses.replace(c.safety, **safety),
                                 status=dataclasses.replace(c.status, enabled=False))
    scanner, base = _Scanner(clock), FakeBase(clock, moving=True)
    loop = ControlLoop(config, scanner=scanner, base=base, camera=None, estimator=Estimator(plain_psm=True),
                       clock=clock, wall_clock=lambda: 1.7e9)
    return loop, clock, scanner, base


def _run(loop: ControlLoop, clock: SimClock, seconds: float) -> None:
    for _ in range(round(seconds / 0.1)):
        clock.now_s += 0.1
        loop.step(clock.now_s)


def test_cruise_stops_for_a_standing_person_and_resumes_when_clear(capsys: pytest.CaptureFixture[str]) -> None:
    loop, clock, scanner, base = _loop()
    _run(loop, clock, 0.5)
    assert loop.mission_state == "moving" and base.commands[-1] == (0.2, 0.0)
    scanner.ranges = cast(legs(0.5, 0.0))
    _run(loop, clock, 0.1)
    assert loop.mission_state == "protective_stop" and base.commands[-1] == (0.0, 0.0)
    _run(loop, clock, 2.0)
    scanner.ranges = cast()  # the person walks away
    _run(loop, clock, 0.9)
    assert loop.mission_state == "protective_stop"  # not yet clear for 1 s
    _run(loop, clock, 0.3)
    assert loop.mission_state == "moving" and base.commands[-1] == (0.2, 0.0)
    summary = loop.safety_summary()
    assert summary["protective_stops"] == 1 and 30 <= summary["protective_stop_cycles"] <= 33
    err = capsys.readouterr().err
    assert "protective field: object 0.44 m ahead" in err and "mission: moving -> protective_stop" in err
    assert "protective field: clear for 1 s" in err and err.count("protective field:") == 2  # once per change
    # a stop for something in the path is the mission doing its job, not a fault: no warning line
    assert "info: mission: moving -> protective_stop" in err and "warning" not in err


def test_cruise_stops_for_a_wall_and_a_mixed_pixel_does_not_stop_it() -> None:
    loop, clock, scanner, base = _loop()
    ranges = cast(legs(0.45, 0.5))
    ranges[beam_towards(0.45, 0.3)] = math.hypot(0.45, 0.3)
    scanner.ranges = ranges
    _run(loop, clock, 0.1)
    scanner.ranges = cast(legs(0.45, 0.5))
    _run(loop, clock, 0.5)
    assert loop.stats.protective_stop_cycles == 0 and loop.mission_state == "moving"
    assert loop.safety_summary()["protective_unconfirmed_returns"] == 1
    scanner.ranges = cast(wall_x_m=0.5)
    _run(loop, clock, 0.1)
    assert loop.mission_state == "protective_stop"


def test_the_field_is_reported_in_the_status_flags_and_registers() -> None:
    from app.status import STATUS_BITS, encode_registers

    loop, clock, scanner, _ = _loop()
    published = []
    loop.status = type("S", (), {"publish": published.append, "stop_requested": False, "stop": lambda self: None})()
    scanner.ranges = cast(legs(0.5, 0.0))
    _run(loop, clock, 0.1)
    regs = encode_registers(published[-1])
    assert regs[0] & (1 << STATUS_BITS["protective_stop"]) and regs[1] == 5
    assert regs[52] == pytest.approx(583, abs=1) and regs[53] == pytest.approx(440, abs=10)


def test_a_live_view_that_cannot_accept_viewers_sets_its_status_bit() -> None:
    from app.status import STATUS_BITS, encode_registers

    loop, clock, _, _ = _loop()
    published = []
    loop.status = type("S", (), {"publish": published.append, "stop_requested": False, "stop": lambda self: None})()
    loop.live_view = type("L", (), {"state": "ok", "stop": lambda self: None})()
    _run(loop, clock, 0.1)
    assert not encode_registers(published[-1])[0] & (1 << STATUS_BITS["live_view_error"])
    loop.live_view.state = "degraded"  # e.g. out of file descriptors: accepting fails, retried every second
    _run(loop, clock, 0.1)
    assert encode_registers(published[-1])[0] & (1 << STATUS_BITS["live_view_error"])


def test_hold_and_a_disabled_field_never_stop_for_the_field() -> None:
    loop, clock, scanner, _ = _loop(mode="hold")
    scanner.ranges = cast(wall_x_m=0.4)
    _run(loop, clock, 0.3)
    assert loop.mission_state == "hold" and loop.stats.protective_stop_cycles == 0
    loop, clock, scanner, base = _loop(field_enabled=False)
    scanner.ranges = cast(wall_x_m=0.4)
    _run(loop, clock, 0.3)
    assert loop.mission_state == "moving" and base.commands[-1] == (0.2, 0.0)


# ---------------------------------------------------------------------------------------------
# sim: the daemon, the byte-level fakes and the world; a box on the robot's path in cruise


def test_sim_cruise_stops_before_a_box_in_its_path(tmp_path: Path) -> None:
    """The robot starts at x = 0.6 m and cruises at 0.2 m/s; a 0.5 m box stands at x = 1.9 m (its near face
    at 1.65 m). The robot's front (0.256 m ahead of its origin) must stop short of the face, and stay."""
    from app.logread import read_log

    scenario = tmp_path / "box.toml"
    scenario.write_text('name = "box_in_path"\nobstacles = 0\nbox_in_path_x_m = 1.9\nduration_s = 8.0\n')
    log = tmp_path / "box.mcap"
    proc = subprocess.run(
        [sys.executable, "-m", "app", "sim", "--scenario-file", str(scenario), "--json", "--no-progress",
         "--log", str(log), "--set", "status.port=0"],
        cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True, timeout=120,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = json.loads(proc.stdout)
    assert summary["protective_stops"] >= 1 and summary["protective_stop_cycles"] > 0
    assert any(e.startswith("protective field: object") for e in summary["events"])
    robot_x = [m.data["robot"][0] for m in read_log(log) if m.topic == "/truth"]
    assert robot_x and max(robot_x) + 0.256 < 1.9 - 0.25  # never touched the box
    assert max(robot_x) > 0.9  # it did drive towards it
    assert summary["scenario"]["params"]["box_in_path_x_m"] == 1.9


def test_the_box_in_path_parameter_adds_only_the_box() -> None:
    from hil_fakes.world.scenarios import ScenarioError, build_scenario, paper_scenario

    plain = paper_scenario("1")
    with_box = build_scenario({**plain.params, "box_in_path_x_m": 2.5})
    assert with_box.walls[: len(plain.walls)] == plain.walls and len(with_box.walls) == len(plain.walls) + 4
    assert with_box.static_footprints() == [(2.5, 0.0, pytest.approx(0.3536, abs=1e-4), "box")]
    assert with_box.obstacles == plain.obstacles and plain.static_footprints() == []
    with pytest.raises(ScenarioError, match="box_in_path_x_m"):
        build_scenario({"box_in_path_x_m": 1.0})  # on the robot at its start
