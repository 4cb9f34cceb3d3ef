"""``sim``'s terminal summary says when the simulated world itself fell behind real time."""

from __future__ import annotations

from app.sim import summary_lines


def _summary(scans_late: int) -> dict:
    return {"scans": 400, "odometry_samples": 120, "frames_used": 100, "devices": {"a": {}, "b": {}, "c": {}},
            "log_path": None, "headline": {},
            "fakes": {"scanner": {"scans_sent": 420, "scans_late": scans_late}}}


def test_a_starved_world_is_named_in_the_summary_and_a_punctual_one_is_not() -> None:
    warned = [ln for ln in summary_lines(_summary(120)) if ln.startswith("warning:")]
    assert warned == ["warning: the simulated world fell behind real time (this machine was too busy): 120 of 540 "
                      "scans late or skipped; the figures are of a starved run"]
    assert not [ln for ln in summary_lines(_summary(0)) if ln.startswith("warning:")]
    assert not [ln for ln in summary_lines({**_summary(0), "fakes": {}}) if ln.startswith("warning:")]
