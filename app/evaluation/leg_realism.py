"""The simulated world's legs against the leg detector learned from real scans (issue 29).

    PYTHONPATH=. python -m app.evaluation.leg_realism [--data-dir DIR | --no-real] [--step S] [--json]
                                                      [--geometry utm30lx|leg_tracker|both]

The same leg-candidate segments the estimator and ``tools/train_legs.py`` take (pre-filtered, segmented,
at most ``LegConfig.max_width_m`` wide, at least 3 returns) are scored by the shipped model
(``vipsm/data/legs_model.npz``) and described by their shape features, per range band, for four sets:

* ``real_legs``: the labelled leg segments of the held-out recording ``positive_6`` (never trained on);
* ``real_nonlegs``: every candidate segment of the drive's second half (``negative_2``, never trained on);
* ``sim_legs``: segments of the realistic world's walking people (the world says which beams hit a
  person; a segment counts when most of its returns are that person's);
* ``sim_clutter``: segments on the realistic world's furniture (chair and table legs, bins, posts, boxes:
  the segment's centroid within 5 cm of a piece's footprint), per kind too.

The real recordings come from a 768-beam Hokuyo at 0.3516 deg steps; the simulated UTM-30LX has
0.25 deg steps, so a leg at the same range has about 1.4x as many returns, and its own range noise.
``--geometry leg_tracker`` casts the simulated sweeps on the recordings' beam pattern (the world takes
any beam angles) with the recordings' measured range noise (``LEG_TRACKER_SIGMA_M``) and depth edges
(footprint and pulse: ``hil_fakes.world.laser_effects.LEG_TRACKER_*``), so the world's
bodies are compared with real ones through the same sensor; ``utm30lx`` is the world as the estimator
sees it. ``sensor_noise`` reports both sensors' measured range noise (the recordings' still laser, and
the recorded UTM-30LX frame in ``hokuyo_utm30lx_session``). ``--no-real``: the simulated sets only.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from app.evaluation.real_data import DRIVE_BAG, drive_leg_rows, labelled_leg_rows
from app.legmodel import leg_candidates
from hil_fakes.world import LaserModel, World
from hil_fakes.world.laser_effects import LEG_TRACKER_DIVERGENCE_DEG, LEG_TRACKER_ECHO_SEPARATION_M
from hil_fakes.world.scenarios import Scenario, suite_scenario
from vipsm.legs import FEATURE_NAMES, LegModel

#: range bands (m) of the tables, 1-2 m wide: the returns on a leg fall as 1 / range, so the sets are
#: compared at about the same range (their range distributions differ within wider bands)
BANDS_M = ((0.0, 1.0), (1.0, 2.0), (2.0, 3.0), (3.0, 4.0), (4.0, 6.0), (6.0, 8.0))
HELD_OUT = "positive_6"
#: a segment's centroid this close to a labelled leg cluster is that leg (as in tools/train_legs.py)
#: the suite's scenes with walking people, and the furnished ones (nothing else moves in them)
PEOPLE_SCENES = ("cross_30", "cross_60", "cross_90", "head_on_step_aside", "two_people_opposite",
                 "stand_then_walk", "crowd", "stop_and_go")
CLUTTER_SCENES = ("static_clutter", "lights_off", "cylinder_clutter")
#: the shape features compared side by side (the model's names)
SHAPE = ("n_points", "width_m", "circularity_m", "radius_m", "linearity_m", "std_m", "range_m")
#: the recordings' beam pattern: 768 beams from -135 deg at 2 pi / 1024 (PROVENANCE.md of the data)
LEG_TRACKER_BEAMS = 768
LEG_TRACKER_STEP_RAD = 2 * math.pi / 1024
LEG_TRACKER_PERIOD_S = 1.0 / 7.5
#: the recordings' range noise (sigma, m): the scan-to-scan spread of the still laser's returns on the
#: static background of positive_6 (``recording_noise``: 5.1-6.4 mm at 0-8 m; positive_1: 3.8-3.9 mm)
LEG_TRACKER_SIGMA_M = 0.005


class LegRealismError(ValueError):
    """A bad argument or unreadable data for the leg realism check."""


@dataclass
class Samples:
    """Feature rows of one set of segments, with a label per row (a clutter kind, or the set's name)."""

    rows: list[np.ndarray] = field(default_factory=list)
    kinds: list[str] = field(default_factory=list)

    def add(self, row: np.ndarray, kind: str) -> None:
        self.rows.append(row)
        self.kinds.append(kind)

    def matrix(self) -> np.ndarray:
        return np.array(self.rows).reshape(-1, len(FEATURE_NAMES))


# ------------------------------------------------------------------------------------------ real data
def real_legs(data: Path, name: str = HELD_OUT) -> Samples:
    """The labelled leg segments of a recording (by default the held-out one)."""
    out = Samples()
    for row in labelled_leg_rows(data, name):
        out.add(row, "leg")
    return out


def real_nonlegs(data: Path) -> Samples:
    """Every candidate segment of the drive's second half (by time, per laser): nobody is there."""
    out = Samples()
    for row in drive_leg_rows(data)[1]:
        out.add(row, "drive")
    return out


# ------------------------------------------------------------------------------------------ sensor noise
#: range bands (m) of the noise figures (few returns per band in one frame: coarser than ``BANDS_M``)
NOISE_BANDS_M = ((0.1, 2.0), (2.0, 4.0), (4.0, 8.0))
UTM_SESSION = "hokuyo_utm30lx_session/example_utm_30lx.jsonl"


def recording_noise(data: Path, name: str = HELD_OUT) -> dict[str, Any]:
    """Range noise of the recordings' (still) laser: per beam that sees the static background (within
    5 cm of its median range in 95 % of the scans), the deviations from that median; their standard
    deviation per range band (deviations beyond 5 cm, a person passing, left out)."""
    from app.bagread import BagTopics, read_bag
    from app.evaluation.real_data import scan_topics

    bag = data / f"{name}.bag"
    scans = np.array([bc.scan.ranges_m for bc in read_bag(bag, BagTopics(scan_topics(bag)[0]))])
    finite = np.isfinite(scans)
    med = np.median(np.where(finite, scans, np.inf), axis=0)
    dev = scans - med
    static = np.mean(np.abs(np.nan_to_num(dev, nan=1.0)) < 0.05, axis=0) > 0.95
    out: dict[str, Any] = {"recording": name, "scans": int(scans.shape[0])}
    for lo, hi in NOISE_BANDS_M:
        v = dev[:, static & (med >= lo) & (med < hi)]
        v = v[np.abs(np.nan_to_num(v, nan=1.0)) < 0.05]
        out[f"{lo:g}-{hi:g}m"] = {"returns": int(v.size), "sigma_m": round(float(np.std(v)), 4) if v.size else None}
    return out


def utm30lx_frame_noise(shared: Path) -> dict[str, Any]:
    """Range noise of the recorded UTM-30LX frame (one ME scan of a room, ``hokuyo_utm30lx_session``):
    the second difference of neighbouring beams' ranges is ~0 on a flat or gently curved surface and
    sqrt(6) sigma of the noise, so the 68th percentile of ``|r[i-1] - 2 r[i] + r[i+1]| / sqrt(6)`` per
    range band estimates sigma. An upper bound: surface roughness, corners and the 1 mm resolution count
    too. ``{}`` when the file is absent."""
    from drivers.hokuyo_scip.codec import ScanFrame, ScipDecoder

    path = shared / UTM_SESSION
    if not path.exists():
        return {}
    dec, frames = ScipDecoder(), []
    for line in path.read_text().splitlines():
        rec = json.loads(line)
        if rec["dir"] == "sensor_to_host":
            frames += [e for e in dec.feed(bytes.fromhex(rec["hex"])) if isinstance(e, ScanFrame)]
    if not frames:
        return {}
    r = frames[0].distances.astype(float) / 1000.0
    mid = r[1:-1]
    d2 = np.abs(r[:-2] - 2.0 * mid + r[2:]) / math.sqrt(6.0)
    ok = (r[:-2] > 0.1) & (mid > 0.1) & (r[2:] > 0.1)
    out: dict[str, Any] = {"file": UTM_SESSION, "beams": int(r.size)}
    for lo, hi in NOISE_BANDS_M:
        m = ok & (mid >= lo) & (mid < hi)
        if not m.any():
            out[f"{lo:g}-{hi:g}m"] = {"returns": 0}
            continue
        r_med = float(np.median(mid[m]))
        out[f"{lo:g}-{hi:g}m"] = {"returns": int(m.sum()), "median_range_m": round(r_med, 2),
                                  "sigma_m": round(float(np.quantile(d2[m], 0.68)), 4),
                                  "simulated_sigma_m": round(float(LaserModel().sigma_m(np.array(r_med))), 4)}
    return out


# ------------------------------------------------------------------------------------------ simulation
def beam_pattern(geometry: str, world: World) -> tuple[np.ndarray, float]:
    """The sweep's beam angles (rad) and time between beams (s) for ``geometry``."""
    if geometry == "utm30lx":
        return world.laser.angles_rad(), world.laser.beam_dt_s
    if geometry == "leg_tracker":
        a = -math.radians(135.0) + np.arange(LEG_TRACKER_BEAMS) * LEG_TRACKER_STEP_RAD
        return a, LEG_TRACKER_PERIOD_S / 1024
    raise LegRealismError(f"unknown geometry {geometry!r} (utm30lx, leg_tracker)")


def _laser_pose(world: World, t_s: float) -> tuple[float, float, float]:
    x, y, th = (float(v) for v in world.robot_pose(np.array(t_s)))
    m = world.mount
    c, s = math.cos(th), math.sin(th)
    return x + c * m.laser_x_m - s * m.laser_y_m, y + s * m.laser_x_m + c * m.laser_y_m, th + m.laser_theta_rad


def sweeps(scenario: Scenario, geometry: str, step_s: float) -> Iterator[tuple[World, float, Any, np.ndarray]]:
    """The world's sweeps every ``step_s`` over the scenario, the robot driven as the evaluation drives it
    (``Scenario.command_at``): (world, time, sweep, beam angles)."""
    laser = LaserModel()
    if geometry == "leg_tracker":
        laser = replace(laser, sigma_near_m=LEG_TRACKER_SIGMA_M, sigma_per_range=0.0, sigma_far_m=LEG_TRACKER_SIGMA_M)
        if scenario.laser_effects.enabled:  # that sensor's footprint and pulse (fitted to its edges)
            scenario = replace(scenario, laser_effects=replace(
                scenario.laser_effects, divergence_rad=math.radians(LEG_TRACKER_DIVERGENCE_DEG),
                echo_separation_m=LEG_TRACKER_ECHO_SEPARATION_M))
    world = World(scenario, laser=laser)
    angles, dt = beam_pattern(geometry, world)
    command = scenario.command_at(0.0)
    world.command(*command, 0.0)
    for k in range(int(scenario.duration_s / step_s) + 1):
        t = k * step_s
        if scenario.command_at(t) != command:
            command = scenario.command_at(t)
            world.command(*command, t)
        yield world, t, world.sweep(t, angles, dt), angles


def sim_legs(scenes: Iterable[str], geometry: str, step_s: float) -> Samples:
    """Segments of walking people: most of the segment's returns hit a person (the world's truth)."""
    out = Samples()
    for name in scenes:
        sc = suite_scenario(name)
        people = {i for i, o in enumerate(sc.obstacles) if getattr(o, "gait", None) is not None}
        for _, _, sw, b in sweeps(sc, geometry, step_s):
            kept, x = leg_candidates(sw.ranges_m, b)
            for (a, z, _), row in zip(kept, x, strict=True):
                hit = sw.hit_obstacle[a:z][np.isfinite(sw.ranges_m[a:z])]
                owner = np.bincount(np.maximum(hit, 0)).argmax() if hit.size else -1
                if owner in people and np.mean(hit == owner) > 0.5:
                    out.add(row, "leg")
    return out


def sim_clutter(scenes: Iterable[str], geometry: str, step_s: float) -> Samples:
    """Segments on furniture: no moving body hit, the centroid within 5 cm of a piece's footprint."""
    out = Samples()
    for name in scenes:
        sc = suite_scenario(name)
        pieces = np.array([(x, y, r) for x, y, r, _ in sc.clutter.footprints()]).reshape(-1, 3)
        kinds = [k for *_, k in sc.clutter.footprints()]
        for world, t, sw, b in sweeps(sc, geometry, step_s):
            kept, x = leg_candidates(sw.ranges_m, b)
            lx, ly, lth = _laser_pose(world, t)
            for (a, z, pts), row in zip(kept, x, strict=True):
                if np.any(sw.hit_obstacle[a:z] >= 0) or not pieces.size:
                    continue
                c = pts.mean(axis=0)
                wx = lx + math.cos(lth) * c[0] - math.sin(lth) * c[1]
                wy = ly + math.sin(lth) * c[0] + math.cos(lth) * c[1]
                gap = np.hypot(pieces[:, 0] - wx, pieces[:, 1] - wy) - pieces[:, 2]
                j = int(np.argmin(np.abs(gap)))
                if abs(gap[j]) <= 0.05:
                    out.add(row, kinds[j])
    return out


# ------------------------------------------------------------------------------------------ tables
def band_figures(x: np.ndarray, p: np.ndarray, threshold_p: float) -> dict[str, Any]:
    """Per range band: segments, the leg probability's quartiles, the share at or above the operating
    point, and the median (quartiles) of the shape features."""
    rng = x[:, FEATURE_NAMES.index("range_m")] if x.size else np.zeros(0)
    out: dict[str, Any] = {}
    for lo, hi in BANDS_M:
        m = (rng >= lo) & (rng < hi)
        key = f"{lo:g}-{hi:g}m"
        if not m.any():
            out[key] = {"segments": 0}
            continue
        q = np.quantile(p[m], (0.25, 0.5, 0.75))
        fig: dict[str, Any] = {"segments": int(m.sum()),
                               "p_quartiles": [round(float(v), 3) for v in q],
                               "share_at_operating_point": round(float(np.mean(p[m] >= threshold_p)), 3)}
        for name in SHAPE:
            v = x[m, FEATURE_NAMES.index(name)]
            fig[name] = [round(float(u), 4) for u in np.quantile(v, (0.25, 0.5, 0.75))]
        out[key] = fig
    return out


def range_share(samples: Samples, model: LegModel, lo_m: float, hi_m: float, kinds: Iterable[str] | None = None
                ) -> tuple[int, float | None]:
    """(segments, share at or above the model's operating point) of the samples whose range is in
    [lo_m, hi_m), optionally of the given kinds only (None: no such segment)."""
    x = samples.matrix()
    rng = x[:, FEATURE_NAMES.index("range_m")]
    m = (rng >= lo_m) & (rng < hi_m)
    if kinds is not None:
        m &= np.isin(np.array(samples.kinds, dtype=object), list(kinds))
    if not m.any():
        return 0, None
    return int(m.sum()), float(np.mean(model.predict(x[m]) >= model.threshold_p))


def describe(samples: Samples, model: LegModel, by_kind: bool = False) -> dict[str, Any]:
    x = samples.matrix()
    p = model.predict(x)
    out: dict[str, Any] = {"segments": int(x.shape[0]),
                           "share_at_operating_point": round(float(np.mean(p >= model.threshold_p)), 3)
                           if p.size else None,
                           "bands": band_figures(x, p, model.threshold_p)}
    if by_kind:
        kinds = np.array(samples.kinds)
        out["kinds"] = {k: {"segments": int(np.sum(kinds == k)),
                            "share_at_operating_point": round(float(np.mean(p[kinds == k] >= model.threshold_p)), 3)}
                        for k in sorted(set(samples.kinds))}
    return out


def measure(data: Path | None, geometries: Iterable[str], step_s: float, model: LegModel | None = None
            ) -> dict[str, Any]:
    """The report: the real held-out sets (when ``data`` holds them) and the simulated sets per geometry."""
    from app.legmodel import default_leg_model

    model = model or default_leg_model()
    report: dict[str, Any] = {"threshold_p": round(model.threshold_p, 4), "bands_m": [list(b) for b in BANDS_M],
                              "held_out": HELD_OUT, "drive": "negative_2 second half (held out)"}
    if data is not None:
        report["sensor_noise"] = {"recording": recording_noise(data), "utm30lx": utm30lx_frame_noise(data.parent),
                                  "simulated_leg_tracker_sigma_m": LEG_TRACKER_SIGMA_M}
        report["real_legs"] = describe(real_legs(data), model)
        report["real_nonlegs"] = describe(real_nonlegs(data), model)
    for g in geometries:
        report[f"sim_legs_{g}"] = describe(sim_legs(PEOPLE_SCENES, g, step_s), model)
        report[f"sim_clutter_{g}"] = describe(sim_clutter(CLUTTER_SCENES, g, step_s), model, by_kind=True)
    return report


def table(report: dict[str, Any]) -> str:
    """The report as a Markdown table: per set and band, segments, share at the operating point, median
    leg probability and median shape features."""
    head = ("| set | band | segments | share >= op | p median | n_points | width_m | circ. resid. m | radius_m |\n"
            "|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for name, fig in report.items():
        if not isinstance(fig, dict) or "bands" not in fig:
            continue
        for band, b in fig["bands"].items():
            if not b["segments"]:
                lines.append(f"| {name} | {band} | 0 | | | | | | |")
                continue
            lines.append(f"| {name} | {band} | {b['segments']} | {b['share_at_operating_point']:.2f} | "
                         f"{b['p_quartiles'][1]:.2f} | {b['n_points'][1]:g} | {b['width_m'][1]:.3f} | "
                         f"{b['circularity_m'][1]:.4f} | {b['radius_m'][1]:.3f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m app.evaluation.leg_realism", description=__doc__.split("\n")[0])
    ap.add_argument("--data-dir", type=Path, default=None, help="the real_people_laser folder (default: shared data)")
    ap.add_argument("--geometry", choices=("utm30lx", "leg_tracker", "both"), default="both")
    ap.add_argument("--step", type=float, default=0.2, help="seconds between simulated sweeps (default 0.2)")
    ap.add_argument("--no-real", action="store_true", help="the simulated sets only")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if not 0.01 <= args.step <= 5.0:
        print(f"leg_realism: error: --step must be in [0.01, 5] s, got {args.step}", file=sys.stderr)
        return 2
    data = None
    if not args.no_real:
        from app.cmd_eval import default_real_data_dir

        data = args.data_dir or default_real_data_dir()
        if not (data / DRIVE_BAG).exists() or not (data / f"{HELD_OUT}_extracted.bag").exists():
            print(f"leg_realism: error: no recordings in {data} (--no-real for the simulated sets only)",
                  file=sys.stderr)
            return 2
    geometries = ("utm30lx", "leg_tracker") if args.geometry == "both" else (args.geometry,)
    report = measure(data, geometries, args.step)
    print(json.dumps(report) if args.json else table(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
