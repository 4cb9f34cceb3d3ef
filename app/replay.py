"""Replay a field log through the estimator: ``vipsm-robot replay LOG.mcap``.

The daemon records, per cycle, the estimator's exact inputs on ``/vipsm/cycle`` (scan ranges, the
bearing formula, odometry, frame metadata) and the JPEG on ``/camera/image``. Replay rebuilds the
same ``Scan``, ``Odometry`` and ``Frame`` (the JPEG decoded by the same OpenCV call as live), runs a
fresh estimator, and compares with the recorded estimates: a simulated or real run replays to the
same poses and obstacles exactly.
"""

from __future__ import annotations

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


def _nan(values: list[float | None]) -> np.ndarray:
    return np.array([math.nan if v is None else v for v in values], dtype=float)


def scan_from_record(rec: dict[str, Any]) -> Scan:
    from .daemon import normalised_bearings

    ranges = _nan(rec["ranges_m"])
    return Scan(
        ranges_m=ranges,
        bearings_rad=normalised_bearings(rec["first_bearing_rad"], rec["bearing_step_rad"], len(ranges)),
        stamp_s=rec["stamp_s"],
        seq=rec["seq"],
        beam_dt_s=rec["beam_dt_s"],
    )


def odometry_from_record(rec: dict[str, Any]) -> Odometry:
    return Odometry(rec["x_m"], rec["y_m"], rec["theta_rad"], rec["v_mps"], rec["w_radps"], rec["stamp_s"])


def frame_from_record(rec: dict[str, Any], jpeg: bytes) -> Frame:
    fx, fy, cx, cy, w, h = rec["intrinsics"]
    return Frame(
        image=decode_jpeg(jpeg),
        stamp_s=rec["stamp_s"],
        intrinsics=Intrinsics(fx, fy, cx, cy, int(w), int(h)),
        pan_rad=rec["pan_rad"],
        tilt_rad=rec["tilt_rad"],
        seq=rec["seq"],
    )


@dataclass
class ReplayCycle:
    cycle: int
    scan: Scan
    odometry: Odometry
    frame: Frame | None
    recorded: dict[str, Any]
    truth: dict[str, Any] | None


def iter_cycles(path: str | Path, read: LogReadResult | None = None) -> Iterator[ReplayCycle]:
    """The recorded cycles in order; frames are matched to cycles by sequence number."""
    read = read if read is not None else LogReadResult()
    jpegs: dict[int, bytes] = {}
    truth_by_stamp: dict[float, dict[str, Any]] = {}
    pending: list[dict[str, Any]] = []
    import base64

    def emit(rec: dict[str, Any]) -> ReplayCycle:
        fr = rec["frame"]
        frame = None
        if fr is not None:
            jpeg = jpegs.get(fr["seq"])
            if jpeg is None:
                raise LogFormatError(f"cycle {rec['cycle']}: frame {fr['seq']} is not in the log")
            frame = frame_from_record(fr, jpeg)
        return ReplayCycle(
            cycle=rec["cycle"],
            scan=scan_from_record(rec["scan"]),
            odometry=odometry_from_record(rec["odometry"]),
            frame=frame,
            recorded=rec["estimate"],
            truth=truth_by_stamp.get(rec["scan"]["stamp_s"]),
        )

    # The writer may put a cycle before its frame or truth (different producers); hold cycles
    # until the next cycle arrives, by which time everything logged with them has been seen.
    for msg in read_log(path, read):
        if msg.topic == "/camera/image":
            jpegs[msg.data["seq"]] = base64.b64decode(msg.data["data"])
            if len(jpegs) > 64:
                for k in sorted(jpegs)[:-32]:
                    del jpegs[k]
        elif msg.topic == "/truth":
            truth_by_stamp[msg.data["stamp_s"]] = msg.data
            if len(truth_by_stamp) > 64:
                for k in sorted(truth_by_stamp)[:-32]:
                    del truth_by_stamp[k]
        elif msg.topic == "/vipsm/cycle":
            pending.append(msg.data)
            if len(pending) > 1:
                yield emit(pending.pop(0))
    for rec in pending:
        yield emit(rec)


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
