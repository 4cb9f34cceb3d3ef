"""Replay a field log through the estimator: ``vipsm-robot replay LOG.mcap``.

The daemon records, per cycle, the estimator's exact inputs on ``/vipsm/cycle`` (scan ranges, the
bearing formula, odometry, frame metadata) and the JPEG on ``/camera/image``. Replay rebuilds the
same ``Scan``, ``Odometry`` and ``Frame`` (the JPEG decoded by the same OpenCV call as live), runs a
fresh estimator, and compares with the recorded estimates: a simulated or real run replays to the
same poses and obstacles exactly.
"""

from __future__ import annotations

import base64
import binascii
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from vipsm.estimator import Estimator, EstimatorConfig
from vipsm.types import Estimate, Frame, Intrinsics, Odometry, Scan

from .errors import LogFormatError
from .fieldlog import LogReadResult, read_log


def deterministic_opencv() -> None:
    """OpenCV single-threaded: its parallel optical flow combines per-thread partial results in
    scheduling order, so under CPU contention two runs on the same inputs can differ in the last
    bits. The daemon and replay both call this, so a replay reproduces live estimates exactly."""
    import cv2

    cv2.setNumThreads(1)


def decode_jpeg(jpeg: bytes) -> np.ndarray:
    """The JPEG decode used live and in replay (grey, as the estimator's optical flow wants)."""
    from drivers.errors import ProtocolError

    from .cmd_camera import decode_jpeg as decode

    try:
        return decode(jpeg, grey=True)
    except ProtocolError as exc:
        raise LogFormatError(str(exc)) from exc


#: a recorded scan longer than this is refused (the UTM-30LX gives 1081 beams, the widest SCIP
#: sensors a few thousand)
MAX_BEAMS = 10_000


def _num(rec: dict[str, Any], key: str) -> float:
    """A finite real number, or ValueError naming the key."""
    v = rec[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ValueError(f"{key!r} is {v!r}, not a finite number")
    return float(v)


def _obj(rec: dict[str, Any], key: str) -> dict[str, Any]:
    v = rec[key]
    if not isinstance(v, dict):
        raise ValueError(f"{key!r} is a {type(v).__name__}, not an object")
    return v


def _int(rec: dict[str, Any], key: str) -> int:
    v = rec[key]
    if isinstance(v, bool) or not isinstance(v, int):
        raise ValueError(f"{key!r} is {v!r}, not an integer")
    return v


def _ranges(values: Any) -> np.ndarray:
    if not isinstance(values, list) or not 1 <= len(values) <= MAX_BEAMS:
        size = len(values) if isinstance(values, list) else type(values).__name__
        raise ValueError(f"'ranges_m' must be a list of 1 to {MAX_BEAMS} values, not {size}")
    if not all(v is None or (isinstance(v, int | float) and not isinstance(v, bool)) for v in values):
        raise ValueError("'ranges_m' holds a value that is neither a number nor null")
    return np.array([math.nan if v is None else v for v in values], dtype=float)


def scan_from_record(rec: dict[str, Any]) -> Scan:
    from .daemon import normalised_bearings

    ranges = _ranges(rec["ranges_m"])
    step = _num(rec, "bearing_step_rad")
    if len(ranges) > 1 and not 0.0 < step <= 2 * math.pi / (len(ranges) - 1):
        raise ValueError(f"'bearing_step_rad' {step!r} does not fit {len(ranges)} beams in one turn")
    return Scan(
        ranges_m=ranges,
        bearings_rad=normalised_bearings(_num(rec, "first_bearing_rad"), step, len(ranges)),
        stamp_s=_num(rec, "stamp_s"),
        seq=_int(rec, "seq"),
        beam_dt_s=_num(rec, "beam_dt_s"),
    )


def odometry_from_record(rec: dict[str, Any]) -> Odometry:
    keys = ("x_m", "y_m", "theta_rad", "v_mps", "w_radps", "stamp_s")
    return Odometry(*(_num(rec, k) for k in keys))


def frame_from_record(rec: dict[str, Any], jpeg: bytes) -> Frame:
    intr = rec["intrinsics"]
    if not isinstance(intr, list) or len(intr) != 6:
        raise ValueError(f"'intrinsics' must be 6 numbers, not {intr!r}"[:200])
    fx, fy, cx, cy, w, h = (_num({"intrinsics": v}, "intrinsics") for v in intr)
    if fx <= 0 or fy <= 0 or not (1 <= w <= 16384 and 1 <= h <= 16384):
        raise ValueError(f"'intrinsics' {intr!r} are not a camera's")
    dist = rec.get("distortion", [0.0, 0.0, 0.0, 0.0])  # logs before it was recorded: pinhole
    if not isinstance(dist, list) or len(dist) != 4:
        raise ValueError(f"'distortion' must be 4 numbers, not {dist!r}"[:200])
    k1, k2, p1, p2 = (_num({"distortion": v}, "distortion") for v in dist)
    return Frame(
        image=decode_jpeg(jpeg),
        stamp_s=_num(rec, "stamp_s"),
        intrinsics=Intrinsics(fx, fy, cx, cy, int(w), int(h), k1, k2, p1, p2),
        pan_rad=_num(rec, "pan_rad"),
        tilt_rad=_num(rec, "tilt_rad"),
        seq=_int(rec, "seq"),
    )


@dataclass
class ReplayCycle:
    cycle: int
    scan: Scan
    odometry: Odometry
    frame: Frame | None
    recorded: dict[str, Any]
    truth: dict[str, Any] | None


def _image_key(data: dict[str, Any], log_time_ns: int) -> tuple[str, int]:
    """Version 2 logs: a frame is found by its image's log time; version 1 by a ``seq`` in the image."""
    return ("seq", int(data["seq"])) if "seq" in data else ("t", log_time_ns)


def _frame_key(fr: dict[str, Any]) -> tuple[str, int]:
    t = fr.get("image_log_time_ns")
    return ("t", int(t)) if t is not None else ("seq", int(fr["seq"]))


def _image_bytes(data: dict[str, Any]) -> bytes:
    raw = data["data"]
    return raw if isinstance(raw, bytes) else base64.b64decode(raw, validate=True)


class _Recent(dict):  # type: ignore[type-arg]
    """The newest entries only (frames and truth wait here for the cycle that uses them)."""

    def put(self, key: Any, value: Any, keep: int = 64) -> None:
        self[key] = value
        if len(self) > keep:
            for k in list(self)[: len(self) - keep // 2]:
                del self[k]


def iter_cycles(path: str | Path, read: LogReadResult | None = None) -> Iterator[ReplayCycle]:
    """The recorded cycles in order. A cycle whose record is malformed is skipped and counted in
    ``read.bad_messages`` (with the reason), never replayed half-built."""
    read = read if read is not None else LogReadResult()
    jpegs, truth_by_stamp = _Recent(), _Recent()
    pending: list[tuple[int, dict[str, Any]]] = []

    def emit(n: int, rec: dict[str, Any]) -> ReplayCycle | None:
        try:
            return cycle_from_record(rec, jpegs, truth_by_stamp)
        except (KeyError, TypeError, ValueError, IndexError, OverflowError, LogFormatError) as exc:
            read.note_bad(f"cycle message {n}: {type(exc).__name__}: {str(exc)[:200]}")
            return None

    # The writer may put a cycle before its frame or truth (different producers); hold cycles
    # until the next cycle arrives, by which time everything logged with them has been seen.
    n = 0
    for msg in read_log(path, read):
        try:
            if msg.topic == "/camera/image":
                jpegs.put(_image_key(msg.data, msg.log_time_ns), _image_bytes(msg.data))
            elif msg.topic == "/truth":
                truth_by_stamp.put(float(msg.data["stamp_s"]), msg.data)
        except (KeyError, TypeError, ValueError, binascii.Error) as exc:
            read.note_bad(f"{msg.topic} message: {type(exc).__name__}: {str(exc)[:200]}")
        if msg.topic == "/vipsm/cycle":
            n += 1
            pending.append((n, msg.data))
            if len(pending) > 1:
                cyc = emit(*pending.pop(0))
                if cyc is not None:
                    yield cyc
    for item in pending:
        cyc = emit(*item)
        if cyc is not None:
            yield cyc


def cycle_from_record(rec: dict[str, Any], jpegs: dict[Any, bytes], truths: dict[float, Any]) -> ReplayCycle:
    """One ``/vipsm/cycle`` record as the estimator's inputs, checked (raises on a malformed one)."""
    fr = rec["frame"]
    frame = None
    if fr is not None:
        fr = _obj(rec, "frame")
        jpeg = jpegs.get(_frame_key(fr))
        if jpeg is None:
            raise LogFormatError(f"cycle {rec['cycle']}: frame {fr['seq']} is not in the log")
        frame = frame_from_record(fr, jpeg)
    scan = scan_from_record(_obj(rec, "scan"))
    return ReplayCycle(
        cycle=_int(rec, "cycle"),
        scan=scan,
        odometry=odometry_from_record(_obj(rec, "odometry")),
        frame=frame,
        recorded=_obj(rec, "estimate"),
        truth=truths.get(scan.stamp_s),
    )


def recorded_estimator_config(path: str | Path) -> EstimatorConfig | None:
    """The estimator configuration the run used (``/vipsm/config``), if the log has it."""
    from .config import from_dict

    for msg in read_log(path):
        if msg.topic == "/vipsm/config":
            try:
                return from_dict(EstimatorConfig, msg.data["estimator"], "estimator.")  # type: ignore[no-any-return]
            except (KeyError, ValueError) as exc:
                raise LogFormatError(f"{path}: the recorded configuration does not fit this version: {exc}") from exc
        if msg.topic == "/vipsm/cycle":
            break
    return None


def recorded_log_version(path: str | Path) -> int:
    """The field-log layout the file was written with (``/vipsm/config``'s ``log_version``; 1 before it
    was recorded)."""
    for msg in read_log(path):
        if msg.topic == "/vipsm/config":
            v = msg.data.get("log_version", 1)
            return v if isinstance(v, int) and not isinstance(v, bool) else 1
        if msg.topic == "/vipsm/cycle":
            break
    return 1


def run_replay(
    path: str | Path,
    config: EstimatorConfig | None = None,
    plain_psm: bool = False,
    progress: Any = None,
) -> tuple[list[tuple[ReplayCycle, Estimate]], LogReadResult]:
    """Runs the estimator over the log's cycles: with ``config``, or else the recorded one."""
    read = LogReadResult()
    deterministic_opencv()
    config = config or recorded_estimator_config(path) or EstimatorConfig()
    est = Estimator(config, plain_psm=plain_psm)
    out: list[tuple[ReplayCycle, Estimate]] = []
    for i, cyc in enumerate(iter_cycles(path, read)):
        out.append((cyc, est.step(cyc.scan, cyc.odometry, cyc.frame)))
        if progress is not None:
            progress(i)
    return out, read


def replay_trace(results: list[tuple[ReplayCycle, Estimate]], mount: EstimatorConfig, label: str) -> Any:
    """A replayed run as a :class:`app.evaluation.traces.RunTrace` for the figures: time from the first
    cycle, poses and obstacles in the odometry frame; the truth (simulated logs) moved there with the
    log's origin."""
    from .evaluation.traces import CycleTrace, RunTrace, scan_endpoints_xy, split_cut, track_point

    cycles = []
    t0 = results[0][0].scan.stamp_s if results else 0.0
    for cyc, est in results:
        pose = (est.pose.x_m, est.pose.y_m, est.pose.theta_rad)
        kept, cut = split_cut(cyc.scan.ranges_m, est.restored_indices)
        true_pose, true_obs = _truth_in_odom(cyc.truth)
        views = () if cyc.truth is None else tuple(len(o) > 6 and bool(o[6]) for o in cyc.truth["obstacles"] if o[5])
        cycles.append(CycleTrace(
            cyc.scan.stamp_s - t0, pose, true_pose, scan_endpoints_xy(kept, cyc.scan.bearings_rad, pose, mount),
            tuple(track_point(o) for o in est.obstacles), true_obs,
            scan_endpoints_xy(cut, cyc.scan.bearings_rad, pose, mount), views))
    return RunTrace(label, tuple(cycles), ())


def _truth_in_odom(truth: dict[str, Any] | None) -> tuple[Any, tuple[tuple[float, float, float], ...]]:
    """The true robot pose and the moving obstacles (x, y, radius) in the odometry frame."""
    if truth is None:
        return None, ()
    ox, oy, oth = (float(v) for v in truth["origin"])
    c, s = math.cos(-oth), math.sin(-oth)

    def to_odom(x: float, y: float) -> tuple[float, float]:
        dx, dy = x - ox, y - oy
        return c * dx - s * dy, s * dx + c * dy

    rx, ry, rth = (float(v) for v in truth["robot"])
    robot = (*to_odom(rx, ry), rth - oth)
    obs = tuple((*to_odom(float(o[0]), float(o[1])), float(o[4])) for o in truth["obstacles"] if o[5])
    return robot, obs
