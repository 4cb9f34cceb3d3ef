"""ROS 1 ``.bag`` files and ROS 2 bag folders as the estimator's inputs (``vipsm-robot replay BAG``).

Read with the pure-Python ``rosbags`` package (no ROS needed); the type store comes from the bag (ROS 1
bags carry their message definitions, ROS 2 bags are read with the ROS 2 types).

* ``sensor_msgs/LaserScan`` (``--scan``) -> :class:`vipsm.types.Scan`: bearings ``angle_min + i *
  angle_increment`` (a scanner turning clockwise, negative increment, is reversed so bearings ascend),
  ranges outside ``[range_min, range_max]`` or not finite -> NaN (no return), stamp from the header
  (the first beam's time), ``beam_dt_s`` from ``time_increment``. The sensor's geometry, scan period and
  range limits are taken from these fields (:class:`SensorInfo`), never assumed.
* ``nav_msgs/Odometry`` (``--odom``) -> :class:`vipsm.types.Odometry`, the newest one received before the
  scan (as live). Without an odometry topic every scan gets the identity odometry (the robot "did not
  move"): the matcher's prediction is the last pose, so the scan matcher alone tracks any motion.
* ``sensor_msgs/CompressedImage`` or ``sensor_msgs/Image`` (``--image``) -> :class:`vipsm.types.Frame`
  (grey), with intrinsics from ``sensor_msgs/CameraInfo`` (``--camera-info``) or given explicitly; the
  newest image received before the scan goes with it (the estimator refuses a stale one itself).

Errors (all :class:`BagError`, an :class:`app.errors.AppError`: the CLI prints one line, exit 2):
:class:`BagOpenError` (missing, not a bag, truncated or damaged index), :class:`BagTopicError` (a topic
that is not in the bag; the message lists the topics there are), :class:`BagTypeError` (a topic of the
wrong message type, an image encoding that cannot be read). A single message that cannot be
deserialised is skipped and counted in :attr:`BagReadResult.bad_messages`; damage part-way through
(a chunk that cannot be read) ends the bag there, the scans before it kept, with
:attr:`BagReadResult.truncated` and its reason (both: exit 3).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vipsm.types import Frame, Intrinsics, Odometry, Scan

from .errors import AppError

LASER_SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
IMAGE_TYPES = ("sensor_msgs/msg/CompressedImage", "sensor_msgs/msg/Image")
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
#: a scan with more beams than this is refused (the widest SCIP sensors give a few thousand)
MAX_BEAMS = 10_000
#: reasons of skipped messages kept (the count is complete)
MAX_REASONS = 20


class BagError(AppError):
    """A ROS bag that cannot be replayed as asked."""


class BagOpenError(BagError):
    """Missing, not a ROS bag, truncated or with a damaged index."""


class BagTopicError(BagError):
    """A topic asked for is not in the bag."""


class BagTypeError(BagError):
    """A topic carries another message type than the one asked for, or an unreadable image encoding."""


@dataclass(frozen=True)
class BagTopics:
    scan: str
    odom: str | None = None
    image: str | None = None
    camera_info: str | None = None


@dataclass(frozen=True)
class SensorInfo:
    """The laser as the data describes it (first scan's fields)."""

    frame_id: str
    n_beams: int
    angle_min_rad: float
    angle_increment_rad: float
    range_min_m: float
    range_max_m: float
    #: ``scan_time``, else ``time_increment`` times the beams in one turn; 0 if the bag says neither
    scan_period_s: float

    @property
    def fov_rad(self) -> float:
        return abs(self.angle_increment_rad) * max(self.n_beams - 1, 0)

    def as_dict(self) -> dict[str, Any]:
        return {"frame_id": self.frame_id, "beams": self.n_beams, "fov_deg": round(math.degrees(self.fov_rad), 3),
                "step_deg": round(math.degrees(abs(self.angle_increment_rad)), 5),
                "range_min_m": round(self.range_min_m, 4), "range_max_m": round(self.range_max_m, 4),
                "scan_period_s": round(self.scan_period_s, 6)}


@dataclass
class BagReadResult:
    """What reading the bag met besides the cycles."""

    topics: dict[str, str] = field(default_factory=dict)
    sensor: SensorInfo | None = None
    scans: int = 0
    odometry: int = 0
    frames: int = 0
    bad_messages: int = 0
    bad: list[str] = field(default_factory=list)
    #: the bag ended in damage part-way (the scans before it were read); why
    truncated: bool = False
    reason: str = ""

    def note_bad(self, reason: str) -> None:
        self.bad_messages += 1
        if len(self.bad) < MAX_REASONS:
            self.bad.append(reason)


@dataclass(frozen=True)
class BagCycle:
    """One scan with the odometry and frame that go with it (``odometry_given`` False: the identity)."""

    scan: Scan
    odometry: Odometry
    frame: Frame | None
    jpeg: bytes | None
    odometry_given: bool
    #: the time the bag recorded the scan at (ns)
    bag_time_ns: int
    #: the laser as this scan's message describes it (its range limits and scan_time, for a field log)
    sensor: SensorInfo | None = None


# ---------------------------------------------------------------------------------------------
# message conversion (pure: a deserialised message in, an estimator type out)


def stamp_of(msg: Any) -> float:
    st = msg.header.stamp
    return float(st.sec) + 1e-9 * float(st.nanosec)


def sensor_info(msg: Any) -> SensorInfo:
    n = len(msg.ranges)
    inc = float(msg.angle_increment)
    period = float(msg.scan_time)
    if not (math.isfinite(period) and period > 0.0):
        ti = abs(float(msg.time_increment))
        period = ti * 2.0 * math.pi / abs(inc) if ti > 0.0 and inc != 0.0 else 0.0
    return SensorInfo(str(msg.header.frame_id), n, float(msg.angle_min), inc, float(msg.range_min),
                      float(msg.range_max), period)


def scan_from_msg(msg: Any, seq: int) -> Scan:
    """A ``sensor_msgs/LaserScan`` as the estimator's scan (ValueError if it is not a plausible one)."""
    from .daemon import normalised_bearings

    ranges = np.asarray(msg.ranges, dtype=float)
    n = ranges.size
    inc = float(msg.angle_increment)
    if not 1 <= n <= MAX_BEAMS:
        raise ValueError(f"{n} beams (expected 1 to {MAX_BEAMS})")
    if not math.isfinite(inc) or (n > 1 and not 0.0 < abs(inc) * (n - 1) <= 2 * math.pi + 1e-6):
        raise ValueError(f"angle_increment {inc!r} does not fit {n} beams in one turn")
    lo, hi = float(msg.range_min), float(msg.range_max)
    with np.errstate(invalid="ignore"):
        ranges = np.where(np.isfinite(ranges) & (ranges >= lo) & (ranges <= hi) & (ranges > 0.0), ranges, np.nan)
    stamp, dt = stamp_of(msg), abs(float(msg.time_increment))
    if not math.isfinite(dt):
        dt = 0.0
    first = float(msg.angle_min)
    intens = np.asarray(msg.intensities, dtype=float) if len(msg.intensities) == n else None
    if inc < 0.0:  # clockwise: reversed, the first bearing is the last beam's (taken last)
        first, inc = first + inc * (n - 1), -inc
        ranges = ranges[::-1].copy()
        intens = None if intens is None else intens[::-1].copy()
        stamp, dt = stamp + dt * (n - 1), -dt
    return Scan(ranges, normalised_bearings(first, inc, n), stamp, seq, dt, intens)


def _yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def odometry_from_msg(msg: Any) -> Odometry:
    p = msg.pose.pose
    tw = msg.twist.twist
    vals = (float(p.position.x), float(p.position.y), _yaw(p.orientation), float(tw.linear.x), float(tw.angular.z),
            stamp_of(msg))
    if not all(math.isfinite(v) for v in vals):
        raise ValueError("odometry with a non-finite value")
    return Odometry(*vals)


def intrinsics_from_camera_info(msg: Any) -> Intrinsics:
    k = np.asarray(getattr(msg, "k", getattr(msg, "K", None)), dtype=float).ravel()
    d = np.asarray(getattr(msg, "d", getattr(msg, "D", [])), dtype=float).ravel()
    if k.size != 9 or k[0] <= 0 or k[4] <= 0:
        raise ValueError(f"camera info K {k.tolist()} is not a camera matrix")
    dist = [float(v) for v in d[:4]] + [0.0] * max(0, 4 - d.size)
    return Intrinsics(float(k[0]), float(k[4]), float(k[2]), float(k[5]), int(msg.width), int(msg.height), *dist)


def image_from_msg(msg: Any, msgtype: str) -> tuple[np.ndarray, bytes | None]:
    """A grey uint8 image (and the JPEG bytes when the message is one) from an image message."""
    if msgtype == "sensor_msgs/msg/CompressedImage":
        from drivers.errors import ProtocolError

        from .cmd_camera import decode_jpeg  # the decoder used live and in replay

        jpeg = bytes(np.asarray(msg.data, dtype=np.uint8).tobytes())
        fmt = str(msg.format).lower()
        try:
            grey = decode_jpeg(jpeg, grey=True)
        except ProtocolError as exc:
            raise ValueError(str(exc)) from exc
        return grey, jpeg if "jpeg" in fmt or "jpg" in fmt else None
    import cv2

    enc = str(msg.encoding).lower()
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8)
    channels = {"mono8": 1, "8uc1": 1, "bgr8": 3, "rgb8": 3, "bgra8": 4, "rgba8": 4}.get(enc)
    if channels is None:
        raise BagTypeError(f"image encoding {msg.encoding!r} is not supported (mono8, bgr8, rgb8, bgra8, rgba8)")
    if h < 1 or w < 1 or step < w * channels or data.size < h * step:
        raise ValueError(f"image {w}x{h} step {step} does not fit its {data.size} bytes")
    img = data[: h * step].reshape(h, step)[:, : w * channels].reshape(h, w, channels)
    code = {3: cv2.COLOR_RGB2GRAY if enc == "rgb8" else cv2.COLOR_BGR2GRAY,
            4: cv2.COLOR_RGBA2GRAY if enc == "rgba8" else cv2.COLOR_BGRA2GRAY}
    grey = img[:, :, 0].copy() if channels == 1 else cv2.cvtColor(img, code[channels])
    return grey, None


# ---------------------------------------------------------------------------------------------
# the bag


def open_reader(path: str | Path) -> Any:
    """An opened ``rosbags`` AnyReader (ROS 1 file or ROS 2 folder), or :class:`BagOpenError`."""
    from rosbags.highlevel import AnyReader, AnyReaderError

    p = Path(path)
    if not p.exists():
        raise BagOpenError(f"no such bag: {p}")
    reader = AnyReader([p])
    try:
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError) as exc:
        hint = " (a ROS 1 bag cut short: `rosbag reindex` may recover it)" if "index" in str(exc).lower() else ""
        raise BagOpenError(f"{p}: cannot read the bag: {exc}{hint}") from exc
    return reader


def is_bag(path: str | Path) -> bool:
    """A ROS 1 bag file (``.bag``) or a ROS 2 bag folder (``metadata.yaml`` inside)."""
    p = Path(path)
    return p.suffix == ".bag" or (p.is_dir() and (p / "metadata.yaml").exists())


def bag_topics(reader: Any) -> dict[str, str]:
    return {c.topic: c.msgtype for c in reader.connections}


def check_topics(topics: BagTopics, present: dict[str, str], path: str | Path) -> None:
    """Each asked topic exists (a missing leading ``/`` is forgiven) with the right message type."""
    wanted = [(topics.scan, (LASER_SCAN,), "--scan"), (topics.odom, (ODOMETRY,), "--odom"),
              (topics.image, IMAGE_TYPES, "--image"), (topics.camera_info, (CAMERA_INFO,), "--camera-info")]
    listing = ", ".join(f"{t} ({ty.split('/')[-1]})" for t, ty in sorted(present.items())) or "none"
    for topic, types, flag in wanted:
        if topic is None:
            continue
        if topic not in present:
            raise BagTopicError(f"{path}: {flag} topic {topic!r} is not in the bag; its topics: {listing}")
        if present[topic] not in types:
            raise BagTypeError(f"{path}: {flag} topic {topic!r} carries {present[topic]}, not "
                               f"{' or '.join(types)}")


def resolve_topic(topic: str | None, present: dict[str, str]) -> str | None:
    """``scan`` and ``/scan`` name the same topic (ROS 1 bags are written with either)."""
    if topic is None or topic in present:
        return topic
    alt = topic[1:] if topic.startswith("/") else "/" + topic
    return alt if alt in present else topic


def read_bag(path: str | Path, topics: BagTopics, intrinsics: Intrinsics | None = None,
             read: BagReadResult | None = None, max_scans: int | None = None) -> Iterator[BagCycle]:
    """The bag's scans in recorded order, each with its odometry and frame."""
    read = read if read is not None else BagReadResult()
    reader = open_reader(path)
    try:
        present = bag_topics(reader)
        read.topics = dict(present)
        topics = BagTopics(*(resolve_topic(t, present) for t in (topics.scan, topics.odom, topics.image,
                                                                  topics.camera_info)))  # type: ignore[arg-type]
        check_topics(topics, present, path)
        if topics.image is not None and topics.camera_info is None and intrinsics is None:
            raise BagError(f"{path}: --image needs --camera-info TOPIC or the intrinsics (--fx --fy --cx --cy)")
        yield from _cycles(reader, topics, intrinsics, read, max_scans, path)
    finally:
        reader.close()


def _cycles(reader: Any, topics: BagTopics, intrinsics: Intrinsics | None, read: BagReadResult,
            max_scans: int | None, path: str | Path) -> Iterator[BagCycle]:
    wanted = {t for t in (topics.scan, topics.odom, topics.image, topics.camera_info) if t is not None}
    conns = [c for c in reader.connections if c.topic in wanted]
    odom: Odometry | None = None
    frame: tuple[Frame, bytes | None] | None = None
    seq = 0
    try:
        for conn, t_ns, raw in reader.messages(connections=conns):
            try:
                msg = reader.deserialize(raw, conn.msgtype)
                if conn.topic == topics.scan:
                    scan, sensor = scan_from_msg(msg, seq), sensor_info(msg)
                    if read.sensor is None:
                        read.sensor = sensor
                    seq += 1
                    read.scans += 1
                    ident = Odometry(0.0, 0.0, 0.0, 0.0, 0.0, scan.stamp_s)
                    yield BagCycle(scan, odom if odom is not None else ident, frame[0] if frame else None,
                                   frame[1] if frame else None, odom is not None, t_ns, sensor)
                    if max_scans is not None and read.scans >= max_scans:
                        return
                elif conn.topic == topics.odom:
                    odom = odometry_from_msg(msg)
                    read.odometry += 1
                elif conn.topic == topics.camera_info:
                    intrinsics = intrinsics_from_camera_info(msg)
                elif conn.topic == topics.image and intrinsics is not None:
                    frame = _frame(msg, conn.msgtype, intrinsics, read.frames)
                    read.frames += 1
            except BagTypeError:
                raise
            except (ValueError, TypeError, IndexError, KeyError, AttributeError, AppError) as exc:
                read.note_bad(f"{conn.topic} at {t_ns} ns: {type(exc).__name__}: {str(exc)[:200]}")
    except BagError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags raises many kinds for a damaged chunk
        # the scans before the damage were replayed; they are kept, and the cut is reported
        read.truncated = True
        read.reason = f"damaged after {read.scans} scans: {type(exc).__name__}: {str(exc)[:200]}"


def _frame(msg: Any, msgtype: str, intr: Intrinsics, seq: int) -> tuple[Frame, bytes | None]:
    grey, jpeg = image_from_msg(msg, msgtype)
    h, w = grey.shape[:2]
    if (w, h) != (intr.width_px, intr.height_px):  # intrinsics given for another size: scale them
        sx, sy = w / intr.width_px, h / intr.height_px
        intr = Intrinsics(intr.fx_px * sx, intr.fy_px * sy, intr.cx_px * sx, intr.cy_px * sy, w, h, intr.k1, intr.k2,
                          intr.p1, intr.p2)
    return Frame(grey, stamp_of(msg), intr, 0.0, 0.0, seq), jpeg
