"""The real-data suite (``vipsm-robot eval --data real``): the estimator, laser only, on the recorded
leg_tracker scans in ``../shared/data/real_people_laser`` (PROVENANCE.md there), scored per recording.

* **Labelled recordings** (``positive_N.bag`` with ``positive_N_extracted.bag``): the extracted bag holds
  the walking person's leg clusters (PoseArray, laser frame) for part of the scans, with the stamps
  rewritten; each training scan is matched to the scan of ``positive_N.bag`` with identical ranges,
  which gives its time. Per labelled scan: is there a report within 0.3 / 0.5 m of a labelled leg
  (recall, split by the person's speed), the distance of the nearest report to the person's centre (the
  midpoint of the two labelled legs, in the scans where both are labelled; the person's position error,
  median over matched scans) and to the nearest leg (half a stride from a correct centre), and reports
  more than 1 m from every labelled leg (per minute of labelled scans; a second person passing counts here
  too, so this bounds false reports from above). The person's speed: the legs' centroid fitted linearly
  over the labelled scans within ``SPEED_WINDOW_S`` around the scan (one leg or two labelled moves the
  centroid by a hip's width, so a difference of neighbours would not do);
  walking > 0.3 m/s, slow 0.1-0.3, standing < 0.1; ``walking_after_onset``: the walking scans at least
  ``ONSET_BUDGET_S`` (issue 29's first-report budget) after their walk began.
* **Still recordings** (every recording but the drive): the laser did not move, so the estimator's odometry
  frame is the laser frame. Reports on the static background: the report's range is at least the beam's
  ``BACKGROUND_PERCENTILE`` percentile range over the recording (no return counting as open space,
  infinitely far) less ``BACKGROUND_MARGIN_M`` (a report at or behind the farthest surface that beam
  usually sees: a wall, not a person in front of it; a report outside the field of view or on beams the
  robot itself blocks, nearer than ``SELF_M``, is out of view, counted apart); tracks that never move:
  reported tracks whose reports all lie within ``STILL_TRACK_M`` of their mean *and* whose place the laser
  saw unchanged (:func:`place_change_m`: nothing arrived there or left from ``PLACE_WINDOW_S`` before the
  first report to as long after the last). A walker reported only for a few cycles has reports close
  together too, but the laser saw it come or go; judged by its reports alone it would count as still
  (``still_tracks_by_reports_per_min``, also given). In a labelled scan a report within 0.5 m of a
  labelled leg is the person, counted in neither.
* **The drive** (``negative_2.bag``, nobody present, no odometry): every report is false (per minute);
  the matcher's path is compared with an independent scan-to-map registration of the same scans by
  ``kiss-icp`` (run here only, never in the product's loop), as recorded (``kiss_icp``) and configured for
  these scans (``kiss_icp_configured``: the robot's reach left out, each sweep de-skewed); each path
  source's three lasers against each other after their fitted mounts (one rigid robot:
  ``laser_agreement``); every path's end against the loop closure (the last scans matched directly to the
  first: the drive ends where it began, ``loop_closure``).
* Every recording: the share of cycles the matcher refused (odometry fallback) and why.

"Report": an entry of ``Estimate.obstacles`` (the estimate has no other list of bodies).
A recording that is absent is listed under ``skipped`` with its name.
"""

from __future__ import annotations

import bisect
import math
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vipsm.estimator import Estimator, EstimatorConfig
from vipsm.legs import FEATURE_NAMES, LegModel
from vipsm.psm import PsmResult
from vipsm.types import EstimateFlag

from ..bagread import LASER_SCAN, BagTopics, bag_topics, open_reader, read_bag
from ..legmodel import default_leg_model, default_model_path, leg_candidates, load_leg_model
from .identity import identity_metrics

SPEED_WINDOW_S = 1.0  # the centroid fit spans +-half of this
WALKING_MPS = 0.3
STANDING_MPS = 0.1
RECALL_RADII_M = (0.3, 0.5)
FAR_M = 1.0
BACKGROUND_PERCENTILE = 95.0
BACKGROUND_MARGIN_M = 0.3
STILL_TRACK_M = 0.3
#: the place of a track whose reports lie close together, as the laser saw it: the nearest return at or behind
#: it on the beams within a person's radius (``PLACE_RADIUS_M``) of the reports' mean, from ``PLACE_WINDOW_S`` before
#: the first report to as long after the last. A change of more than ``PLACE_CHANGE_M`` (a leg's width: the
#: people stage's ``leg_travel_m``) means something came or left there: the track was on a moving thing.
#: A chair stays put to the range noise, a standing person's sway moves its nearest return a few cm
PLACE_RADIUS_M = 0.25
PLACE_WINDOW_S = 1.0
PLACE_CHANGE_M = 0.2
#: a beam that returns nearer than this in ``BACKGROUND_PERCENTILE`` percent of the scans sees the robot that
#: carries the laser (its frame, a mount): what lies behind is never seen there
SELF_M = 0.5
#: no return, as a range: open space, farther than any report (finite, so the percentile interpolates cleanly)
OPEN_SPACE_M = 1e9
#: two labelled legs this close are one person's pair (a walker's legs at the laser's height lie within a
#: step of each other; the labels' pairs are 0.19-0.40 m apart, 5th-95th percentile); farther apart, the
#: labelled box held something else too (a second person, a chair leg)
PAIR_M = 0.6
#: issue 29's budget for the first report of a walk: the labelled walking scans this soon after a walk's
#: onset are left out of ``walking_after_onset`` (a causal estimator cannot yet know; the label is a fit
#: centred on the scan, so it calls a walk about a quarter of a second before the pelvis has moved)
ONSET_BUDGET_S = 0.3
#: kiss-icp against the matcher: the matcher "lost" once their positions differ by this much
LOST_M = 0.5
#: the configured reference (``kiss_icp_configured``) registers only returns beyond this: the robot's own parts
#: (frame, mounts) lie within it, as the estimator's ``self_returns_max_range_m`` says of any robot; seen
#: through the whole drive they move with the robot and pull a registration without a model of them
#: towards standing still (the drive's lasers see them at 0.12-0.73 m)
ROBOT_REACH_M = EstimatorConfig().self_returns_max_range_m
#: the lasers' agreement (rigid mounts): poses interpolated to this common time step, the mount fitted from
#: the relative motions over ``MOUNT_LAG_S`` (short enough that a drift builds little within one)
AGREE_STEP_S = 0.05
MOUNT_LAG_S = 2.0
#: the drive ends where it began: each of its last ``LOOP_SCANS`` scans matched directly to each of its first
#: ones (``loop_closure``) measures where the laser truly ended, with no drift in it
LOOP_SCANS = 3


@dataclass(frozen=True)
class Recording:
    name: str
    bag: str
    kind: str  # "labelled", "still" or "drive"
    labels: str | None = None


RECORDINGS = (
    Recording("positive_1", "positive_1.bag", "labelled", "positive_1_extracted.bag"),
    Recording("positive_2", "positive_2.bag", "labelled", "positive_2_extracted.bag"),
    Recording("positive_3", "positive_3.bag", "labelled", "positive_3_extracted.bag"),
    Recording("positive_6", "positive_6.bag", "labelled", "positive_6_extracted.bag"),
    Recording("demo_stationary_simple_environment", "demo_stationary_simple_environment.bag", "still"),
    Recording("negative_2", "negative_2.bag", "drive"),
)


@dataclass
class Cycle:
    stamp_s: float
    pose: tuple[float, float, float]
    reports: list[tuple[int, float, float]]  # (track_id, x_m, y_m)
    fallback: bool
    reason: str | None
    #: ``Estimate.people``: (track_id, x_m, y_m, moving)
    people: list[tuple[int, float, float, bool]] = field(default_factory=list)


@dataclass
class Run:
    topic: str
    cycles: list[Cycle] = field(default_factory=list)
    ranges: list[np.ndarray] = field(default_factory=list)
    bearings: np.ndarray | None = None
    sensor: dict[str, Any] | None = None
    ms_per_cycle: float = 0.0
    #: the bag ended in damage part-way: why ("" = read whole)
    truncation: str = ""
    #: the first scan's ``Scan.beam_dt_s`` (the sweep's time per beam; 0 if the data does not say)
    beam_dt_s: float = 0.0

    @property
    def minutes(self) -> float:
        if len(self.cycles) < 2:
            return 0.0
        return (self.cycles[-1].stamp_s - self.cycles[0].stamp_s) / 60.0


# ---------------------------------------------------------------------------------------------
# running the estimator


def refusal_reason(est: Estimator) -> str | None:
    """Why the matcher gave the odometry's pose this cycle (None: it matched)."""
    dbg = est.last_debug
    if dbg is None or not dbg.match.flags & EstimateFlag.ODOMETRY_FALLBACK:
        return None
    res: PsmResult | None = dbg.match.result
    if res is None and est._matcher.keyframe is None:  # noqa: SLF001 - the suite looks inside on purpose
        return "no_keyframe"  # no scan yet had enough valid beams to become the reference
    if res is None:
        return "refused_before_matching"  # restoration covered too much, or unusable bearings
    if res.refused:
        return str(res.reason.value)
    return "correction_too_large"  # matched, but further from the prediction than max_correction


def run_estimator(bag: Path, topic: str, max_scans: int | None = None,
                  config: EstimatorConfig | None = None, leg_model: LegModel | None = None) -> Run:
    """The estimator (laser only, no odometry: each cycle predicted where the last ended) over a bag, with
    ``leg_model`` (None: the packaged leg detector)."""
    from ..bagread import BagReadResult

    est = Estimator(config or EstimatorConfig(), leg_model=leg_model or default_leg_model())
    run = Run(topic)
    read = BagReadResult()
    t0 = time.perf_counter()
    for bc in read_bag(bag, BagTopics(topic), read=read, max_scans=max_scans):
        e = est.step(bc.scan, bc.odometry if bc.odometry_given else None, None)  # no --odom: no odometry
        run.cycles.append(Cycle(bc.scan.stamp_s, (e.pose.x_m, e.pose.y_m, e.pose.theta_rad),
                                [(o.track_id, o.x_m, o.y_m) for o in e.obstacles],
                                bool(e.flags & EstimateFlag.ODOMETRY_FALLBACK), refusal_reason(est),
                                [(p.track_id, p.x_m, p.y_m, p.moving) for p in e.people]))
        run.ranges.append(bc.scan.ranges_m)
        if run.bearings is None:
            run.bearings = bc.scan.bearings_rad
            run.beam_dt_s = float(bc.scan.beam_dt_s)
    run.ms_per_cycle = 1e3 * (time.perf_counter() - t0) / max(len(run.cycles), 1)
    run.sensor = read.sensor.as_dict() if read.sensor is not None else None
    run.truncation = read.reason if read.truncated else ""
    return run


def scan_topics(bag: Path) -> list[str]:
    reader = open_reader(bag)
    try:
        return sorted(t for t, ty in bag_topics(reader).items() if ty == LASER_SCAN)
    finally:
        reader.close()


# ---------------------------------------------------------------------------------------------
# labels


def read_labels(bag: Path, extracted: Path) -> list[tuple[float, np.ndarray]]:
    """(stamp of the matching scan of ``bag``, leg positions (k, 2) in the laser frame), in time order.
    A training scan whose ranges match no scan of ``bag`` is left out."""
    stamps: dict[bytes, float] = {}
    reader = open_reader(bag)
    try:
        scans = [c for c in reader.connections if c.msgtype == LASER_SCAN]
        for conn, _, raw in reader.messages(connections=scans):
            m = reader.deserialize(raw, conn.msgtype)
            stamps[np.asarray(m.ranges, np.float32).tobytes()] = m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
    finally:
        reader.close()
    out: list[tuple[float, np.ndarray]] = []
    legs: np.ndarray | None = None
    reader = open_reader(extracted)
    try:
        for conn, _, raw in reader.messages():
            if conn.topic == "/leg_cluster_positions":
                m = reader.deserialize(raw, conn.msgtype)
                legs = np.array([[p.position.x, p.position.y] for p in m.poses], dtype=float).reshape(-1, 2)
            elif conn.topic == "/training_scan" and legs is not None:
                m = reader.deserialize(raw, conn.msgtype)
                t = stamps.get(np.asarray(m.ranges, np.float32).tobytes())
                if t is not None and legs.size:
                    out.append((t, legs))
                legs = None
    finally:
        reader.close()
    return sorted(out, key=lambda x: x[0])


def person_speeds(labels: list[tuple[float, np.ndarray]], window_s: float = SPEED_WINDOW_S) -> list[float | None]:
    """Per labelled scan, the legs' centroid speed from a straight-line fit over the labelled scans within
    +-window/2 (None: fewer than 3 of them, or spanning less than half the window)."""
    t = np.array([s for s, _ in labels])
    c = np.array([legs.mean(axis=0) for _, legs in labels]).reshape(-1, 2)
    out: list[float | None] = []
    for i in range(t.size):
        near = np.abs(t - t[i]) <= window_s / 2
        tt = t[near]
        if tt.size < 3 or tt.max() - tt.min() < window_s / 2:
            out.append(None)
            continue
        A = np.stack([tt - t[i], np.ones(tt.size)], axis=1)
        coef, *_ = np.linalg.lstsq(A, c[near], rcond=None)
        out.append(float(np.hypot(*coef[0])))
    return out


def since_walk_onset_s(labels: list[tuple[float, np.ndarray]], speeds: list[float | None]) -> list[float | None]:
    """Per labelled scan, the time since its walk began (None: not walking). A walk begins at a walking scan
    whose previous labelled scan is not walking or lies more than half ``SPEED_WINDOW_S`` before it."""
    out: list[float | None] = []
    onset: float | None = None
    prev_t: float | None = None
    for (t, _), v in zip(labels, speeds, strict=True):
        if speed_class(v) != "walking":
            onset = None
        elif onset is None or prev_t is None or t - prev_t > SPEED_WINDOW_S / 2:
            onset = t
        out.append(None if onset is None else t - onset)
        prev_t = t
    return out


def speed_class(v: float | None) -> str:
    if v is None:
        return "unknown"
    return "walking" if v > WALKING_MPS else "slow" if v >= STANDING_MPS else "standing"


def person_centre(legs: np.ndarray, pair_m: float = PAIR_M) -> np.ndarray | None:
    """The labelled person's position: the midpoint of the closest two labelled legs within ``pair_m`` of
    each other (None: one leg labelled, the other hidden, so the person's centre is not known)."""
    if len(legs) < 2:
        return None
    d = np.hypot(legs[:, None, 0] - legs[None, :, 0], legs[:, None, 1] - legs[None, :, 1])
    d[np.tril_indices(len(legs))] = np.inf
    i, j = np.unravel_index(int(np.argmin(d)), d.shape)
    return (legs[i] + legs[j]) / 2.0 if d[i, j] <= pair_m else None


def labelled_metrics(run: Run, labels: list[tuple[float, np.ndarray]], period_s: float) -> dict[str, Any]:
    """Recall at each radius split by speed, the position error of matched reports, far reports per minute."""
    by_stamp = {round(c.stamp_s, 6): c for c in run.cycles}
    speeds = person_speeds(labels)
    since = since_walk_onset_s(labels, speeds)
    hits: dict[str, Counter[str]] = {f"{r:g}": Counter() for r in RECALL_RADII_M}
    totals: Counter[str] = Counter()
    errors, centre_errors, far = [], [], 0
    for (t, legs), v, dt in zip(labels, speeds, since, strict=True):
        cyc = by_stamp.get(round(t, 6))
        if cyc is None:
            continue  # beyond --max-scans
        classes_here = [speed_class(v), "all"] + (["walking_after_onset"] if dt is not None and dt >= ONSET_BUDGET_S
                                                   else [])
        totals.update(classes_here)
        pts = np.array([[x, y] for _, x, y in cyc.reports]).reshape(-1, 2)
        if not pts.size:
            continue
        d = np.hypot(pts[:, None, 0] - legs[None, :, 0], pts[:, None, 1] - legs[None, :, 1]).min(axis=1)
        far += int(np.count_nonzero(d > FAR_M))
        for r in RECALL_RADII_M:
            if d.min() <= r:
                hits[f"{r:g}"].update(classes_here)
        if d.min() <= max(RECALL_RADII_M):
            errors.append(float(d.min()))
            centre = person_centre(legs)
            if centre is not None:
                centre_errors.append(float(np.hypot(*(pts - centre).T).min()))
    minutes = totals["all"] * period_s / 60.0
    classes = ("walking", "slow", "standing", "unknown", "all", "walking_after_onset")
    run_reports = [by_stamp[round(t, 6)].reports if round(t, 6) in by_stamp else None for t, _ in labels]
    return {
        "labelled_scans": {k: totals[k] for k in classes},
        **{f"recall_{r}m": {k: (round(hits[r][k] / totals[k], 3) if totals[k] else None) for k in classes}
           for r in hits},
        "position_error_median_m": round(float(np.median(errors)), 3) if errors else None,
        "person_position_error_median_m": round(float(np.median(centre_errors)), 3) if centre_errors else None,
        "person_position_scans": len(centre_errors),
        "far_reports_per_min": round(far / minutes, 1) if minutes > 0 else None,
        **identity_metrics(run_reports, labels, PAIR_M, max(RECALL_RADII_M), period_s),
    }


# ---------------------------------------------------------------------------------------------
# still and driving recordings


def background_metrics(run: Run, labels: list[tuple[float, np.ndarray]] | None = None) -> dict[str, Any]:
    """Reports on the static background and tracks that never move, per minute (laser still).

    A beam's background is the ``BACKGROUND_PERCENTILE`` percentile of its ranges over the recording, a
    scan with no return there counting as open space (infinitely far): where a walker crosses open space
    the walker is the only thing the beam ever returns from, and is not the background. In a labelled scan
    a report within ``max(RECALL_RADII_M)`` of a labelled leg is the labelled person, neither a background
    report nor part of a still track. A report at a bearing the laser never sees past (outside its field of
    view, or on beams its own robot blocks: background nearer than ``SELF_M``) is out of view: a track
    coasting where the laser cannot look is judged neither on nor off the background, and counted apart.
    A still track: its reports lie within ``STILL_TRACK_M`` of their mean and the laser saw its place
    unchanged (:func:`place_change_m` at most ``PLACE_CHANGE_M``, on the beams the robot does not block: its
    own frame is the nearest return there in every scan, whatever passes behind)."""
    assert run.bearings is not None
    stack = np.array(run.ranges)
    bg = np.percentile(np.where(np.isfinite(stack), stack, OPEN_SPACE_M), BACKGROUND_PERCENTILE, axis=0)
    b = run.bearings
    half_beam = 0.5 * float(np.median(np.diff(b))) if b.size > 1 else 0.0
    on_bg = unseen = 0
    tracks: dict[int, list[tuple[float, float, float]]] = {}
    on_person: set[int] = set()
    for c in run.cycles:
        legs = _labelled_legs(labels, c.stamp_s)
        for tid, x, y in c.reports:
            if legs is not None and float(np.hypot(*(legs - (x, y)).T).min()) <= max(RECALL_RADII_M):
                on_person.add(tid)
                continue
            tracks.setdefault(tid, []).append((c.stamp_s, x, y))
            bearing = math.atan2(y, x)
            i = int(np.clip(np.searchsorted(b, bearing), 0, b.size - 1))
            if not b[0] - half_beam <= bearing <= b[-1] + half_beam or bg[i] < SELF_M:
                unseen += 1
            elif math.hypot(x, y) >= bg[i] - BACKGROUND_MARGIN_M:
                on_bg += 1
    close = [np.array(p) for tid, p in tracks.items() if tid not in on_person
             and np.hypot(*(np.array(p)[:, 1:] - np.mean(np.array(p)[:, 1:], axis=0)).T).max() <= STILL_TRACK_M]
    still = sum(1 for p in close
                if place_change_m(run, p[:, 0].min(), p[:, 0].max(), p[:, 1:].mean(axis=0), bg < SELF_M)
                <= PLACE_CHANGE_M)
    m = run.minutes
    return {
        "background_reports_per_min": round(on_bg / m, 1) if m > 0 else None,
        "out_of_view_reports_per_min": round(unseen / m, 1) if m > 0 else None,
        "still_tracks_per_min": round(still / m, 2) if m > 0 else None,
        "still_tracks_by_reports_per_min": round(len(close) / m, 2) if m > 0 else None,
        "tracks": len(tracks.keys() | on_person),
    }


def place_change_m(run: Run, first_s: float, last_s: float, xy: np.ndarray,
                   blocked: np.ndarray | None = None) -> float:
    """How much the laser's view of a place changed while a track was reported there: over the scans from
    ``PLACE_WINDOW_S`` before ``first_s`` to as long after ``last_s``, the spread (largest less smallest) of
    the nearest return at or behind the place on the beams within ``PLACE_RADIUS_M`` of ``xy`` (laser frame).
    A scan with no return there sees open space (``OPEN_SPACE_M``): a thing that came into open space changed
    it fully. A return nearer than where its beam enters the place's disc (``PLACE_RADIUS_M`` about ``xy``)
    hides the place on that beam and says nothing of it: a static thing in front of the place at the edge of
    its beams would otherwise be the nearest return in every scan, whatever came and went at the place.
    ``blocked`` (per beam): beams the robot that carries the laser blocks (its own parts); they see nothing of
    the place and are left out. A place no beam sees in any scan of the window is out of view: its change is
    unknown (infinite), so no track there counts as still."""
    assert run.bearings is not None
    r = float(np.hypot(*xy))
    half = math.pi if r <= PLACE_RADIUS_M else math.asin(PLACE_RADIUS_M / r)
    off = np.angle(np.exp(1j * (run.bearings - math.atan2(xy[1], xy[0]))))
    beams = np.abs(off) <= half
    if blocked is not None:
        beams &= ~blocked
        if not beams.any():
            return math.inf
    # where each beam enters the place's disc: a return nearer than that hides the place on that beam
    across = r * np.sin(off[beams])
    entry = r * np.cos(off[beams]) - np.sqrt(np.maximum(PLACE_RADIUS_M**2 - across**2, 0.0))
    nearest = []
    for c, rr in zip(run.cycles, run.ranges, strict=True):
        if first_s - PLACE_WINDOW_S <= c.stamp_s <= last_s + PLACE_WINDOW_S:
            seen = np.where(np.isfinite(rr[beams]), rr[beams], OPEN_SPACE_M)
            seen = seen[seen >= entry]
            if seen.size:
                nearest.append(float(seen.min()))
    return max(nearest) - min(nearest) if nearest else math.inf


def _labelled_legs(labels: list[tuple[float, np.ndarray]] | None, stamp_s: float) -> np.ndarray | None:
    """The labelled legs of the scan at ``stamp_s`` (None: not a labelled scan)."""
    if not labels:
        return None
    k = bisect.bisect_left(labels, stamp_s, key=lambda e: e[0])
    for j in (k - 1, k):
        if 0 <= j < len(labels) and abs(labels[j][0] - stamp_s) < 1e-6 and labels[j][1].size:
            return labels[j][1]
    return None


def report_counts(run: Run) -> dict[str, Any]:
    m = run.minutes
    n = sum(len(c.reports) for c in run.cycles)
    tracks = {tid for c in run.cycles for tid, _, _ in c.reports}
    return {"reports_per_min": round(n / m, 1) if m > 0 else None,
            "tracks_per_min": round(len(tracks) / m, 2) if m > 0 else None}


def refusal_metrics(run: Run) -> dict[str, Any]:
    n = len(run.cycles)
    reasons = Counter(c.reason for c in run.cycles if c.fallback)
    return {"refused_share": round(sum(c.fallback for c in run.cycles) / n, 3) if n else None,
            "refusal_reasons": {str(k): v for k, v in sorted(reasons.items(), key=lambda kv: -kv[1])}}


def kiss_icp_path(run: Run, min_range_m: float = 0.1, deskew: bool = False) -> np.ndarray:
    """(n, 3) laser poses (x, y, yaw) of kiss-icp's scan-to-map registration of the same scans.

    ``min_range_m``: nearer returns are not registered (``ROBOT_REACH_M`` leaves the robot's own parts out);
    ``deskew``: each return is moved to the laser's pose at the stamp by kiss-icp's own last motion over
    the beam's time in the sweep (``Scan.beam_dt_s``; kiss-icp's built-in de-skew assumes a sweep that
    spans the whole interval between scans, these take 50 of 133 ms)."""
    from kiss_icp.config import KISSConfig
    from kiss_icp.kiss_icp import KissICP

    assert run.bearings is not None
    cfg = KISSConfig()
    cfg.data.deskew = False
    cfg.data.max_range = 30.0
    cfg.data.min_range = min_range_m
    cfg.mapping.voxel_size = 0.05  # indoor rooms, 2-D: a 5 cm map
    cfg.adaptive_threshold.initial_threshold = 0.5
    cfg.registration.max_num_threads = 1
    icp = KissICP(cfg)
    c, s = np.cos(run.bearings), np.sin(run.bearings)
    tau_s = np.arange(run.bearings.size) * run.beam_dt_s
    poses: list[tuple[float, float, float]] = []
    for k, r in enumerate(run.ranges):
        ok = np.isfinite(r)
        x, y = r * c, r * s
        if deskew and k >= 2:
            x, y = _moved_by_twist(x, y, tau_s, _twist(poses[-2], poses[-1],
                                                       run.cycles[k - 1].stamp_s - run.cycles[k - 2].stamp_s))
        pts = np.stack([x[ok], y[ok], np.zeros(int(ok.sum()))], axis=1).astype(np.float64)
        icp.register_frame(pts, np.zeros(pts.shape[0]))
        T = icp.last_pose
        poses.append((float(T[0, 3]), float(T[1, 3]), math.atan2(T[1, 0], T[0, 0])))
    return np.array(poses).reshape(-1, 3)


def _twist(a: tuple[float, float, float], b: tuple[float, float, float], dt_s: float) -> np.ndarray:
    """Body-frame velocity (vx, vy, w) that moved pose ``a`` to ``b`` in ``dt_s`` (0 for no time)."""
    if not dt_s > 0:
        return np.zeros(3)
    ca, sa = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    dth = (b[2] - a[2] + math.pi) % (2 * math.pi) - math.pi
    return np.array([ca * dx + sa * dy, -sa * dx + ca * dy, dth]) / dt_s


def _moved_by_twist(x: np.ndarray, y: np.ndarray, tau_s: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Returns seen at ``tau_s`` after the stamp, in the laser's frame at the stamp (first order in the sweep)."""
    th = v[2] * tau_s
    ct, st = np.cos(th), np.sin(th)
    return ct * x - st * y + v[0] * tau_s, st * x + ct * y + v[1] * tau_s


def path_comparison(run: Run, ref: np.ndarray) -> dict[str, Any]:
    """The matcher's path against the reference's (both start at the first scan's pose)."""
    est = np.array([c.pose for c in run.cycles]).reshape(-1, 3)
    off = np.hypot(est[:, 0] - ref[:, 0], est[:, 1] - ref[:, 1])
    t = np.array([c.stamp_s for c in run.cycles]) - run.cycles[0].stamp_s
    lost = np.flatnonzero(off > LOST_M)
    step_est = np.hypot(*np.diff(est[:, :2], axis=0).T)
    step_ref = np.hypot(*np.diff(ref[:, :2], axis=0).T)
    frozen = (step_est < 0.001) & (step_ref > 0.01)
    dyaw = (est[-1, 2] - ref[-1, 2] + math.pi) % (2 * math.pi) - math.pi
    return {
        "matcher_path_m": round(float(step_est.sum()), 2),
        "kiss_icp_path_m": round(float(step_ref.sum()), 2),
        "final_offset_m": round(float(off[-1]), 3),
        "max_offset_m": round(float(off.max()), 3),
        "rms_offset_m": round(float(np.sqrt(np.mean(off**2))), 3),
        "final_heading_diff_deg": round(math.degrees(dyaw), 2),
        "lost_after_s": round(float(t[lost[0]]), 2) if lost.size else None,
        "frozen_while_moving_share": round(float(frozen.mean()), 3) if frozen.size else None,
        # the loop's closure, one definition for both: how far the last pose lies from the first (the drive
        # ends where it started, so a path that drifted ends away from its start)
        "end_to_start_m": round(end_to_start_m(est), 3),
        "kiss_icp_end_to_start_m": round(end_to_start_m(ref), 3),
    }


def end_to_start_m(path: np.ndarray) -> float:
    """Distance of a path's last position from its first ((n, >=2) poses; 0 for fewer than two)."""
    if path.shape[0] < 2:
        return 0.0
    return float(np.hypot(*(path[-1, :2] - path[0, :2])))


# ---------------------------------------------------------------------------------------------
# the drive's lasers against each other: one robot, rigid mounts

#: per laser (topic): the stamps and the (n, 3) poses of one path source
LaserPaths = dict[str, tuple[np.ndarray, np.ndarray]]


def _relative(p: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Poses ``p[j]`` in the frames of poses ``p[i]`` ((k, 3) each)."""
    c, s = np.cos(p[i, 2]), np.sin(p[i, 2])
    dx, dy = p[j, 0] - p[i, 0], p[j, 1] - p[i, 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, p[j, 2] - p[i, 2]], axis=1)


def fit_mount(pa: np.ndarray, pb: np.ndarray, lag: int) -> tuple[float, float, float]:
    """Laser b's mount in laser a's frame (phi, x, y) from two paths of one rigid robot at common times
    ((n, 3), headings unwrapped): each relative motion over ``lag`` samples satisfies A X = X B, whose
    translation part t_A = R_X t_B + (I - R_B) p is linear in (cos phi, sin phi, p) (2-D hand-eye
    calibration, least squares); the rotation is then normalised and p solved again with it."""
    i = np.arange(max(pa.shape[0] - lag, 0))
    a, b = _relative(pa, i, i + lag), _relative(pb, i, i + lag)
    if a.shape[0] < 2:
        raise ValueError(f"too few poses ({pa.shape[0]}) to fit a mount over {lag} samples")
    cb, sb = np.cos(b[:, 2]), np.sin(b[:, 2])
    one = np.ones_like(cb)
    m = np.concatenate([np.stack([b[:, 0], -b[:, 1], one - cb, sb], axis=1),
                        np.stack([b[:, 1], b[:, 0], -sb, one - cb], axis=1)])
    rhs = np.concatenate([a[:, 0], a[:, 1]])
    c, s = np.linalg.lstsq(m, rhs, rcond=None)[0][:2]
    phi = math.atan2(s, c)
    rot = np.concatenate([math.cos(phi) * b[:, 0] - math.sin(phi) * b[:, 1],
                          math.sin(phi) * b[:, 0] + math.cos(phi) * b[:, 1]])
    px, py = np.linalg.lstsq(m[:, 2:], rhs - rot, rcond=None)[0]
    return phi, float(px), float(py)


def as_mounted(pb: np.ndarray, mount: tuple[float, float, float]) -> np.ndarray:
    """Laser b's path (from its first pose) as the path of the laser at a, b being at ``mount`` in a's frame:
    X Q_b X^-1 (both start at the identity)."""
    phi, px, py = mount
    q = _relative(pb, np.zeros(pb.shape[0], dtype=int), np.arange(pb.shape[0]))
    c, s, cb, sb = math.cos(phi), math.sin(phi), np.cos(q[:, 2]), np.sin(q[:, 2])
    return np.stack([c * q[:, 0] - s * q[:, 1] + (1 - cb) * px + sb * py,
                     s * q[:, 0] + c * q[:, 1] - sb * px + (1 - cb) * py, q[:, 2]], axis=1)


def laser_agreement(paths: LaserPaths) -> dict[str, dict[str, float]]:
    """How far each laser's path leaves the other lasers' on one rigid robot: the paths (stamps, (n, 3)
    poses) interpolated to common times, each other laser's mapped onto this one's mount (fitted from
    the two paths, ``fit_mount``) and averaged; the largest distance from that mean and the final heading
    difference. Every registration of the three lasers' scans should agree with itself this way, whatever
    the mounts; a laser that leaves the other two is the one that errs."""
    if len(paths) < 2:
        return {}
    t0 = max(t[0] for t, _ in paths.values())
    t1 = min(t[-1] for t, _ in paths.values())
    times = np.arange(t0, t1, AGREE_STEP_S)
    lag = round(MOUNT_LAG_S / AGREE_STEP_S)
    if times.size < lag + 2:
        return {}
    common = {k: np.stack([np.interp(times, t, p[:, 0]), np.interp(times, t, p[:, 1]),
                           np.interp(times, t, np.unwrap(p[:, 2]))], axis=1) for k, (t, p) in paths.items()}
    out = {}
    for a, pa in common.items():
        others = np.mean([as_mounted(pb, fit_mount(pa, pb, lag)) for b, pb in common.items() if b != a], axis=0)
        own = as_mounted(pa, (0.0, 0.0, 0.0))
        off = np.hypot(own[:, 0] - others[:, 0], own[:, 1] - others[:, 1])
        out[a] = {"max_offset_m": round(float(off.max()), 3),
                  "final_heading_deg": round(math.degrees(float(own[-1, 2] - others[-1, 2])), 2)}
    return out


def icp_pose(ref_xy: np.ndarray, cur_xy: np.ndarray, iterations: int = 100, trim: float = 0.8,
             gate_m: float = 0.5) -> np.ndarray:
    """Pose (x, y, yaw) of the points ``cur_xy`` ((m, 2)) in the frame of ``ref_xy`` ((k, 2)), from none:
    point-to-point ICP, each step's pairs the nearest within ``gate_m`` and within the ``trim`` quantile of
    the distances, solved in closed form (a check of the loop, written for the suite: no product code)."""
    from scipy.spatial import cKDTree

    tree = cKDTree(ref_xy)
    x = y = th = 0.0
    for _ in range(iterations):
        c, s = math.cos(th), math.sin(th)
        q = cur_xy @ np.array([[c, s], [-s, c]]) + (x, y)
        d, j = tree.query(q)
        keep = (d <= np.quantile(d, trim)) & (d < gate_m)
        if keep.sum() < 3:
            break
        a, b = q[keep], ref_xy[j[keep]]
        ma, mb = a.mean(axis=0), b.mean(axis=0)
        h = (a - ma).T @ (b - mb)
        turn = math.atan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
        rot = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
        t = mb - rot @ ma
        x, y = rot @ (x, y) + t
        th += turn
        if abs(turn) < 1e-9 and math.hypot(*t) < 1e-9:
            break
    return np.array([x, y, th])


def loop_closure(run: Run, min_range_m: float = ROBOT_REACH_M) -> np.ndarray | None:
    """Where the laser truly ended, in its first scan's frame: each of the last ``LOOP_SCANS`` scans matched
    by ``icp_pose`` to each of the first (returns beyond ``min_range_m``: not the robot's own parts), the
    median pose. For a drive that ends where it began (None for fewer than 2 ``LOOP_SCANS`` scans)."""
    n = len(run.ranges)
    if n < 2 * LOOP_SCANS or run.bearings is None:
        return None
    c, s = np.cos(run.bearings), np.sin(run.bearings)

    def xy(k: int) -> np.ndarray:
        r = run.ranges[k]
        ok = np.isfinite(r) & (r > min_range_m)
        return np.stack([r[ok] * c[ok], r[ok] * s[ok]], axis=1)

    poses = [icp_pose(xy(a), xy(b)) for a in range(LOOP_SCANS) for b in range(n - LOOP_SCANS, n)]
    return np.median(np.array(poses), axis=0)


def end_vs_loop(path: np.ndarray, loop: np.ndarray) -> dict[str, float]:
    """A path's last pose against the loop closure's (both in the first scan's frame)."""
    dth = (path[-1, 2] - loop[2] + math.pi) % (2 * math.pi) - math.pi
    return {"end_vs_loop_closure_m": round(float(math.hypot(*(path[-1, :2] - loop[:2]))), 3),
            "end_heading_vs_loop_closure_deg": round(math.degrees(dth), 2)}


# ---------------------------------------------------------------------------------------------
# the suite


def evaluate_recording(rec: Recording, data_dir: Path, max_scans: int | None = None,
                       leg_model: LegModel | None = None) -> list[dict[str, Any]]:
    """One entry per scan topic evaluated (the drive has three lasers); ``leg_model``: as
    :func:`run_estimator`."""
    bag = data_dir / rec.bag
    topics = scan_topics(bag)
    out = []
    headings: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # kiss-icp's heading per laser (the drive)
    headings_conf: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # the same of the configured reference
    paths: dict[str, LaserPaths] = {}  # per path source, per laser: stamps, poses
    for topic in topics if rec.kind == "drive" else topics[:1]:
        run = run_estimator(bag, topic, max_scans, leg_model=leg_model)
        res: dict[str, Any] = {"recording": rec.name, "topic": topic, "kind": rec.kind, "scans": len(run.cycles),
                               "duration_s": round(60.0 * run.minutes, 2), "sensor": run.sensor,
                               "ms_per_cycle": round(run.ms_per_cycle, 2), **refusal_metrics(run), **report_counts(run)}
        if run.truncation:
            res["truncation"] = run.truncation
        if not run.cycles:  # nothing on the topic (or damaged at once): nothing to score
            out.append(res)
            continue
        labels = read_labels(bag, data_dir / rec.labels) if rec.labels and (data_dir / rec.labels).exists() else None
        res.update(_report_metrics(run, rec, labels))
        for key, moving in (("people", False), ("moving_people", True)):
            pr = _people_run(run, moving)
            res[key] = {**report_counts(pr), **_report_metrics(pr, rec, labels)}
        if rec.kind == "drive":
            res["kiss_icp"] = _kiss(run, headings, paths.setdefault("kiss_icp", {}))
            res["kiss_icp_configured"] = _kiss(run, headings_conf, paths.setdefault("kiss_icp_configured", {}),
                                               min_range_m=ROBOT_REACH_M, deskew=True)
            paths.setdefault("matcher", {})[topic] = (np.array([c.stamp_s for c in run.cycles]),
                                                      np.array([c.pose for c in run.cycles]).reshape(-1, 3))
            if max_scans is None or len(run.cycles) < max_scans:  # the whole drive: it ends where it began
                _loop_figures(res, run, paths)
        out.append(res)
    _heading_agreement(out, headings)
    _heading_agreement(out, headings_conf, "kiss_icp_configured")
    _lasers_agreement(out, paths)
    return out


def _loop_figures(res: dict[str, Any], run: Run, paths: dict[str, LaserPaths]) -> None:
    """The loop closure (``loop_closure``) and each path's end against it: the matcher's under
    ``loop_closure``, each reference's in its own block."""
    loop = loop_closure(run)
    if loop is None:
        return
    est = np.array([c.pose for c in run.cycles]).reshape(-1, 3)
    res["loop_closure"] = {"x_m": round(float(loop[0]), 3), "y_m": round(float(loop[1]), 3),
                           "heading_deg": round(math.degrees(float(loop[2])), 2), **end_vs_loop(est, loop)}
    for src in ("kiss_icp", "kiss_icp_configured"):
        if res.get(src, {}).get("done") and run.topic in paths.get(src, {}):
            res[src].update(end_vs_loop(paths[src][run.topic][1], loop))


def _lasers_agreement(results: list[dict[str, Any]], paths: dict[str, LaserPaths]) -> None:
    """Each path source's lasers against each other (``laser_agreement``): the matcher's under
    ``matcher_vs_other_lasers``, each reference's in its own block as ``vs_other_lasers``."""
    agree = {src: laser_agreement(p) for src, p in paths.items()}
    for r in results:
        topic = r["topic"]
        if topic in agree.get("matcher", {}):
            r["matcher_vs_other_lasers"] = agree["matcher"][topic]
        for src in ("kiss_icp", "kiss_icp_configured"):
            if topic in agree.get(src, {}) and r.get(src, {}).get("done"):
                r[src]["vs_other_lasers"] = agree[src][topic]


def _people_run(run: Run, moving_only: bool) -> Run:
    """The run with ``Estimate.people`` (every person, or the moving ones) in place of the reports."""
    cycles = [Cycle(c.stamp_s, c.pose, [(i, x, y) for i, x, y, mv in c.people if mv or not moving_only], c.fallback,
                    c.reason) for c in run.cycles]
    return Run(run.topic, cycles, run.ranges, run.bearings, run.sensor, run.ms_per_cycle, run.truncation)


def _report_metrics(run: Run, rec: Recording, labels: list[tuple[float, np.ndarray]] | None) -> dict[str, Any]:
    """The background figures (a still laser) and the labelled ones (a labelled recording) of ``run``'s reports."""
    res: dict[str, Any] = {}
    if rec.kind != "drive":
        res.update(background_metrics(run, labels))
    if labels is not None:
        period = run.sensor["scan_period_s"] if run.sensor and run.sensor["scan_period_s"] > 0 else 0.1
        res.update(labelled_metrics(run, labels, period))
    return res


def _kiss(run: Run, headings: dict[str, tuple[np.ndarray, np.ndarray]],
          paths: LaserPaths, min_range_m: float = 0.1, deskew: bool = False) -> dict[str, Any]:
    try:
        ref = kiss_icp_path(run, min_range_m=min_range_m, deskew=deskew)
    except ImportError as exc:
        return {"done": False, "reason": f"kiss-icp is not installed: {exc}"}
    stamps = np.array([c.stamp_s for c in run.cycles])
    headings[run.topic] = (stamps, np.unwrap(ref[:, 2]))
    paths[run.topic] = (stamps, ref)
    return {"done": True, "min_range_m": min_range_m, "deskew": deskew, **path_comparison(run, ref)}


def _heading_agreement(results: list[dict[str, Any]], headings: dict[str, tuple[np.ndarray, np.ndarray]],
                       key: str = "kiss_icp") -> None:
    """The reference checked against itself: lasers on one robot turn alike whatever their mounts, so
    kiss-icp's headings from each laser's scans alone must agree (the largest difference to any other)."""
    for r in results:
        mine = headings.get(r["topic"])
        if mine is None or len(headings) < 2:
            continue
        diffs = [np.abs(np.interp(mine[0], t, y) - mine[1]).max() for k, (t, y) in headings.items() if k != r["topic"]]
        r[key]["heading_vs_other_lasers_max_deg"] = round(math.degrees(float(max(diffs))), 2)


def run_suite(data_dir: Path, only: list[str] | None = None, max_scans: int | None = None,
              leg_model: Path | None = None) -> dict[str, Any]:
    """Every recording of ``data_dir`` (or those ``only`` names) evaluated, with the leg detector stored at
    ``leg_model`` (None: the packaged one; :func:`app.legmodel.load_leg_model` raises on a bad file)."""
    model = default_leg_model() if leg_model is None else load_leg_model(leg_model)
    results, skipped = [], []
    for rec in RECORDINGS:
        if only and rec.name not in only:
            continue
        if not (data_dir / rec.bag).exists():
            skipped.append(rec.name)
            continue
        results.extend(evaluate_recording(rec, data_dir, max_scans, model))
    return {"data_dir": str(data_dir), "leg_model": str(leg_model or default_model_path()), "recordings": results,
            "skipped": skipped}


def print_real_table(suite: dict[str, Any]) -> None:
    """One line per recording and laser (the JSON holds every figure; ``id sw``: the identity switches of
    ``people`` along the labelled trajectories)."""
    def f(v: Any, digits: int = 2) -> str:
        return "-" if v is None else f"{v:.{digits}f}" if isinstance(v, float) else str(v)

    head = (f"{'recording':<46} {'scans':>5} {'refused':>7} {'rep/min':>7} {'bg/min':>6} {'still/min':>9} "
            f"{'walk@.5':>7} {'all@.5':>6} {'all@.3':>6} {'pos m':>5} {'leg m':>5} {'far/min':>7} {'id sw':>5} "
            f"{'kiss max m':>10} {'conf max m':>10}")
    print(head)
    print("-" * len(head))
    for r in suite["recordings"]:
        r5, r3 = r.get("recall_0.5m", {}), r.get("recall_0.3m", {})
        k, kc = r.get("kiss_icp", {}), r.get("kiss_icp_configured", {})
        print(f"{r['recording'] + ' ' + r['topic']:<46} {r['scans']:>5} {f(r['refused_share']):>7} "
              f"{f(r['reports_per_min'], 1):>7} {f(r.get('background_reports_per_min'), 1):>6} "
              f"{f(r.get('still_tracks_per_min')):>9} {f(r5.get('walking')):>7} {f(r5.get('all')):>6} "
              f"{f(r3.get('all')):>6} {f(r.get('person_position_error_median_m')):>5} "
              f"{f(r.get('position_error_median_m')):>5} {f(r.get('far_reports_per_min'), 1):>7} "
              f"{f(r.get('people', {}).get('id_switches')):>5} "
              f"{f(k.get('max_offset_m')):>10} {f(kc.get('max_offset_m')):>10}")
    for name in suite["skipped"]:
        print(f"{name}: skipped (not in {suite['data_dir']})")


# ---------------------------------------------------------------------------------------------
# the leg detector's samples (tools/train_legs.py, app/evaluation/leg_realism.py)

#: a segment's centroid this close to a labelled leg cluster's position is that leg (the label is the
#: centroid of leg_tracker's own cluster of the same returns, so they agree to a few centimetres)
LABEL_M = 0.12
#: the drive through empty rooms (nobody present: every segment is a non-leg) and its three lasers
DRIVE_BAG = "negative_2.bag"
DRIVE_TOPICS = ("/left_scan", "/rear_scan", "/right_scan")


def labelled_leg_rows(data: Path, name: str) -> np.ndarray:
    """Features of the labelled leg segments of the recording ``name`` (``name.bag`` with its labels in
    ``name_extracted.bag``): segments whose centroid lies within ``LABEL_M`` of a labelled leg (a segment
    holding two labelled legs, the legs touching, is one too)."""
    bag = data / f"{name}.bag"
    labels = {round(t, 6): legs for t, legs in read_labels(bag, data / f"{name}_extracted.bag")}
    rows = []
    for bc in read_bag(bag, BagTopics(scan_topics(bag)[0])):
        legs = labels.get(round(bc.scan.stamp_s, 6))
        if legs is None:
            continue
        kept, x = leg_candidates(bc.scan.ranges_m, bc.scan.bearings_rad)
        for (_, _, pts), row in zip(kept, x, strict=True):
            c = pts.mean(axis=0)
            if np.min(np.hypot(legs[:, 0] - c[0], legs[:, 1] - c[1])) <= LABEL_M:
                rows.append(row)
    return np.array(rows).reshape(-1, len(FEATURE_NAMES))


def drive_leg_rows(data: Path) -> tuple[np.ndarray, np.ndarray]:
    """Features of every candidate segment of the drive (nobody present), (first half, second half) by
    time on each laser: training takes the first, validation the second."""
    first, second = [], []
    for topic in DRIVE_TOPICS:
        scans = [(bc.scan.stamp_s, bc.scan.ranges_m, bc.scan.bearings_rad)
                 for bc in read_bag(data / DRIVE_BAG, BagTopics(topic))]
        mid = 0.5 * (scans[0][0] + scans[-1][0])
        for t, r, b in scans:
            (first if t < mid else second).append(leg_candidates(r, b)[1])
    width = len(FEATURE_NAMES)
    return (np.concatenate(first).reshape(-1, width) if first else np.zeros((0, width)),
            np.concatenate(second).reshape(-1, width) if second else np.zeros((0, width)))
