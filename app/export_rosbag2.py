"""A field log as a ROS 2 bag (``vipsm-robot export LOG.mcap --rosbag2 OUT_DIR``), written with the
pure-Python ``rosbags`` package, so a ROS 2 user can ``ros2 bag play`` it without this program.

==================  ================================  ===============================================
topic               type                              from
==================  ================================  ===============================================
``/scan``           ``sensor_msgs/msg/LaserScan``     ``/scan`` + ``/vipsm/scanner`` (REP 117 ranges kept)
``/odom``           ``nav_msgs/msg/Odometry``         ``/odom`` wheel odometry (+ speeds from cycles)
``/vipsm/pose``     ``nav_msgs/msg/Odometry``         the estimated pose with its covariance
``/camera/image/compressed``  ``sensor_msgs/msg/CompressedImage``  ``/camera/image``
``/vipsm/obstacles``  ``visualization_msgs/msg/MarkerArray``  cylinders + velocity arrows
``/tf``             ``tf2_msgs/msg/TFMessage``        odom->base_link, base_link->camera, world->...
``/tf_static``      ``tf2_msgs/msg/TFMessage``        base_link->laser, once (transient local)
==================  ================================  ===============================================

A ``/scan`` message takes its bearings from itself and its ``range_min``/``range_max``,
``time_increment`` and ``scan_time`` from the newest ``/vipsm/scanner`` record before it (the scanner's
own values: the UTM-30LX's PP reply live and in ``sim``, a bag's LaserScan fields in ``replay BAG
--log``), never from one scanner model. A log written before that channel (log version 1 or 2), or a
scan that does not fit the record (another beam count or window), is exported with range_min 0 and
range_max +inf (the log's ranges already mark invalid readings +-inf or NaN, REP 117), the beam time
of the log's first ``/vipsm/cycle`` with as many beams and as scan time the median spacing of the
scans' stamps (0, ROS's "unknown", where the log gives neither); that is said once per beam count
(``ExportResult.warnings``) and the scans counted (``scan_info``).

Frames follow REP 105 (``odom``, ``base_link``, ``laser``); header stamps are the messages' own
stamps, bag times the log times. Version 1 logs (no ``/tf``) export without transforms.

Each topic offers the QoS that ``ros2 bag record`` writes for a publisher with ROS 2's default
profile (reliable, volatile; ``/tf_static`` transient local, as tf2's static broadcaster), in the
bag-format-8 encoding rosbag2 uses from Humble on (enums as integers, infinite durations as
``RMW_DURATION_INFINITE``), so ``ros2 bag play`` offers them again.

Covariances (``nav_msgs/msg/Odometry``, row-major 6x6 over x, y, z, roll, pitch, yaw): ``/vipsm/pose``
carries the estimator's x/y/yaw pose covariance; ``/odom`` (wheel odometry, which measures none) the
estimator's own dead-reckoning model: a standard deviation of ``estimator.odom_sigma_per_m`` per metre
driven in x and y and ``estimator.odom_sigma_rad_per_rad`` per radian turned in yaw, accumulated from
the start (values from the log's ``/vipsm/config``); twists the same per unit of speed. The axes a
planar robot does not observe (z, roll, pitch and their rates), and any value the log lacks, get
``UNOBSERVED_VARIANCE`` (1e6: "ignore", as planar odometry publishers do), never -1.

The bag is written into a hidden folder beside ``OUT_DIR`` and renamed to it only when complete, so
``OUT_DIR`` exists only as a whole bag; the partial folder of a killed export is removed by the next
export to the same ``OUT_DIR``. A message that cannot be read or converted is skipped and counted
(``read.bad_messages``), a damaged chunk too (``read.bad_chunks``), as in ``replay``.
"""

from __future__ import annotations

import contextlib
import fcntl
import math
import os
import shutil
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import AppError
from .logread import LogMessage, LogReadResult, read_log

TOPICS = {
    "/scan": "sensor_msgs/msg/LaserScan",
    "/odom": "nav_msgs/msg/Odometry",
    "/vipsm/pose": "nav_msgs/msg/Odometry",
    "/camera/image/compressed": "sensor_msgs/msg/CompressedImage",
    "/vipsm/obstacles": "visualization_msgs/msg/MarkerArray",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
}
STATIC_CHILDREN = ("laser",)


#: variance of an axis the data does not observe (z, roll, pitch; a value the log lacks)
UNOBSERVED_VARIANCE = 1e6
#: the smallest standard deviations given (before the robot has moved the model's own would be 0,
#: a singular matrix a filter cannot invert): 1 mm and 0.001 rad, the encoders' order of resolution
MIN_SIGMA_M = 1e-3
MIN_SIGMA_RAD = 1e-3
#: log topics with no ROS 2 counterpart here (counted in ``ExportResult.not_exported``, not errors)
NOT_EXPORTED = ("/pose", "/obstacles", "/log", "/diagnostics", "/truth", "/vipsm/config", "/vipsm/scanner")
#: the schema each exported log topic must carry
EXPECTED_SCHEMA = {"/scan": "foxglove.LaserScan", "/odom": "foxglove.PoseInFrame", "/tf": "foxglove.FrameTransforms",
                   "/camera/image": "foxglove.CompressedImage", "/vipsm/cycle": "vipsm.Cycle"}


@dataclass
class ExportResult:
    out_dir: str
    counts: Counter[str] = field(default_factory=Counter)
    not_exported: Counter[str] = field(default_factory=Counter)
    read: LogReadResult = field(default_factory=LogReadResult)
    #: ``/scan`` messages whose limits and timing came from the log's ``/vipsm/scanner`` ("recorded") or
    #: were assumed (an old log without it, or a scan that does not fit it: "assumed")
    scan_info: Counter[str] = field(default_factory=Counter)
    #: what was assumed, each said once (printed on stderr, in the JSON summary)
    warnings: list[str] = field(default_factory=list)


#: a /scan fits a /vipsm/scanner record when its beam count is the record's and its first and last
#: bearings are the record's within this (both are written from the same bearings: any difference is
#: another scanner or window)
ANGLE_TOL_RAD = 1e-6


@dataclass
class _Scanner:
    """The limits and timing of the log's scans: the newest ``/vipsm/scanner`` record, and for scans
    without one (logs before version 3) the assumption of :func:`legacy_scan_info`."""

    log_path: str
    result: ExportResult
    info: dict[str, Any] | None = None
    legacy: dict[int, dict[str, Any]] = field(default_factory=dict)  # beams -> assumed record
    malformed: bool = False  # the newest record could not be read

    def record(self, d: dict[str, Any]) -> None:
        """A new record (ValueError, KeyError, TypeError if malformed: the scans after it are then assumed,
        never given an older scanner's values)."""
        self.info, self.malformed = None, True
        keys = ("beams", "angle_min_rad", "angle_max_rad", "time_increment_s", "scan_time_s")
        for k in keys:
            v = d[k]
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ValueError(f"{k!r} is {v!r}, not a finite number")
        for k in ("range_min_m", "range_max_m"):
            if d[k] is not None and (isinstance(d[k], bool) or not isinstance(d[k], int | float)):
                raise ValueError(f"{k!r} is {d[k]!r}, not a number or null")
        self.info, self.malformed = d, False

    def for_scan(self, n: int, first_rad: float, last_rad: float) -> dict[str, Any]:
        i = self.info
        if i is not None and i["beams"] == n and abs(i["angle_min_rad"] - first_rad) <= ANGLE_TOL_RAD \
                and abs(i["angle_max_rad"] - last_rad) <= ANGLE_TOL_RAD:
            self.result.scan_info["recorded"] += 1
            return i
        self.result.scan_info["assumed"] += 1
        if n not in self.legacy:
            self.legacy[n] = legacy_scan_info(self.log_path, n)
            why = ("the /vipsm/scanner before it is malformed" if self.malformed else
                   "the log has no /vipsm/scanner before it (written before log version 3)" if i is None else
                   f"it does not fit the /vipsm/scanner before it ({i['beams']} beams from {i['angle_min_rad']:.6f} "
                   f"to {i['angle_max_rad']:.6f} rad)")
            a = self.legacy[n]
            self.result.warnings.append(
                f"{self.log_path}: /scan with {n} beams: {why}; exported with range_min 0 and range_max +inf (every "
                f"finite range in the log is a reading: it marks invalid ones +-inf or NaN), {a['said']}")
        return self.legacy[n]


def legacy_scan_info(log_path: str | Path, n_beams: int) -> dict[str, Any]:
    """What is assumed for a scan the log states no limits or timing for: no limits (``range_min`` 0,
    ``range_max`` +inf: the log's ranges already mark invalid readings); ``time_increment`` the
    ``beam_dt_s`` of the log's first ``/vipsm/cycle`` with as many beams (the estimator's exact input);
    ``scan_time`` the median spacing of the stamps of the log's first ``LEGACY_STAMPS`` such ``/scan``
    messages (the time between scans, measured; a dropped scan is an outlier the median ignores), else
    one turn of the mirror from the beam timing; what neither gives is 0 (ROS's "unknown")."""
    from vipsm.sensor import scan_period_from_stamps, scan_period_s

    timing: tuple[float, float] | None = None  # (beam_dt_s, bearing_step_rad) of the first fitting cycle
    stamps: list[float] = []
    for k, msg in enumerate(read_log(log_path)):
        if k >= LEGACY_SEARCH_MESSAGES or (timing is not None and len(stamps) >= LEGACY_STAMPS):
            break
        if msg.topic == "/scan" and len(stamps) < LEGACY_STAMPS and len(msg.data.get("ranges", ())) == n_beams:
            ts = msg.data.get("timestamp") or {}
            stamps.append(float(ts.get("sec", 0)) + 1e-9 * float(ts.get("nsec", 0)))
        elif timing is None and msg.topic == "/vipsm/cycle":
            timing = _cycle_timing(msg.data, n_beams)
    dt, step = timing if timing is not None else (0.0, 0.0)
    measured = scan_period_from_stamps(np.asarray(stamps))
    period = measured or scan_period_s(dt, step)
    said = ["time_increment " + (f"{dt:.6g} s from the log's /vipsm/cycle" if timing else "0 (unknown: no "
                                 "/vipsm/cycle with as many beams)"),
            "scan_time " + (f"{period:.6g} s, " + (f"the median spacing of {len(stamps)} scans' stamps" if measured
                                                   else "one turn from the beam timing") if period else "0 (unknown)")]
    return {"range_min_m": 0.0, "range_max_m": math.inf, "time_increment_s": dt, "scan_time_s": period,
            "said": "; ".join(said)}


def _cycle_timing(rec: Any, n_beams: int) -> tuple[float, float] | None:
    """(beam_dt_s, bearing_step_rad) of a cycle record whose scan has ``n_beams`` beams, else None."""
    sc = rec.get("scan") if isinstance(rec, dict) else None
    if not isinstance(sc, dict) or not isinstance(sc.get("ranges_m"), list) or len(sc["ranges_m"]) != n_beams:
        return None
    dt, step = sc.get("beam_dt_s"), sc.get("bearing_step_rad")
    ok = all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in (dt, step))
    return (float(dt), float(step)) if ok else None


#: how far into a log :func:`legacy_scan_info` looks (a cycle is logged every 0.1 s, after a few messages
#: of each other channel: thousands of messages are many seconds of a run), and how many scans it times
LEGACY_SEARCH_MESSAGES = 20_000
LEGACY_STAMPS = 50


@dataclass
class _Odometry:
    """The dead-reckoning uncertainty model of the module docstring, fed with every ``/odom`` pose."""

    sigma_per_m: float = 0.05
    sigma_rad_per_rad: float = 0.05
    driven_m: float = 0.0
    turned_rad: float = 0.0
    last: tuple[float, float, float] | None = None
    speeds: tuple[float, float] | None = None  # (v_mps, w_radps) of the newest cycle

    def configure(self, config: dict[str, Any]) -> None:
        est = config.get("estimator", {})
        self.sigma_per_m = float(est.get("odom_sigma_per_m", self.sigma_per_m))
        self.sigma_rad_per_rad = float(est.get("odom_sigma_rad_per_rad", self.sigma_rad_per_rad))

    def add(self, x: float, y: float, yaw: float) -> None:
        if self.last is not None:
            self.driven_m += math.hypot(x - self.last[0], y - self.last[1])
            self.turned_rad += abs(math.remainder(yaw - self.last[2], math.tau))
        self.last = (x, y, yaw)

    def pose_sigmas(self) -> tuple[float, float, float]:
        s = max(MIN_SIGMA_M, self.sigma_per_m * self.driven_m)
        return s, s, max(MIN_SIGMA_RAD, self.sigma_rad_per_rad * self.turned_rad)

    def twist_sigmas(self) -> tuple[float, float] | None:
        if self.speeds is None:
            return None
        v, w = self.speeds
        return max(MIN_SIGMA_M, self.sigma_per_m * abs(v)), max(MIN_SIGMA_RAD, self.sigma_rad_per_rad * abs(w))


class _Bag:
    """The rosbags writer, its connections and the typestore's message classes."""

    def __init__(self, out_dir: Path) -> None:
        from rosbags.rosbag2 import Writer
        from rosbags.typesys import Stores, get_typestore

        self.ts = get_typestore(Stores.ROS2_HUMBLE)
        self.t = self.ts.types
        self.writer = Writer(out_dir, version=8)
        self.conns: dict[str, Any] = {}
        self.odometry = _Odometry()
        self.scanner: _Scanner | None = None

    def __enter__(self) -> _Bag:
        self.writer.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.writer.close()

    def write(self, topic: str, log_time_ns: int, msg: Any) -> None:
        conn = self.conns.get(topic)
        if conn is None:
            conn = self.writer.add_connection(topic, TOPICS[topic], typestore=self.ts,
                                              offered_qos_profiles=offered_qos(latched=topic == "/tf_static"))
            self.conns[topic] = conn
        self.writer.write(conn, log_time_ns, self.ts.serialize_cdr(msg, TOPICS[topic]))

    # -- message pieces ---------------------------------------------------------------------

    def header(self, stamp: dict[str, int], frame_id: str) -> Any:
        return self.t["std_msgs/msg/Header"](stamp=self.t["builtin_interfaces/msg/Time"](
            sec=int(stamp["sec"]), nanosec=int(stamp["nsec"])), frame_id=frame_id)

    def vec(self, x: float, y: float, z: float) -> Any:
        return self.t["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))

    def point(self, x: float, y: float, z: float) -> Any:
        return self.t["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=float(z))

    def quat(self, q: dict[str, float]) -> Any:
        return self.t["geometry_msgs/msg/Quaternion"](x=q["x"], y=q["y"], z=q["z"], w=q["w"])

    def pose(self, p: dict[str, Any]) -> Any:
        pos = p["position"]
        return self.t["geometry_msgs/msg/Pose"](position=self.point(pos["x"], pos["y"], pos["z"]),
                                                orientation=self.quat(p["orientation"]))


def offered_qos(latched: bool) -> list[Any]:
    """What ``ros2 bag record`` writes for a publisher with ROS 2's default profile (``latched``: the
    transient-local profile of a static-transform broadcaster): history unknown and depth 0 (DDS
    discovery does not carry them), reliable, volatile or transient local, automatic liveliness, and
    no deadline, lifespan or lease (``RMW_DURATION_INFINITE``)."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    infinite = QosTime(sec=9223372036, nsec=854775807)
    durability = QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE
    return [Qos(history=QosHistory.UNKNOWN, depth=0, reliability=QosReliability.RELIABLE, durability=durability,
                deadline=infinite, lifespan=infinite, liveliness=QosLiveliness.AUTOMATIC,
                liveliness_lease_duration=infinite, avoid_ros_namespace_conventions=False)]


def export_rosbag2(log_path: str | Path, out_dir: str | Path) -> ExportResult:
    """Writes the bag into ``out_dir``, which must not exist yet; raises :class:`AppError` (and leaves
    nothing behind) when the log cannot be read, the bag cannot be written or no message converts."""
    out = Path(out_dir)
    if out.exists():
        raise AppError(f"{out} exists: the ROS 2 bag is written to a new folder")
    result = ExportResult(str(out))
    from rosbags.rosbag2 import WriterError

    try:
        with partial_folder(out) as tmp:
            with _Bag(tmp) as bag:
                bag.scanner = _Scanner(str(log_path), result)
                for msg in read_log(log_path, result.read):
                    _export_checked(bag, msg, result)
            _finish(log_path, out, tmp, result)
    except WriterError as exc:
        raise AppError(f"cannot write the ROS 2 bag to {out}: {exc}") from exc
    except OSError as exc:
        raise AppError(f"cannot write the ROS 2 bag to {out}: {exc.strerror or exc}") from exc
    return result


def _finish(log_path: str | Path, out: Path, tmp: Path, result: ExportResult) -> None:
    """The complete bag moved to ``out``, unless nothing was exported."""
    if not result.counts:
        r = result.read
        why = f"truncated: {r.reason}" if r.truncated else "no /scan, /odom, /tf, /camera/image or /vipsm/cycle"
        raise AppError(f"{log_path}: no message to export ({why}; {r.bad_messages} malformed, "
                       f"{r.bad_chunks} damaged chunk(s)){': ' + (r.bad + r.corruption)[0] if r.damaged else ''}")
    if out.exists():
        raise AppError(f"{out} appeared while exporting: the bag is not moved there")
    os.rename(tmp, out)


@contextlib.contextmanager
def partial_folder(out: Path) -> Iterator[Path]:
    """A hidden folder beside ``out`` for the bag being written: ``.<name>.partial-<random>/<name>``
    (the bag keeps its final name inside), locked while this process writes it. On the way in, the
    partial folders of exports to the same ``out`` whose writer is gone (their lock is free) are
    removed; on the way out this one is, whatever happened."""
    parent = out.parent
    parent.mkdir(parents=True, exist_ok=True)
    for stale in parent.glob(f".{out.name}.partial-*"):
        _remove_if_abandoned(stale)
    holder = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=parent))
    lock = open(holder / "lock", "w")  # noqa: SIM115 - closed below
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        yield holder / out.name
    finally:
        lock.close()
        shutil.rmtree(holder, ignore_errors=True)


def _remove_if_abandoned(folder: Path) -> None:
    try:
        with open(folder / "lock", "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)  # held: another export is writing it
    except BlockingIOError:
        return
    except OSError:  # no lock file: killed between creating the folder and the lock (or not ours)
        if not folder.is_dir() or time.time() - folder.stat().st_mtime < 60.0:
            return
    shutil.rmtree(folder, ignore_errors=True)


def _export_checked(bag: _Bag, msg: LogMessage, result: ExportResult) -> None:
    """One log message into the bag; one that does not fit its topic is skipped and counted."""
    expected = EXPECTED_SCHEMA.get(msg.topic)
    if expected is None:
        try:
            if msg.topic == "/vipsm/config":
                bag.odometry.configure(msg.data)
            elif msg.topic == "/vipsm/scanner" and bag.scanner is not None:
                bag.scanner.record(msg.data)
        except (KeyError, TypeError, ValueError) as exc:
            result.read.note_bad(f"{msg.topic} message at {msg.log_time_ns} ns: cannot read it: "
                                 f"{type(exc).__name__}: {str(exc)[:200]}")
        result.not_exported[msg.topic] += 1
        return
    if msg.schema != expected:
        result.read.note_bad(f"{msg.topic} message at {msg.log_time_ns} ns: schema {msg.schema!r}, "
                             f"not {expected!r}; not exported")
        return
    try:
        _export_one(bag, msg, result.counts)
    except (KeyError, TypeError, ValueError, IndexError, OverflowError, AttributeError) as exc:
        result.read.note_bad(f"{msg.topic} message at {msg.log_time_ns} ns: cannot convert it: "
                             f"{type(exc).__name__}: {str(exc)[:200]}")


def _export_one(bag: _Bag, msg: LogMessage, counts: Counter[str]) -> None:
    d, t = msg.data, msg.log_time_ns
    if msg.topic == "/vipsm/cycle":
        od = d["odometry"]
        bag.odometry.speeds = (float(od["v_mps"]), float(od["w_radps"]))
        _write(bag, "/vipsm/pose", t, _estimated_pose(bag, d, t), counts)
        _write(bag, "/vipsm/obstacles", t, _markers(bag, d, t), counts)
    elif msg.topic == "/scan":
        _write(bag, "/scan", t, _scan(bag, d), counts)
    elif msg.topic == "/odom":
        _write(bag, "/odom", t, _wheel_odometry(bag, d), counts)
    elif msg.topic == "/camera/image":
        if not isinstance(d.get("data"), bytes):
            raise TypeError("the image data is not bytes")
        img = bag.t["sensor_msgs/msg/CompressedImage"](header=bag.header(d["timestamp"], "camera"), format="jpeg",
                                                        data=np.frombuffer(d["data"], dtype=np.uint8))
        _write(bag, "/camera/image/compressed", t, img, counts)
    elif msg.topic == "/tf":
        _transforms(bag, d, t, counts)


def _write(bag: _Bag, topic: str, t: int, msg: Any, counts: Counter[str]) -> None:
    bag.write(topic, t, msg)
    counts[topic] += 1


def _scan(bag: _Bag, d: dict[str, Any]) -> Any:
    """Bearings from the scan itself; limits and timing from the scanner's record (or assumed)."""
    ranges = np.asarray([math.nan if v is None else v for v in d["ranges"]], dtype=np.float32)  # v1: null
    n = len(ranges)
    first, last = float(d["start_angle"]), float(d["end_angle"])
    inc = (last - first) / (n - 1) if n > 1 else 0.0
    intensities = np.asarray(d["intensities"], dtype=np.float32)
    assert bag.scanner is not None
    info = bag.scanner.for_scan(n, first, last)
    lo, hi = info["range_min_m"], info["range_max_m"]
    return bag.t["sensor_msgs/msg/LaserScan"](
        header=bag.header(d["timestamp"], d["frame_id"] or "laser"), angle_min=first, angle_max=last,
        angle_increment=inc, time_increment=float(info["time_increment_s"]), scan_time=float(info["scan_time_s"]),
        range_min=0.0 if lo is None else float(lo), range_max=math.inf if hi is None else float(hi), ranges=ranges,
        intensities=intensities)


def covariance6(cov3: list[float | None] | None) -> np.ndarray:
    """A 3x3 (x, y, yaw) covariance as ROS's 6x6 (x, y, z, roll, pitch, yaw); the unobserved axes,
    and all three when the 3x3 is missing or not finite, ``UNOBSERVED_VARIANCE``."""
    out = np.zeros(36, dtype=np.float64)
    for k in (2, 3, 4):
        out[k * 7] = UNOBSERVED_VARIANCE
    if cov3 is None or len(cov3) != 9 or any(v is None or not math.isfinite(v) for v in cov3):
        for k in (0, 1, 5):
            out[k * 7] = UNOBSERVED_VARIANCE
        return out
    idx = (0, 1, 5)
    for i in range(3):
        for j in range(3):
            out[idx[i] * 6 + idx[j]] = float(cov3[i * 3 + j])  # type: ignore[arg-type]
    return out


def _diagonal3(sx: float, sy: float, syaw: float) -> list[float | None]:
    return [sx * sx, 0.0, 0.0, 0.0, sy * sy, 0.0, 0.0, 0.0, syaw * syaw]


def _odometry(bag: _Bag, d: dict[str, Any], cov3: list[float | None] | None) -> Any:
    """An ``odom -> base_link`` Odometry with the pose covariance ``cov3`` and the twist of the newest
    cycle (forward speed and turn rate, with the model's covariance; unknown before the first cycle)."""
    t = bag.t
    speeds, sig = bag.odometry.speeds, bag.odometry.twist_sigmas()
    v, w = speeds if speeds is not None else (0.0, 0.0)
    twist = t["geometry_msgs/msg/TwistWithCovariance"](
        twist=t["geometry_msgs/msg/Twist"](linear=bag.vec(v, 0, 0), angular=bag.vec(0, 0, w)),
        covariance=covariance6(None if sig is None else _diagonal3(sig[0], MIN_SIGMA_M, sig[1])))
    return t["nav_msgs/msg/Odometry"](
        header=bag.header(d["timestamp"], "odom"), child_frame_id="base_link",
        pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=bag.pose(d["pose"]), covariance=covariance6(cov3)),
        twist=twist)


def _wheel_odometry(bag: _Bag, d: dict[str, Any]) -> Any:
    p, q = d["pose"]["position"], d["pose"]["orientation"]
    yaw = 2.0 * math.atan2(float(q["z"]), float(q["w"]))
    bag.odometry.add(float(p["x"]), float(p["y"]), yaw)
    return _odometry(bag, d, _diagonal3(*bag.odometry.pose_sigmas()))


def _stamp(t_ns: int) -> dict[str, int]:
    return {"sec": t_ns // 1_000_000_000, "nsec": t_ns % 1_000_000_000}


def _estimated_pose(bag: _Bag, cyc: dict[str, Any], t_ns: int) -> Any:
    x, y, th = cyc["estimate"]["pose"]
    d = {"timestamp": _stamp(t_ns), "pose": {"position": {"x": x, "y": y, "z": 0.0},
                                             "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(th / 2),
                                                             "w": math.cos(th / 2)}}}
    return _odometry(bag, d, cyc["estimate"]["covariance"])


def _markers(bag: _Bag, cyc: dict[str, Any], t_ns: int) -> Any:
    M = bag.t["visualization_msgs/msg/Marker"]
    header = bag.header(_stamp(t_ns), "odom")
    markers = [_marker(bag, header, "obstacles", 0, M.DELETEALL, M.CYLINDER)]
    for ob in cyc["estimate"]["obstacles"]:
        cyl = _marker(bag, header, "obstacles", ob["track_id"], M.ADD, M.CYLINDER)
        cyl.pose.position = bag.point(ob["x_m"], ob["y_m"], 0.5)
        cyl.scale = bag.vec(2 * ob["radius_m"], 2 * ob["radius_m"], 1.0)
        arrow = _marker(bag, header, "velocity", ob["track_id"], M.ADD, M.ARROW)
        arrow.points = [bag.point(ob["x_m"], ob["y_m"], 1.0),
                        bag.point(ob["x_m"] + ob["vx_mps"], ob["y_m"] + ob["vy_mps"], 1.0)]
        arrow.scale = bag.vec(0.04, 0.12, 0.1)
        markers += [cyl, arrow]
    return bag.t["visualization_msgs/msg/MarkerArray"](markers=markers)


def _marker(bag: _Bag, header: Any, ns: str, mid: int, action: int, kind: int) -> Any:
    t = bag.t
    return t["visualization_msgs/msg/Marker"](
        header=header, ns=ns, id=int(mid), type=kind, action=action,
        pose=bag.pose({"position": {"x": 0, "y": 0, "z": 0}, "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}}),
        scale=bag.vec(1, 1, 1), color=t["std_msgs/msg/ColorRGBA"](r=1.0, g=0.3, b=0.1, a=0.8),
        lifetime=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=500_000_000), frame_locked=False,
        points=[], colors=[], texture_resource="", texture=t["sensor_msgs/msg/CompressedImage"](
            header=header, format="", data=np.zeros(0, np.uint8)),
        uv_coordinates=[], text="", mesh_resource="", mesh_file=t["visualization_msgs/msg/MeshFile"](
            filename="", data=np.zeros(0, np.uint8)), mesh_use_embedded_materials=False)


def _transforms(bag: _Bag, d: dict[str, Any], t_ns: int, counts: Counter[str]) -> None:
    t = bag.t
    dynamic, static = [], []
    for tf in d["transforms"]:
        tr = tf["translation"]
        msg = t["geometry_msgs/msg/TransformStamped"](
            header=bag.header(tf["timestamp"], tf["parent_frame_id"]), child_frame_id=tf["child_frame_id"],
            transform=t["geometry_msgs/msg/Transform"](translation=bag.vec(tr["x"], tr["y"], tr["z"]),
                                                      rotation=bag.quat(tf["rotation"])))
        (static if tf["child_frame_id"] in STATIC_CHILDREN else dynamic).append(msg)
    if static and counts["/tf_static"] == 0:
        _write(bag, "/tf_static", t_ns, t["tf2_msgs/msg/TFMessage"](transforms=static), counts)
    if dynamic:
        _write(bag, "/tf", t_ns, t["tf2_msgs/msg/TFMessage"](transforms=dynamic), counts)
