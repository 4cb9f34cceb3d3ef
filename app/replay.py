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
from .legmodel import default_leg_model


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
                raise LogFormatError(f"{path}: the recorded configuration does not fit this version: {exc}; replay "
                                     "it with this version's configuration: add --config FILE or --set") from exc
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
    est = Estimator(config, plain_psm=plain_psm, leg_model=default_leg_model())
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


# ---------------------------------------------------------------------------------------------
# ROS bags (:mod:`app.bagread`): ``vipsm-robot replay BAG --scan TOPIC ...``


def add_bag_arguments(p: Any) -> None:
    """The ``replay`` options that apply to a ROS bag (ignored for a field log)."""
    g = p.add_argument_group("ROS bags (a ROS 1 .bag file or a ROS 2 bag folder)")
    g.add_argument("--scan", metavar="TOPIC", help="sensor_msgs/LaserScan topic (required for a bag)")
    g.add_argument("--odom", metavar="TOPIC", help="nav_msgs/Odometry topic; absent: no odometry (the scan "
                   "matcher alone tracks any motion, each cycle predicted where the last one ended)")
    g.add_argument("--image", metavar="TOPIC", help="sensor_msgs/CompressedImage or Image topic")
    g.add_argument("--camera-info", metavar="TOPIC", help="sensor_msgs/CameraInfo topic for the image's intrinsics")
    for name in ("fx", "fy", "cx", "cy"):
        g.add_argument(f"--{name}", type=float, metavar="PX", help=f"intrinsics without --camera-info: {name} in px")
    g.add_argument("--image-width", type=int, metavar="PX", help="with --fx..: the image size they are for "
                   "(default: the image's own)")
    g.add_argument("--image-height", type=int, metavar="PX")
    g.add_argument("--laser-x", type=float, metavar="M", help="laser mount on the robot: x forward (m); "
                   "default estimator.laser_x_m")
    g.add_argument("--laser-y", type=float, metavar="M", help="laser mount: y left (m)")
    g.add_argument("--laser-yaw-deg", type=float, metavar="DEG", help="laser mount: yaw, counter-clockwise (deg)")
    g.add_argument("--max-scans", type=int, metavar="N", help="replay only the first N scans")
    g.add_argument("--log", dest="out_log", metavar="OUT.mcap",
                   help="write a field log of the inputs and estimates (opens in Foxglove; replays as a field log)")


def bag_estimator_config(config: EstimatorConfig, args: Any) -> EstimatorConfig:
    """The estimator configuration with the laser mount flags applied; without ``--odom`` the matcher is
    seeded by constant velocity (``motion_prior``; recorded in the field log, so its replay agrees)."""
    import dataclasses

    changes: dict[str, float | str] = {}
    if not getattr(args, "odom", None):
        changes["motion_prior"] = "constant_velocity"
    if args.laser_x is not None:
        changes["laser_x_m"] = args.laser_x
    if args.laser_y is not None:
        changes["laser_y_m"] = args.laser_y
    if args.laser_yaw_deg is not None:
        changes["laser_theta_rad"] = math.radians(args.laser_yaw_deg)
    bad = [k for k, v in changes.items() if isinstance(v, float) and not math.isfinite(v)]
    if bad:
        from .errors import AppError

        raise AppError(f"the laser mount {bad[0]} must be a finite number")
    return dataclasses.replace(config, **changes)


def flag_intrinsics(args: Any) -> Intrinsics | None:
    """Intrinsics from ``--fx --fy --cx --cy`` (all four or none); size from the flags or the image."""
    from .errors import AppError

    vals = [getattr(args, k) for k in ("fx", "fy", "cx", "cy")]
    if all(v is None for v in vals):
        return None
    if any(v is None for v in vals) or not all(math.isfinite(v) for v in vals) or vals[0] <= 0 or vals[1] <= 0:
        raise AppError("--fx, --fy, --cx and --cy are given together, fx and fy positive")
    w = args.image_width or int(round(2 * vals[2]))
    h = args.image_height or int(round(2 * vals[3]))
    if w < 1 or h < 1:
        raise AppError("--image-width and --image-height must be positive")
    return Intrinsics(vals[0], vals[1], vals[2], vals[3], w, h)


def run_bag_replay(path: str | Path, topics: Any, config: EstimatorConfig, plain_psm: bool = False,
                   intrinsics: Intrinsics | None = None, max_scans: int | None = None, on_cycle: Any = None,
                   ) -> tuple[list[tuple[ReplayCycle, Estimate]], Any]:
    """The estimator over a ROS bag's scans; ``on_cycle(bag_cycle, estimate)`` sees each one (the field
    log writer). Returns the cycles (as replay cycles, for the figures) and the :class:`BagReadResult`."""
    from .bagread import BagReadResult, read_bag

    read = BagReadResult()
    deterministic_opencv()
    est = Estimator(config, plain_psm=plain_psm, leg_model=default_leg_model())
    out: list[tuple[ReplayCycle, Estimate]] = []
    for i, bc in enumerate(read_bag(path, topics, intrinsics, read, max_scans)):
        e = est.step(bc.scan, bc.odometry, bc.frame)
        out.append((ReplayCycle(i + 1, bc.scan, bc.odometry, bc.frame, {}, None), e))
        if on_cycle is not None:
            on_cycle(bc, e)
    return out, read


class BagFieldLog:
    """A field log of a bag's replay, written with the daemon's writer (:class:`app.fieldlog.FieldLog`)
    and its message builders, so it opens in Foxglove and replays as a field log: ``/vipsm/config``
    once, then per scan ``/scan``, ``/odom`` (with an odometry topic), ``/camera/image`` (JPEG images),
    ``/pose``, ``/obstacles``, ``/tf`` and ``/vipsm/cycle``. Message times are the scans' own stamps.
    Offline, nothing may be dropped: ``log`` waits for the writer (finite timeout) instead."""

    #: the writer must take a message within this long, else the replay stops with an error
    STALL_S = 30.0

    def __init__(self, path: str | Path, config: Any) -> None:
        import dataclasses

        from . import logmessages as lm
        from .fieldlog import FieldLog

        self._lm = lm
        self.queue_size = 512
        self.log = FieldLog(str(path), fsync=False, queue_size=self.queue_size).start()
        e = config.estimator
        self._mounts = lm.Mounts(e.laser_x_m, e.laser_y_m, e.laser_theta_rad, e.camera_x_m, e.camera_y_m, e.camera_z_m)
        self._life_s = 0.3
        self.cycle = 0
        self._last_frame_seq = -1
        self._scanner_info = lm.ScannerInfoLog()
        self._put("/vipsm/config", 0.0, {"log_version": lm.LOG_VERSION, **dataclasses.asdict(config)})

    def _pending(self) -> int:
        s = self.log.stats
        return s.enqueued - s.written - s.bad_messages - s.lost_to_disk

    def _put(self, topic: str, wall_s: float, payload: Any) -> None:
        import time

        from .errors import AppError

        deadline = time.monotonic() + self.STALL_S
        while self._pending() >= self.queue_size // 2:
            if self.log.stats.error is not None or time.monotonic() > deadline:
                raise AppError(f"the field log writer stopped: {self.log.stats.error or 'no progress'}")
            time.sleep(0.002)
        if not self.log.log(topic, wall_s, payload):
            raise AppError(f"the field log writer refused a message: {self.log.stats.error or 'queue full'}")

    def __call__(self, bc: Any, est: Estimate) -> None:
        from .daemon import ScanSample, cycle_message, scan_message

        lm, w = self._lm, bc.scan.stamp_s
        self.cycle += 1
        sample = ScanSample(bc.scan)
        si = bc.sensor
        info = lm.scanner_info(bc.scan, None if si is None else (si.range_min_m, si.range_max_m),
                               None if si is None else si.scan_period_s)
        self._scanner_info.before_scan(self._put, w, info)
        self._put("/scan", w, lambda: scan_message(sample, w))
        od = bc.odometry
        if bc.odometry_given:
            self._put("/odom", w, lm.pose_in_frame(od.x_m, od.y_m, od.theta_rad, w))
        image_wall = None
        if bc.frame is not None and bc.jpeg is not None:
            image_wall = bc.frame.stamp_s
            if bc.frame.seq != self._last_frame_seq:  # each image once, however many cycles use it
                self._last_frame_seq = bc.frame.seq
                self._put("/camera/image", image_wall, lm.compressed_image(bc.jpeg, image_wall))
        frame = bc.frame if bc.jpeg is not None else None  # a raw image is not in the log: replay runs without it
        p = est.pose
        self._put("/pose", w, lm.pose_in_frame(p.x_m, p.y_m, p.theta_rad, w))
        obstacles, life = est.obstacles, self._life_s
        self._put("/obstacles", w, lambda: lm.scene_update(obstacles, w, life))
        people = est.people
        self._put("/people", w, lambda: lm.people_scene_update(people, w, life))
        cycle, scan = self.cycle, bc.scan
        self._put("/vipsm/cycle", w, lambda: cycle_message(cycle, scan, od, frame, image_wall, est))
        pose = (p.x_m, p.y_m, p.theta_rad)
        self._put("/tf", w, lambda: lm.robot_transforms(pose, self._mounts, (0.0, 0.0), w))

    def close(self) -> dict[str, Any]:
        self.log.close(timeout_s=60.0)
        s = self.log.stats
        if s.error is not None or s.state == "disk_error":
            from .errors import AppError

            raise AppError(f"the field log {s.files[-1] if s.files else ''} failed: {s.error or s.last_disk_error}")
        return {"path": s.files[-1] if s.files else None, "messages": s.written, "bad_messages": s.bad_messages}


def cmd_replay_bag(args: Any, app_config: Any) -> int:
    """``vipsm-robot replay BAG --scan TOPIC ...``: the summary as for a field log, plus what the bag
    held (``bag``: topics, the laser's geometry from its LaserScan fields). Exit 0, or 3 when messages
    were skipped as malformed or the bag ended in damage part-way (what came before is replayed and
    reported); a bag that cannot be read as asked: exit 2."""
    import dataclasses
    import sys
    import time

    from .bagread import BagTopics
    from .cli import emit
    from .errors import AppError

    if not args.scan:
        raise AppError(f"{args.log}: a ROS bag needs --scan TOPIC (a sensor_msgs/LaserScan topic)")
    if args.max_scans is not None and args.max_scans < 1:
        raise AppError("--max-scans must be >= 1")
    config = dataclasses.replace(app_config, estimator=bag_estimator_config(app_config.estimator, args))
    topics = BagTopics(args.scan, args.odom, args.image, args.camera_info)
    writer = BagFieldLog(args.out_log, config) if args.out_log else None
    t0 = time.perf_counter()
    try:
        results, read = run_bag_replay(args.log, topics, config.estimator, args.plain_psm, flag_intrinsics(args),
                                       args.max_scans, writer)
    finally:
        written = writer.close() if writer is not None else None
    elapsed = time.perf_counter() - t0
    if not results:
        why = f"; {read.bad_messages} malformed, the first: {read.bad[0]}" if read.bad else ""
        raise AppError(f"{args.log}: no scan to replay on {args.scan}{why}")
    summary = bag_summary(results, read, args, elapsed)
    if written is not None:
        summary["field_log"] = written
    if args.plots:
        summary["plots"] = _bag_plots(results, read, topics, config.estimator, args)
    emit(summary, args.json)
    if read.truncated:
        print(f"vipsm-robot: warning: {args.log}: the bag is {read.reason}", file=sys.stderr)
    if read.bad_messages:
        print(f"vipsm-robot: warning: {args.log}: {read.bad_messages} malformed message(s) skipped, the first: "
              f"{read.bad[0]}", file=sys.stderr)
    return 3 if read.bad_messages or read.truncated else 0


def bag_summary(results: list[tuple[ReplayCycle, Estimate]], read: Any, args: Any, elapsed_s: float
                ) -> dict[str, Any]:
    from vipsm.types import EstimateFlag

    n = len(results)
    fallback = sum(1 for _, e in results if e.flags & EstimateFlag.ODOMETRY_FALLBACK)
    tracks = {o.track_id for _, e in results for o in e.obstacles}
    return {
        "log_path": str(args.log),
        "cycles": n,
        "truncated": read.truncated,
        "truncation": read.reason,
        "plain_psm": bool(args.plain_psm),
        "ms_per_cycle": round(1e3 * elapsed_s / n, 3),
        "bad_messages": read.bad_messages,
        "bad_message_reasons": read.bad,
        "bag": {
            "topics": {"scan": args.scan, "odom": args.odom, "image": args.image, "camera_info": args.camera_info},
            "sensor": read.sensor.as_dict() if read.sensor is not None else None,
            "scans": read.scans, "odometry_messages": read.odometry, "frames": read.frames,
            "duration_s": round(results[-1][0].scan.stamp_s - results[0][0].scan.stamp_s, 3),
        },
        "odometry_fallback_share": round(fallback / n, 4),
        "obstacle_reports": sum(len(e.obstacles) for _, e in results),
        "obstacle_tracks": len(tracks),
    }


def _bag_plots(results: list[tuple[ReplayCycle, Estimate]], read: Any, topics: Any, config: EstimatorConfig,
               args: Any) -> list[str]:
    """The figures: the method replayed and the other one over the same scans (VIPSM above plain PSM)."""
    from .plots import write_figures

    other, _ = run_bag_replay(args.log, topics, config, not args.plain_psm, flag_intrinsics(args), args.max_scans)
    vipsm, plain = (other, results) if args.plain_psm else (results, other)
    traces = [replay_trace(vipsm, config, "vipsm"), replay_trace(plain, config, "plain_psm")]
    return [str(p) for p in write_figures(traces, Path(args.plots), Path(args.log).stem, svg=args.svg)]
