"""Config: defaults round-trip through TOML, overrides, and one-line errors that name the key."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from app.config import Config, dump_toml, load_config, parse_override
from app.errors import ConfigError


def test_defaults_dump_and_load_back_exactly(tmp_path: Path) -> None:
    text = dump_toml(Config())
    path = tmp_path / "c.toml"
    path.write_text(text)
    assert load_config(path) == Config()
    assert "[loop]" in text and "period_s = 0.1" in text and "[estimator" in text


def test_file_and_overrides(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text(
        '[mission]\nmode = "cruise"\ncruise_speed_mps = 0.3\n[devices]\nscanner_url = "socket://127.0.0.1:10940"\n'
    )
    cfg = load_config(path, ["loop.period_s=0.05", "devices.camera_http_url=http://cam", "status.enabled=false"])
    assert cfg.mission.mode == "cruise" and cfg.mission.cruise_speed_mps == 0.3
    assert cfg.devices.scanner_url == "socket://127.0.0.1:10940"
    assert cfg.loop.period_s == 0.05 and cfg.devices.camera_http_url == "http://cam" and cfg.status.enabled is False


@pytest.mark.parametrize(
    ("override", "key", "words"),
    [
        ("loop.period_s=0", "loop.period_s", ">= 0.01"),
        ("loop.period_s=fast", "loop.period_s", "expected a number"),
        ("mission.mode=dance", "mission.mode", "one of"),
        ("status.port=70000", "status.port", "<= 65535"),
        ("status.enabled=1", "status.enabled", "true or false"),
        ("devices.robot_baud=1234", "devices.robot_baud", "one of"),
        ("loop.nope=1", "loop.nope", "unknown key"),
        ("nope=1", "nope", "unknown key"),
        ("loop=3", "loop", "expected a table"),
        ("log.queue_size=10000000000", "log.queue_size", "<= 65536"),
        ("estimator.tracker.accel_sigmas_mps2=[]", "estimator.tracker", "at least one positive"),
        ("estimator.tracker.mode_switch_per_s=-1", "estimator.tracker", "mode_switch_per_s must be >= 0"),
        ("estimator.bodies.max_gap_beams=-1", "estimator.bodies", "max_gap_beams >= 0"),
        ("estimator.bodies.max_leg_width_m=1.5", "estimator.bodies", "max_leg_width_m < max_body_width_m"),
        ("estimator.people.leg_pair_max_m=0.15", "estimator", "< people.leg_pair_max_m"),
        ("estimator.tracker.confirm_vacated_m=-1", "estimator.tracker", "confirm_vacated_m >= 0"),
        ("estimator.tracker.anisotropic_min_speed_mps=0", "estimator.tracker", "anisotropic_min_speed_mps > 0"),
        ("estimator.tracker.confirm_onset_step_m=0", "estimator.tracker", "confirm_onset_step_m > 0"),
        ("estimator.tracker.report_window=3", "estimator.tracker", "report_window >= 4"),
        ("estimator.people.stand_dwell_s=0", "estimator.people", "stand_dwell_s must be > 0"),
        pytest.param("devices.scanner_url=" + "x" * 100_000, "devices.scanner_url", "longer than 4096", id="long-url"),
    ],
)
def test_bad_values_name_their_key(override: str, key: str, words: str) -> None:
    with pytest.raises(ConfigError) as info:
        load_config(None, [override])
    assert info.value.key == key
    assert words in str(info.value) and f"'{key}'" in str(info.value)


@pytest.mark.parametrize("key", ["estimator.bodies.leg_radius_m", "estimator.bodies.camera_interval_max_m",
                                 "estimator.bodies.min_beams", "estimator.flow.fb_check",
                                 "estimator.flow.grid_step_px", "estimator.flow.fit_global",
                                 "estimator.flow.max_depth_m", "estimator.tracker.confirm_displacement_leg_m",
                                 "estimator.tracker.confirm_displacement_sustained_m",
                                 "estimator.tracker.report_recent", "estimator.tracker.meas_sigma_m",
                                 "estimator.tracker.default_radius_m", "estimator.tracker.min_radius_m",
                                 "estimator.tracker.max_radius_m", "estimator.tracker.min_fit_extent_rad",
                                 "estimator.tracker.radius_smoothing", "estimator.tracker.confirm_radius_tol",
                                 "estimator.tracker.confirm_occluded_radius_tol", "estimator.tracker.confirm_hits",
                                 "estimator.tracker.confirm_evidence", "estimator.tracker.confirm_onset_rows",
                                 "estimator.tracker.confirm_straightness", "estimator.tracker.confirm_advancing",
                                 "estimator.tracker.report_straightness", "estimator.tracker.kind_change_m",
                                 "estimator.tracker.merge_m"])
def test_a_removed_key_is_refused_as_removed_never_ignored(key: str) -> None:
    """A key an older version had (issue 29 removed or derived it): an old config file that sets it is refused
    with the key named and what replaced it, not read as if the value still applied."""
    with pytest.raises(ConfigError) as info:
        load_config(None, [f"{key}=1"])
    assert info.value.key == key and "was removed" in str(info.value) and "unknown key" not in str(info.value)


def test_an_old_config_file_with_a_removed_key_is_refused(tmp_path: Path) -> None:
    old = tmp_path / "old.toml"
    old.write_text("[estimator.bodies]\nseg_jump_m = 0.15\nperson_radius_m = 0.3\n")
    with pytest.raises(ConfigError, match="estimator.people.person_radius_m") as info:
        load_config(old)
    assert info.value.key == "estimator.bodies.person_radius_m"


def test_unreadable_files_are_config_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such file"):
        load_config(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[loop\nperiod_s = ")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(bad)


def test_override_values_are_toml_else_strings() -> None:
    assert parse_override("a.b=1.5") == (["a", "b"], 1.5)
    assert parse_override("a=true") == (["a"], True)
    assert parse_override("a=/dev/ttyACM0") == (["a"], "/dev/ttyACM0")
    with pytest.raises(ConfigError):
        parse_override("novalue")


def test_cli_prints_one_line_error_naming_the_key() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "app", "dump-config", "--set", "loop.period_s=-1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "loop.period_s" in lines[0]
