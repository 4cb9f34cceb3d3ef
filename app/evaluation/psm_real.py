"""The polar scan matcher on real recorded scans (what ``vipsm-robot eval-psm`` runs).

Data sets (read in place from ``--data DIR``, normally ``../shared/data``):

* ``psm_diosi_examples/hokuyo_utm_30lx_from_Mohsen_Akbaritabar.txt``: 25 consecutive real UTM-30LX
  scans (1081 ranges in m, 10000 = invalid, a header line first). Consecutive pairs are matched from
  a zero initial guess with the original v0.3 UTM parameters (:meth:`PsmConfig.diosi_v03_utm`) and
  compared with the original's results for the pairs ``shared/protocols/psm.md`` §8.3 lists.
* ``freiburg_slam_benchmark/intel_gfs.json`` + ``intel_corrected_log.json``: 910 Intel Research Lab
  scans (180 ranges at 1 deg, 81.83 = no return) with raw odometry and gmapping-corrected poses.
  Consecutive pairs are seeded with the odometry difference and compared with the corrected relative
  pose. A refused pair is scored with its odometry guess (as psm.md §7 does for the originals).
* ``freiburg_slam_benchmark/csail_gfs.json`` + ``csail_corrected_log.json``: 406 MIT CSAIL scans (361
  ranges at 0.5 deg, 81.91 = no return), scored the same way.

Both Freiburg sets are matched with the preset their geometry selects (``PsmConfig.for_geometry``: 1 deg
``one_degree``, 0.5 deg ``half_degree``: PSM, then point-to-line refinement); ``psm_alone`` repeats the
match without the refinement.

Errors are ``est (-) truth``: the translation norm (m) and the absolute rotation (deg) of the
relative pose of the estimate expressed in the reference's frame.
"""

from __future__ import annotations

import dataclasses
import json
import math
import statistics
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from vipsm.geometry import between
from vipsm.psm import PsmConfig, PsmResult, match, preset_name_for
from vipsm.types import Pose2D, Scan

from ..errors import AppError

DIOSI_FILE = Path("psm_diosi_examples") / "hokuyo_utm_30lx_from_Mohsen_Akbaritabar.txt"
INTEL_RAW = Path("freiburg_slam_benchmark") / "intel_gfs.json"
INTEL_CORRECTED = Path("freiburg_slam_benchmark") / "intel_corrected_log.json"

UTM_BEAMS = 1081
UTM_BEARINGS = np.radians(-135.0 + 0.25 * np.arange(UTM_BEAMS))
DIOSI_INVALID_M = 9999.0  # the file writes 10000 for "no valid return"
INTEL_BEAMS = 180
INTEL_BEARINGS = np.radians(-90.0 + np.arange(INTEL_BEAMS, dtype=float))
INTEL_NO_RETURN_M = 81.8  # the log writes 81.83 for "no return"
CSAIL_RAW = Path("freiburg_slam_benchmark") / "csail_gfs.json"
CSAIL_CORRECTED = Path("freiburg_slam_benchmark") / "csail_corrected_log.json"
CSAIL_BEAMS = 361
CSAIL_BEARINGS = np.radians(-90.0 + 0.5 * np.arange(CSAIL_BEAMS, dtype=float))
CSAIL_NO_RETURN_M = 81.0  # the log writes 81.91 for "no return"; its farthest returns are ~32 m
OVER_M = 0.20

# The original v0.3's results on the Diosi sequence (psm.md §8.3): pair -> (dx cm right, dy cm forward, dtheta deg)
DIOSI_REFERENCE: dict[tuple[int, int], tuple[float, float, float]] = {
    (0, 1): (-0.48, 8.88, 0.95),
    (9, 10): (-9.47, -5.95, 45.98),
    (12, 13): (-0.71, 41.07, 0.61),
    (17, 18): (12.32, -5.99, -44.50),
}
DIOSI_TOL_M = 0.01
DIOSI_TOL_DEG = 0.2


class DataFormatError(AppError):
    """A data file that is missing, truncated or not in the expected format; the message names it."""


# ------------------------------------------------------------------------------------------ readers
def read_diosi_scans(path: Path) -> list[Scan]:
    """The Diosi UTM-30LX text file: a header line, then one scan of 1081 ranges (m) per line."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise DataFormatError(f"{path}: cannot read: {exc}") from exc
    except UnicodeDecodeError as exc:
        raise DataFormatError(f"{path}: not a text file: {exc}") from exc
    lines = text.splitlines()
    if len(lines) < 3:
        raise DataFormatError(f"{path}: expected a header line and at least two scans, got {len(lines)} lines")
    scans: list[Scan] = []
    for lineno, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = line.split()
        if len(fields) != UTM_BEAMS:
            raise DataFormatError(f"{path}:{lineno}: expected {UTM_BEAMS} ranges, got {len(fields)} (truncated?)")
        try:
            r = np.array([float(f) for f in fields])
        except ValueError as exc:
            raise DataFormatError(f"{path}:{lineno}: not a number: {exc}") from exc
        if not np.all(np.isfinite(r)) or np.any(r < 0):
            raise DataFormatError(f"{path}:{lineno}: ranges must be finite and >= 0")
        r[r >= DIOSI_INVALID_M] = np.nan
        r[r <= 0.0] = np.nan
        scans.append(Scan(r, UTM_BEARINGS.copy(), float(len(scans)), seq=len(scans)))
    return scans


@dataclass(frozen=True)
class LoggedScan:
    stamp_s: float
    scan: Scan
    pose: Pose2D


def read_freiburg_json(path: Path, n_beams: int, bearings: np.ndarray, no_return_m: float) -> list[LoggedScan]:
    """``{"map": {"<stamp>": {"range": [...], "x": .., "y": .., "theta": ..}}}``, sorted by stamp."""
    try:
        with path.open("r", encoding="utf-8") as fh:
            doc = json.load(fh)
    except OSError as exc:
        raise DataFormatError(f"{path}: cannot read: {exc}") from exc
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataFormatError(f"{path}: not valid JSON (truncated?): {exc}") from exc
    if not isinstance(doc, dict) or not isinstance(doc.get("map"), dict) or not doc["map"]:
        raise DataFormatError(f'{path}: expected an object with a non-empty "map" object')
    out: list[LoggedScan] = []
    for key, entry in doc["map"].items():
        try:
            stamp = float(key)
        except ValueError as exc:
            raise DataFormatError(f"{path}: scan key {key!r} is not a timestamp") from exc
        if not isinstance(entry, dict):
            raise DataFormatError(f"{path}: scan {key}: not an object")
        try:
            r = np.asarray(entry["range"], dtype=float)
            x, y, th = float(entry["x"]), float(entry["y"]), float(entry["theta"])
        except KeyError as exc:
            raise DataFormatError(f"{path}: scan {key}: missing field {exc}") from exc
        except (TypeError, ValueError) as exc:
            raise DataFormatError(f"{path}: scan {key}: bad value: {exc}") from exc
        if r.shape != (n_beams,):
            raise DataFormatError(f"{path}: scan {key}: expected {n_beams} ranges, got {r.size}")
        if not (np.all(np.isfinite(r)) and math.isfinite(x) and math.isfinite(y) and math.isfinite(th)):
            raise DataFormatError(f"{path}: scan {key}: non-finite values")
        r = r.copy()
        r[(r >= no_return_m) | (r <= 0.0)] = np.nan
        out.append(LoggedScan(stamp, Scan(r, bearings.copy(), stamp), Pose2D(x, y, th)))
    out.sort(key=lambda s: s.stamp_s)
    return out


# ------------------------------------------------------------------------------------------ evaluation
def _err(truth: Pose2D, est: Pose2D) -> tuple[float, float]:
    e = between(truth, est)
    return math.hypot(e.x_m, e.y_m), abs(math.degrees(e.theta_rad))


def _pair_row(i: int, j: int, res: PsmResult, ms: float) -> dict[str, Any]:
    return {
        "pair": [i, j],
        "dx_m": round(res.dx_m, 5),
        "dy_m": round(res.dy_m, 5),
        "dtheta_rad": round(res.dtheta_rad, 6),
        "refused": res.refused,
        "reason": res.reason.value,
        "iterations": res.iterations,
        "beams_used": res.beams_used,
        "ms": round(ms, 3),
    }


def _summary(trans: list[float], rot: list[float], refused: int, times_ms: list[float]) -> dict[str, Any]:
    t = np.asarray(trans)
    return {
        "median_trans_err_m": round(float(np.median(t)), 5) if t.size else None,
        "median_rot_err_deg": round(float(np.median(rot)), 4) if rot else None,
        "p90_trans_err_m": round(float(np.percentile(t, 90)), 5) if t.size else None,
        "share_over_0_20m": round(float(np.mean(t > OVER_M)), 4) if t.size else None,
        "refused": refused,
        "ms_per_match_median": round(statistics.median(times_ms), 3) if times_ms else None,
    }


def eval_diosi(path: Path, per_pair: bool) -> dict[str, Any]:
    scans = read_diosi_scans(path)
    cfg = PsmConfig.diosi_v03_utm()
    rows, trans, rot, times = [], [], [], []
    refused = 0
    reference = []
    for i in range(len(scans) - 1):
        t0 = time.perf_counter()
        res = match(scans[i], scans[i + 1], Pose2D(0.0, 0.0, 0.0), cfg)
        ms = 1000.0 * (time.perf_counter() - t0)
        times.append(ms)
        refused += int(res.refused)
        rows.append(_pair_row(i, i + 1, res, ms))
        ref = DIOSI_REFERENCE.get((i, i + 1))
        if ref is not None:
            # the original: x right, y forward (cm); here x forward, y left (m)
            truth = Pose2D(ref[1] / 100.0, -ref[0] / 100.0, math.radians(ref[2]))
            et, er = _err(truth, res.pose)
            trans.append(et)
            rot.append(er)
            reference.append(
                {
                    "pair": [i, i + 1],
                    "dx_m": round(res.dx_m, 4),
                    "dy_m": round(res.dy_m, 4),
                    "dtheta_deg": round(math.degrees(res.dtheta_rad), 3),
                    "original_dx_m": truth.x_m,
                    "original_dy_m": truth.y_m,
                    "original_dtheta_deg": ref[2],
                    "dev_m": round(et, 4),
                    "dev_deg": round(er, 3),
                }
            )
    out: dict[str, Any] = {
        "file": str(path),
        "pairs": len(scans) - 1,
        "initial_guess": "zero",
        "config": "PsmConfig.diosi_v03_utm()",
        "compared_with": "original PSM v0.3 results (psm.md 8.3), not ground truth",
        "reference_pairs": len(reference),
        **_summary(trans, rot, refused, times),
        "max_dev_m": round(max(trans), 4) if trans else None,
        "max_dev_deg": round(max(rot), 3) if rot else None,
        "within_tolerance": bool(trans) and max(trans) <= DIOSI_TOL_M and max(rot) <= DIOSI_TOL_DEG,
        "reference": reference,
    }
    if per_pair:
        out["per_pair"] = rows
    return out


def eval_intel(raw_path: Path, corrected_path: Path, per_pair: bool) -> dict[str, Any]:
    return eval_freiburg(raw_path, corrected_path, INTEL_BEAMS, INTEL_BEARINGS, INTEL_NO_RETURN_M, per_pair)


def eval_csail(raw_path: Path, corrected_path: Path, per_pair: bool) -> dict[str, Any]:
    return eval_freiburg(raw_path, corrected_path, CSAIL_BEAMS, CSAIL_BEARINGS, CSAIL_NO_RETURN_M, per_pair)


def eval_freiburg(raw_path: Path, corrected_path: Path, n_beams: int, bearings: np.ndarray, no_return_m: float,
                  per_pair: bool) -> dict[str, Any]:
    """Consecutive pairs seeded with odometry, matched with the preset the scans' geometry selects
    (:meth:`PsmConfig.for_geometry`), scored against the corrected poses; ``psm_alone``: the same preset
    without the point-to-line refinement (and a pair PSM refuses scored as its odometry guess)."""
    raw = read_freiburg_json(raw_path, n_beams, bearings, no_return_m)
    cor = read_freiburg_json(corrected_path, n_beams, bearings, no_return_m)
    cor_by_stamp = {s.stamp_s: s.pose for s in cor}
    missing = [s.stamp_s for s in raw if s.stamp_s not in cor_by_stamp]
    if missing:
        raise DataFormatError(f"{corrected_path}: {len(missing)} scans of {raw_path.name} have no corrected pose")
    step = float(bearings[1] - bearings[0])
    preset = preset_name_for(step, no_return_m)
    cfg = PsmConfig.preset(preset)
    alone = dataclasses.replace(cfg, refine_iterations=0, refine_refused=False)
    rows, trans, rot, times = [], [], [], []
    odo_trans, odo_rot, alone_trans, alone_rot = [], [], [], []
    refused = alone_refused = 0
    for i in range(len(raw) - 1):
        a, b = raw[i], raw[i + 1]
        guess = between(a.pose, b.pose)
        truth = between(cor_by_stamp[a.stamp_s], cor_by_stamp[b.stamp_s])
        t0 = time.perf_counter()
        res = match(a.scan, b.scan, guess, cfg)
        ms = 1000.0 * (time.perf_counter() - t0)
        times.append(ms)
        refused += int(res.refused)
        et, er = _err(truth, res.pose)  # a refused result carries the guess: scored as odometry
        trans.append(et)
        rot.append(er)
        ot, orr = _err(truth, guess)
        odo_trans.append(ot)
        odo_rot.append(orr)
        res0 = match(a.scan, b.scan, guess, alone)
        alone_refused += int(res0.refused)
        e0 = _err(truth, res0.pose)
        alone_trans.append(e0[0])
        alone_rot.append(e0[1])
        if per_pair:
            row = _pair_row(i, i + 1, res, ms)
            row.update({"err_m": round(et, 5), "err_deg": round(er, 4)})
            rows.append(row)
    out: dict[str, Any] = {
        "files": [str(raw_path), str(corrected_path)],
        "pairs": len(raw) - 1,
        "initial_guess": "odometry",
        "config": f'PsmConfig.preset("{preset}")',
        "compared_with": "gmapping-corrected poses (an estimate, not ground truth)",
        **_summary(trans, rot, refused, times),
        "refused_scored_as": "odometry guess",
        "odometry_median_trans_err_m": round(float(np.median(odo_trans)), 5),
        "odometry_median_rot_err_deg": round(float(np.median(odo_rot)), 4),
        "psm_alone": {
            "median_trans_err_m": round(float(np.median(alone_trans)), 5),
            "median_rot_err_deg": round(float(np.median(alone_rot)), 4),
            "p90_trans_err_m": round(float(np.percentile(alone_trans, 90)), 5),
            "refused": alone_refused,
        },
    }
    if per_pair:
        out["per_pair"] = rows
    return out


# ---------------------------------------------------------------------------------------------
# speed on real scans (``vipsm-robot bench --only estimator``)


def _timed(pairs: list[tuple[Scan, Scan, Pose2D]], cfg: PsmConfig, repetitions: int) -> dict[str, float]:
    """Per-match wall time over ``repetitions`` passes: ``match`` (both scans preprocessed in the
    call) and ``match_prepared`` (the scans preprocessed beforehand, as the estimator keeps them)."""
    from vipsm.psm import match_prepared, prepare

    whole, matched = [], []
    prepared = [(prepare(a, cfg), prepare(b, cfg), g) for a, b, g in pairs]
    for _ in range(repetitions):
        for a, b, guess in pairs:
            t0 = time.perf_counter()
            match(a, b, guess, cfg)
            whole.append(1000.0 * (time.perf_counter() - t0))
        for ra, rb, guess in prepared:
            t0 = time.perf_counter()
            match_prepared(ra, rb, guess, cfg)
            matched.append(1000.0 * (time.perf_counter() - t0))
    return {
        "ms_median": round(statistics.median(whole), 3),
        "ms_p90": round(float(np.percentile(whole, 90)), 3),
        "ms_prepared_median": round(statistics.median(matched), 3),
        "ms_prepared_p90": round(float(np.percentile(matched, 90)), 3),
    }


def bench_real(data: Path, repetitions: int = 20) -> dict[str, Any]:
    """PSM speed on the real scans: the 24 consecutive Diosi UTM-30LX pairs from a zero guess at
    the original v0.3 parameters and at this project's defaults, the 909 Intel pairs seeded with
    odometry at ``PsmConfig.sick_1deg()`` and at the ``one_degree`` preset (PSM + refinement), and the
    405 CSAIL pairs at ``half_degree`` (Freiburg sets: ``repetitions // 10`` passes). Missing data: a reason."""
    out: dict[str, Any] = {}
    diosi = data / DIOSI_FILE
    if diosi.exists():
        scans = read_diosi_scans(diosi)
        pairs = [(scans[i], scans[i + 1], Pose2D(0.0, 0.0, 0.0)) for i in range(len(scans) - 1)]
        for name, cfg in (("v03", PsmConfig.diosi_v03_utm()), ("default", PsmConfig())):
            out.update({f"psm_real_utm_{name}_{k}": v for k, v in _timed(pairs, cfg, repetitions).items()})
        out["psm_real_utm_pairs"] = len(pairs)
    else:
        out["psm_real_utm_skipped"] = f"{diosi} not found"
    raw = data / INTEL_RAW
    if raw.exists():
        logged = read_freiburg_json(raw, INTEL_BEAMS, INTEL_BEARINGS, INTEL_NO_RETURN_M)
        pairs = [(a.scan, b.scan, between(a.pose, b.pose)) for a, b in zip(logged, logged[1:])]
        timed = _timed(pairs, PsmConfig.sick_1deg(), max(1, repetitions // 10))
        out.update({f"psm_real_intel_{k}": v for k, v in timed.items()})
        timed = _timed(pairs, PsmConfig.preset("one_degree"), max(1, repetitions // 10))
        out.update({f"psm_real_intel_preset_{k}": v for k, v in timed.items()})
        out["psm_real_intel_pairs"] = len(pairs)
    else:
        out["psm_real_intel_skipped"] = f"{raw} not found"
    raw = data / CSAIL_RAW
    if raw.exists():
        logged = read_freiburg_json(raw, CSAIL_BEAMS, CSAIL_BEARINGS, CSAIL_NO_RETURN_M)
        pairs = [(a.scan, b.scan, between(a.pose, b.pose)) for a, b in zip(logged, logged[1:])]
        timed = _timed(pairs, PsmConfig.preset("half_degree"), max(1, repetitions // 10))
        out.update({f"psm_real_csail_preset_{k}": v for k, v in timed.items()})
        out["psm_real_csail_pairs"] = len(pairs)
    else:
        out["psm_real_csail_skipped"] = f"{raw} not found"
    return out
