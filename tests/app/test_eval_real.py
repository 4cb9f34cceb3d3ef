"""The real-data suite (``eval --data real``): its metrics on made-up runs whose answers are known, and the
suite itself on one small shared recording (skipped without the data)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from app.evaluation.real_data import (
    RECORDINGS,
    ROBOT_REACH_M,
    Cycle,
    Run,
    background_metrics,
    end_to_start_m,
    labelled_metrics,
    path_comparison,
    person_centre,
    person_speeds,
    place_change_m,
    refusal_metrics,
    speed_class,
)


def _labels(speed_mps: float, n: int = 20, period_s: float = 0.1) -> list[tuple[float, np.ndarray]]:
    """Two legs 0.2 m apart moving along x at ``speed_mps``; every other scan only one leg labelled."""
    out = []
    for i in range(n):
        x = 2.0 + speed_mps * i * period_s
        legs = np.array([[x, 0.1], [x, -0.1]]) if i % 2 == 0 else np.array([[x, 0.1]])
        out.append((100.0 + i * period_s, legs))
    return out


def test_speed_from_the_legs_centroid_fit() -> None:
    walking = person_speeds(_labels(0.8))
    assert walking[10] == pytest.approx(0.8, abs=0.15)
    assert [speed_class(v) for v in (walking[10], person_speeds(_labels(0.2))[10], person_speeds(_labels(0.0))[10])] \
        == ["walking", "slow", "standing"]
    assert person_speeds(_labels(0.5, n=2))[0] is None  # two scans do not give a speed


def test_labelled_metrics_recall_error_and_far_reports() -> None:
    labels = _labels(0.8)
    cycles = []
    for i, (t, legs) in enumerate(labels):
        reports = []
        if i < 10:
            reports.append((1, legs[0, 0] + 0.2, 0.1))  # 0.2 m from a leg
        elif i < 15:
            reports.append((1, legs[0, 0] + 0.4, 0.1))  # 0.4 m: found at 0.5 m, not at 0.3 m
        reports.append((2, -3.0, 0.0))  # far from every leg
        cycles.append(Cycle(t, (0.0, 0.0, 0.0), reports, False, None))
    m = labelled_metrics(Run("/scan", cycles), labels, 0.1)
    assert m["labelled_scans"]["all"] == 20
    assert m["recall_0.3m"]["all"] == pytest.approx(0.5) and m["recall_0.5m"]["all"] == pytest.approx(0.75)
    assert m["position_error_median_m"] == pytest.approx(0.2, abs=1e-6)
    # to the person's centre (between the legs, at y = 0): only the 8 matched scans with both legs labelled
    assert m["person_position_scans"] == 8
    assert m["person_position_error_median_m"] == pytest.approx(math.hypot(0.2, 0.1), abs=1e-3)
    assert m["far_reports_per_min"] == pytest.approx(20 / (20 * 0.1 / 60), rel=1e-3)


def test_person_centre_is_the_closest_pair_of_labelled_legs() -> None:
    pair_and_chair = np.array([[2.0, 0.15], [4.0, 1.0], [2.1, -0.15]])
    assert person_centre(pair_and_chair) == pytest.approx([2.05, 0.0])
    assert person_centre(np.array([[2.0, 0.0]])) is None  # the other leg hidden: centre unknown
    assert person_centre(np.array([[2.0, 0.0], [2.0, 1.2]])) is None  # farther apart than a step


def test_background_reports_and_still_tracks() -> None:
    b = np.linspace(-1.0, 1.0, 101)
    ranges = [np.full(101, 4.0) for _ in range(61)]  # a wall at 4 m, 6 s at 10 Hz
    cycles = []
    for i in range(61):
        reports = [(1, 4.0 * math.cos(0.2), 4.0 * math.sin(0.2)),  # on the wall, never moving
                   (2, 1.0 + 0.03 * i, 0.0)]  # a walker in front of it, up to 2.8 m
        cycles.append(Cycle(i * 0.1, (0.0, 0.0, 0.0), reports, False, None))
    m = background_metrics(Run("/scan", cycles, ranges, b))
    assert m["background_reports_per_min"] == pytest.approx(61 / 0.1, rel=1e-3)
    assert m["still_tracks_per_min"] == pytest.approx(10.0) and m["tracks"] == 2


def test_a_walker_reported_briefly_is_no_still_track_a_chair_is() -> None:
    """Reports close together are a still track only where the laser saw the place unchanged: a walker
    reported for three cycles while it crossed (its reports within 0.3 m) arrived in front of the wall,
    so the place changed; a chair reported as long stood there all the time."""
    b = np.linspace(-1.0, 1.0, 201)
    ranges, cycles = [], []
    for i in range(60):
        r = np.full(201, 4.0)  # a wall at 4 m
        r[40:46] = 2.0  # a chair at 2 m, bearing about -0.57 rad, always there
        walker_beam = 100 + (i - 30) * 3  # a walker crossing at 2 m, in view from cycle 10 to 50
        if 10 <= i <= 50:
            r[max(walker_beam - 3, 0):walker_beam + 3] = 2.0
        ranges.append(r)
        reports = []
        if 29 <= i <= 31:  # reported only as it passes bearing 0, 0.12 m a cycle
            reports.append((1, 2.0, 0.06 * (i - 30)))
        if 29 <= i <= 31:
            reports.append((2, 2.0 * math.cos(b[43]), 2.0 * math.sin(b[43])))
        cycles.append(Cycle(i * 0.1, (0.0, 0.0, 0.0), reports, False, None))
    run = Run("/scan", cycles, ranges, b)
    assert place_change_m(run, 2.9, 3.1, np.array([2.0, 0.0])) == pytest.approx(2.0)
    assert place_change_m(run, 2.9, 3.1, np.array([2.0 * math.cos(b[43]), 2.0 * math.sin(b[43])])) == 0.0
    m = background_metrics(run)
    assert m["still_tracks_by_reports_per_min"] == pytest.approx(2 / run.minutes, rel=1e-3)  # by the reports
    assert m["still_tracks_per_min"] == pytest.approx(1 / run.minutes, rel=1e-3)  # the chair only


def test_the_robots_own_frame_does_not_hide_a_walker_from_the_still_track_test() -> None:
    """A walker reported for four cycles as it passes beside the robot, on a place whose beams partly hit the
    robot's own frame (0.4 m in every scan): the frame is the nearest return there whatever passes behind it,
    so with those beams the place looked unchanged and the walker counted as a still track. Left out, the
    place changed (the walker came in front of the wall at 4 m); a place only the frame's beams cover is out
    of view (no change known), and a chair in view stays a still track."""
    b = np.linspace(-1.0, 1.0, 201)
    ranges, cycles = [], []
    for i in range(60):
        r = np.full(201, 4.0)
        r[100:104] = 0.4  # the robot's frame, every scan
        r[40:46] = 2.0  # a chair at 2 m, always there
        if 25 <= i <= 35:
            r[94:100] = 0.8  # a walker passing beside the frame, 0.8 m out
        ranges.append(r)
        reports = [(1, 0.8 * math.cos(b[99]), 0.8 * math.sin(b[99]))] if 29 <= i <= 32 else []
        if 29 <= i <= 32:
            reports.append((2, 2.0 * math.cos(b[43]), 2.0 * math.sin(b[43])))
        cycles.append(Cycle(i * 0.1, (0.0, 0.0, 0.0), reports, False, None))
    run = Run("/scan", cycles, ranges, b)
    blocked = np.zeros(201, bool)
    blocked[100:104] = True
    walker = np.array([0.8 * math.cos(b[99]), 0.8 * math.sin(b[99])])
    # the frame, nearer than the place, hides it on its beams even where they are not known to be blocked
    assert place_change_m(run, 2.9, 3.2, walker) == pytest.approx(3.2)
    assert place_change_m(run, 2.9, 3.2, walker, blocked) == pytest.approx(3.2)
    assert place_change_m(run, 2.9, 3.2, walker, np.ones(201, bool)) == math.inf  # every beam blocked
    m = background_metrics(run)
    assert m["still_tracks_by_reports_per_min"] == pytest.approx(2 / run.minutes, rel=1e-3)
    assert m["still_tracks_per_min"] == pytest.approx(1 / run.minutes, rel=1e-3)  # the chair only


def test_a_thing_in_front_of_a_place_does_not_hide_a_walker_from_the_still_track_test() -> None:
    """A post at 2.0 m stands at the edge of the beams of a place 2.36 m out, where a walker passes for 0.7 s in
    front of a wall at 3.0 m: the post is the nearest return of those beams in every scan, so the place looked
    unchanged and the walker, reported three cycles, counted as a still track. Returns nearer than where their
    beam enters the place's disc hide it on that beam and say nothing of it (a second post at the other edge,
    at the place's own range but beside the disc, too): the place changed (the walker came in front of the wall). A
    place hidden in every scan of its window is out of view, never still; the post's own place is still."""
    b = np.linspace(-1.0, 1.0, 401)
    ranges, cycles = [], []
    place = np.array([2.36, 0.0])
    post = int(np.searchsorted(b, -0.1))  # within the place's beams: asin(0.25 / 2.36) = 0.106 rad
    aside = int(np.searchsorted(b, 0.1))
    for i in range(40):
        r = np.full(401, 3.0)
        r[post - 1:post + 1] = 2.0
        r[aside - 1:aside + 1] = 2.2  # at the place's range, 0.28 m beside it: outside its disc, in front of it
        if 15 <= i <= 21:
            r[196:205] = 2.3  # the walker, passing the place
        ranges.append(r)
        reports = [(1, 2.36, 0.05 * (i - 18))] if 17 <= i <= 19 else []
        cycles.append(Cycle(i * 0.1, (0.0, 0.0, 0.0), reports, False, None))
    run = Run("/scan", cycles, ranges, b)
    assert place_change_m(run, 1.7, 1.9, place) == pytest.approx(0.7)
    post_xy = np.array([2.0 * math.cos(b[post]), 2.0 * math.sin(b[post])])
    assert place_change_m(run, 1.7, 1.9, post_xy) == pytest.approx(0.0)
    hidden = np.array([3.5 * math.cos(b[200]), 3.5 * math.sin(b[200])])  # behind the wall: never seen
    assert place_change_m(run, 1.7, 1.9, hidden) == math.inf
    m = background_metrics(run)
    assert m["still_tracks_by_reports_per_min"] == pytest.approx(1 / run.minutes, rel=1e-3)
    assert m["still_tracks_per_min"] == 0.0


def test_a_report_where_the_laser_cannot_look_is_out_of_view_not_background() -> None:
    """Beams the robot's own frame blocks (0.3 m, every scan) and bearings outside the field of view see
    nothing behind: a track coasting there is counted apart, not as on the background."""
    b = np.linspace(-1.0, 1.0, 101)
    r = np.full(101, 4.0)
    r[90:] = 0.3  # the robot's frame on the last 11 beams
    cycles = [Cycle(i * 0.1, (0.0, 0.0, 0.0), [(1, 2.0 * math.cos(0.9), 2.0 * math.sin(0.9)),  # behind the frame
                                               (2, 2.0 * math.cos(1.2), 2.0 * math.sin(1.2)),  # beyond the view
                                               (3, 4.0, 0.0)], False, None)  # on the wall
              for i in range(60)]
    run = Run("/scan", cycles, [r] * 60, b)
    m = background_metrics(run)
    assert m["background_reports_per_min"] == pytest.approx(60 / run.minutes, abs=0.1)  # the wall report alone
    assert m["out_of_view_reports_per_min"] == pytest.approx(120 / run.minutes, abs=0.1)
    m_near = background_metrics(Run("/scan", cycles, [np.where(np.arange(101) >= 90, 0.6, 4.0)] * 60, b))
    assert m_near["out_of_view_reports_per_min"] == pytest.approx(60 / run.minutes, abs=0.1)  # 0.6 m: no robot


def test_a_walker_in_open_space_and_a_labelled_person_are_not_background() -> None:
    """A beam with no return most of the time looks into open space: a walker it returns from now and
    then is in front of the background, not on it (before, the percentile over returns only made the
    walker its own background). A report on a labelled leg is the person: no still track either."""
    b = np.linspace(-1.0, 1.0, 101)
    ranges, cycles, labels = [], [], []
    for i in range(60):
        r = np.full(101, np.nan)  # open space, no return ...
        r[50] = 3.0 if i % 10 == 0 else np.nan  # ... but the walker crossing beam 50 now and then
        r[10] = 4.0  # and a wall on beam 10
        ranges.append(r)
        reports = [(1, 3.0, 0.0), (2, 2.0, 1.0)]  # the walker (labelled), and a standing thing
        cycles.append(Cycle(i * 0.1, (0.0, 0.0, 0.0), reports, False, None))
        labels.append((i * 0.1, np.array([[3.05, 0.1], [2.95, -0.1]])))
    m = background_metrics(Run("/scan", cycles, ranges, b), labels)
    assert m["background_reports_per_min"] == 0.0
    assert m["still_tracks_per_min"] == pytest.approx(60 / 5.9, rel=1e-3) and m["tracks"] == 2  # only track 2
    unlabelled = background_metrics(Run("/scan", cycles, ranges, b))
    assert unlabelled["background_reports_per_min"] == 0.0
    # unlabelled, the walker's reports stand still too, but the laser saw it come and go on beam 50
    assert unlabelled["still_tracks_by_reports_per_min"] == pytest.approx(120 / 5.9, rel=1e-3)
    assert unlabelled["still_tracks_per_min"] == pytest.approx(60 / 5.9, rel=1e-3)


def test_refusals_and_path_comparison() -> None:
    cycles = [Cycle(i * 0.1, (0.0 if i >= 5 else 0.1 * i, 0.0, 0.0), [], i >= 5, "no_valid_shift" if i >= 5 else None)
              for i in range(10)]
    run = Run("/scan", cycles)
    assert refusal_metrics(run) == {"refused_share": 0.5, "refusal_reasons": {"no_valid_shift": 5}}
    ref = np.array([[0.1 * i, 0.0, 0.0] for i in range(10)])
    m = path_comparison(run, ref)
    assert m["kiss_icp_path_m"] == pytest.approx(0.9) and m["max_offset_m"] == pytest.approx(0.9)
    assert m["lost_after_s"] == pytest.approx(0.6)  # 0.5 m behind at 0.6 s
    assert m["end_to_start_m"] == pytest.approx(0.0) and m["kiss_icp_end_to_start_m"] == pytest.approx(0.9)


def test_end_to_start_closes_a_loop_and_measures_a_gap() -> None:
    loop = np.array([[math.cos(a), math.sin(a), a] for a in np.linspace(0.0, 2 * math.pi, 50)])
    assert end_to_start_m(loop) == pytest.approx(0.0, abs=1e-9)
    assert end_to_start_m(loop + np.linspace(0.0, 0.3, 50)[:, None] * [1.0, 0.0, 0.0]) == pytest.approx(0.3)
    assert end_to_start_m(loop[:1]) == 0.0


def test_suite_on_one_recording_skips_the_absent(shared_data: Path, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    src = shared_data / "real_people_laser"
    if not (src / "positive_2.bag").exists() or not (src / "positive_2_extracted.bag").exists():
        pytest.skip(f"positive_2 not in {src}")
    for name in ("positive_2.bag", "positive_2_extracted.bag"):  # linked, not copied
        (tmp_path / name).symlink_to(src / name)
    assert main(["eval", "--data", "real", "--data-dir", str(tmp_path), "--max-scans", "120", "--json"]) == 0
    suite = json.loads(capsys.readouterr().out)
    assert suite["skipped"] == [r.name for r in RECORDINGS if r.name != "positive_2"]
    (r,) = suite["recordings"]
    assert r["recording"] == "positive_2" and r["scans"] == 120 and r["sensor"]["beams"] == 768
    assert 0 < r["labelled_scans"]["all"] < 83  # the labelled scans among the first 120
    assert 0.0 <= r["recall_0.5m"]["all"] <= 1.0 and r["recall_0.3m"]["all"] <= r["recall_0.5m"]["all"]
    assert 0.0 <= r["refused_share"] <= 1.0 and r["background_reports_per_min"] is not None
    assert r["people"]["labelled_trajectories"] >= 1 and r["people"]["id_switches"] >= 0
    # the table: one line per recording, the people's identity switches in the ``id sw`` column
    assert main(["eval", "--data", "real", "--data-dir", str(tmp_path), "--max-scans", "120"]) == 0
    head, _, row, *rest = capsys.readouterr().out.splitlines()
    assert "id sw" in head and row.startswith("positive_2") and f" {r['people']['id_switches']} " in row
    assert sum("skipped" in line for line in rest) == len(RECORDINGS) - 1


def test_eval_real_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["eval", "--data", "real", "--data-dir", str(tmp_path / "none")]) == 2
    assert "not a directory" in capsys.readouterr().err
    assert main(["eval", "--data", "real", "--data-dir", str(tmp_path), "--only", "nope"]) == 2
    assert "unknown recording(s) nope" in capsys.readouterr().err
    assert main(["eval", "--data", "real", "--data-dir", str(tmp_path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["skipped"] == [r.name for r in RECORDINGS]


def test_eval_real_leg_model_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--leg-model``: a missing or damaged file is refused before any recording is read; the simulated runs
    refuse it (they use the packaged detector)."""
    assert main(["eval", "--data", "real", "--data-dir", str(tmp_path), "--leg-model", str(tmp_path / "no.npz")]) == 2
    assert "--leg-model" in capsys.readouterr().err
    (tmp_path / "bad.npz").write_bytes(b"PK\x03\x04" + bytes(60))
    assert main(["eval", "--data", "real", "--data-dir", str(tmp_path), "--leg-model", str(tmp_path / "bad.npz")]) == 2
    assert "cannot read the leg model" in capsys.readouterr().err
    assert main(["eval", "--scenario", "paper1", "--leg-model", str(tmp_path / "bad.npz")]) == 2
    assert "applies to --data real" in capsys.readouterr().err


def test_eval_real_scores_with_the_leg_model_given(shared_data: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """A detector that takes nothing for a leg (every leaf's probability 0) finds nobody where the packaged
    one finds the labelled walker: the file given is the one the estimator runs with."""
    from app.legmodel import default_model_path

    src = shared_data / "real_people_laser"
    if not (src / "positive_2.bag").exists() or not (src / "positive_2_extracted.bag").exists():
        pytest.skip(f"positive_2 not in {src}")
    with np.load(default_model_path(), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["value"] = np.zeros_like(arrays["value"])
    np.savez_compressed(tmp_path / "blind.npz", **arrays)
    found = {}
    for model in (None, tmp_path / "blind.npz"):
        extra = ["--leg-model", str(model)] if model else []
        assert main(["eval", "--data", "real", "--data-dir", str(src), "--only", "positive_2", "--max-scans", "120",
                     "--json", *extra]) == 0
        suite = json.loads(capsys.readouterr().out)
        assert suite["leg_model"] == str(model or default_model_path())
        found[model] = suite["recordings"][0]["people"]["recall_0.5m"]["all"]
    assert found[None] > 0.5 and found[tmp_path / "blind.npz"] == 0.0


def test_drive_against_kiss_icp(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The drive's first 40 scans of each laser: kiss-icp runs as the reference, as recorded and configured
    for the scans (the robot's reach left out, de-skewed), and each path source's three lasers agree with
    each other (headings; paths after their fitted mounts), whatever the lasers' mounts."""
    pytest.importorskip("kiss_icp", reason="kiss-icp (the optional 'eval' dependency) is not installed")
    src = shared_data / "real_people_laser"
    if not (src / "negative_2.bag").exists():
        pytest.skip(f"negative_2.bag not in {src}")
    assert main(["eval", "--data", "real", "--data-dir", str(src), "--only", "negative_2", "--max-scans", "40",
                 "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["recordings"]
    assert [r["topic"] for r in rows] == ["/left_scan", "/rear_scan", "/right_scan"]
    for r in rows:
        k = r["kiss_icp"]
        assert k["done"] and k["kiss_icp_path_m"] > 0.5  # the robot drove
        assert k["heading_vs_other_lasers_max_deg"] < 5.0
        assert k["end_to_start_m"] >= 0.0 and k["kiss_icp_end_to_start_m"] > 0.0
        assert r["reports_per_min"] is not None and "background_reports_per_min" not in r  # not a still laser
        plain, conf = r["kiss_icp"], r["kiss_icp_configured"]
        assert (plain["min_range_m"], plain["deskew"]) == (0.1, False)
        assert conf["done"] and (conf["min_range_m"], conf["deskew"]) == (ROBOT_REACH_M, True)
        assert conf["kiss_icp_path_m"] > 0.5 and conf["max_offset_m"] < 0.3
        assert "loop_closure" not in r and "end_vs_loop_closure_m" not in conf  # cut short: the drive is no loop
        for agree in (r["matcher_vs_other_lasers"], plain["vs_other_lasers"], conf["vs_other_lasers"]):
            assert 0.0 <= agree["max_offset_m"] < 0.3 and abs(agree["final_heading_deg"]) < 5.0


def test_walking_after_onset_leaves_out_the_first_report_budget() -> None:
    """A person stands 1 s, then walks: the walking scans within ``ONSET_BUDGET_S`` of the walk's onset are in
    ``walking`` but not in ``walking_after_onset``; a report only from 0.5 s into the walk is found in every
    settled walking scan and in fewer of all walking ones."""
    from app.evaluation.real_data import ONSET_BUDGET_S, since_walk_onset_s

    period = 0.1
    labels = []
    for i in range(40):
        x = 2.0 + max(0.0, i * period - 1.0) * 0.8
        labels.append((100.0 + i * period, np.array([[x, 0.1], [x, -0.1]])))
    speeds = person_speeds(labels)
    since = since_walk_onset_s(labels, speeds)
    walking = [i for i, v in enumerate(speeds) if speed_class(v) == "walking"]
    assert walking and since[walking[0]] == 0.0 and all(since[i] is None for i in range(walking[0]))
    assert since[walking[-1]] == pytest.approx((walking[-1] - walking[0]) * period)
    start = walking[0]
    cycles = [Cycle(t, (0.0, 0.0, 0.0), [(1, legs[0, 0], 0.0)] if 100.0 + (start + 5) * period <= t + 1e-9 else [],
                    False, None) for t, legs in labels]
    m = labelled_metrics(Run("/scan", cycles), labels, period)
    settled = sum(1 for i in walking if since[i] >= ONSET_BUDGET_S)
    assert 0 < m["labelled_scans"]["walking_after_onset"] == settled < m["labelled_scans"]["walking"]
    assert m["recall_0.5m"]["walking"] < m["recall_0.5m"]["walking_after_onset"] < 1.0
