"""A field log as a ROS 2 bag (``vipsm-robot export LOG.mcap --rosbag2 OUT_DIR``), written with the
pure-Python ``rosbags`` package, so a ROS 2 user can ``ros2 bag play`` it without this program.

==================  ================================  ===============================================
topic               type                              from
==================  ================================  ===============================================
``/scan``           ``sensor_msgs/msg/LaserScan``     ``/scan`` (REP 117 invalid ranges kept)
``/odom``           ``nav_msgs/msg/Odometry``         ``/odom`` wheel odometry (+ speeds from cycles)
``/vipsm/pose``     ``nav_msgs/msg/Odometry``         the estimated pose with its covariance
``/camera/image/compressed``  ``sensor_msgs/msg/CompressedImage``  ``/camera/image``
``/vipsm/obstacles``  ``visualization_msgs/msg/MarkerArray``  cylinders + velocity arrows
``/tf``             ``tf2_msgs/msg/TFMessage``        odom->base_link, base_link->camera, world->...
``/tf_static``      ``tf2_msgs/msg/TFMessage``        base_link->laser, once (transient local)
==================  ================================  ===============================================

Frames follow REP 105 (``odom``, ``base_link``, ``laser``); header stamps are the messages' own
stamps, bag times the log times. Version 1 logs (no ``/tf``) export without transforms.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import AppError
from .logread import LogMessage, LogReadResult, read_log

#: the UTM-30LX's limits (PP: DMIN 23 mm, DMAX 60000 mm); the log does not repeat them per scan
RANGE_MIN_M = 0.023
RANGE_MAX_M = 60.0
SCAN_PERIOD_S = 0.025

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


@dataclass
class ExportResult:
    out_dir: str
    counts: Counter[str] = field(default_factory=Counter)
    read: LogReadResult = field(default_factory=LogReadResult)


class _Bag:
    """The rosbags writer, its connections and the typestore's message classes."""

    def __init__(self, out_dir: Path) -> None:
        from rosbags.rosbag2 import Writer
        from rosbags.typesys import Stores, get_typestore

        self.ts = get_typestore(Stores.ROS2_HUMBLE)
        self.t = self.ts.types
        self.writer = Writer(out_dir, version=8)
        self.conns: dict[str, Any] = {}

    def __enter__(self) -> _Bag:
        self.writer.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.writer.close()

    def write(self, topic: str, log_time_ns: int, msg: Any) -> None:
        conn = self.conns.get(topic)
        if conn is None:
            qos = _latched_qos() if topic == "/tf_static" else ()
            conn = self.writer.add_connection(topic, TOPICS[topic], typestore=self.ts, offered_qos_profiles=qos)
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


def _latched_qos() -> list[Any]:
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    zero = QosTime(sec=0, nsec=0)
    return [Qos(history=QosHistory.KEEP_LAST, depth=1, reliability=QosReliability.RELIABLE,
                durability=QosDurability.TRANSIENT_LOCAL, deadline=zero, lifespan=zero,
                liveliness=QosLiveliness.AUTOMATIC, liveliness_lease_duration=zero,
                avoid_ros_namespace_conventions=False)]


def export_rosbag2(log_path: str | Path, out_dir: str | Path) -> ExportResult:
    """Writes the bag; the output folder must not exist yet (rosbags refuses to overwrite)."""
    out = Path(out_dir)
    if out.exists():
        raise AppError(f"{out} exists: the ROS 2 bag is written to a new folder")
    result = ExportResult(str(out))
    cycles: dict[int, dict[str, Any]] = {}  # the newest cycles by log time (speeds, covariance, obstacles)
    from rosbags.rosbag2 import WriterError

    try:
        with _Bag(out) as bag:
            for msg in read_log(log_path, result.read):
                _export_one(bag, msg, cycles, result.counts)
    except WriterError as exc:
        raise AppError(f"cannot write the ROS 2 bag to {out}: {exc}") from exc
    return result


def _export_one(bag: _Bag, msg: LogMessage, cycles: dict[int, dict[str, Any]], counts: Counter[str]) -> None:
    d, t = msg.data, msg.log_time_ns
    if msg.topic == "/vipsm/cycle":
        cycles[t] = d
        if len(cycles) > 8:
            del cycles[min(cycles)]
        _write(bag, "/vipsm/pose", t, _estimated_pose(bag, d, t), counts)
        _write(bag, "/vipsm/obstacles", t, _markers(bag, d, t), counts)
    elif msg.topic == "/scan" and msg.schema == "foxglove.LaserScan":
        _write(bag, "/scan", t, _scan(bag, d), counts)
    elif msg.topic == "/odom" and msg.schema == "foxglove.PoseInFrame":
        _write(bag, "/odom", t, _odometry(bag, d, "odom", "base_link", None), counts)
    elif msg.topic == "/camera/image" and isinstance(d.get("data"), bytes):
        img = bag.t["sensor_msgs/msg/CompressedImage"](header=bag.header(d["timestamp"], "camera"), format="jpeg",
                                                        data=np.frombuffer(d["data"], dtype=np.uint8))
        _write(bag, "/camera/image/compressed", t, img, counts)
    elif msg.topic == "/tf":
        _transforms(bag, d, t, counts)


def _write(bag: _Bag, topic: str, t: int, msg: Any, counts: Counter[str]) -> None:
    bag.write(topic, t, msg)
    counts[topic] += 1


def _scan(bag: _Bag, d: dict[str, Any]) -> Any:
    ranges = np.asarray(d["ranges"], dtype=np.float32)
    n = len(ranges)
    inc = (d["end_angle"] - d["start_angle"]) / (n - 1) if n > 1 else 0.0
    intensities = np.asarray(d["intensities"], dtype=np.float32)
    return bag.t["sensor_msgs/msg/LaserScan"](
        header=bag.header(d["timestamp"], d["frame_id"] or "laser"), angle_min=d["start_angle"],
        angle_max=d["end_angle"], angle_increment=inc, time_increment=SCAN_PERIOD_S / 1440.0,
        scan_time=SCAN_PERIOD_S, range_min=RANGE_MIN_M, range_max=RANGE_MAX_M, ranges=ranges,
        intensities=intensities)


def _covariance6(cov3: list[float | None] | None) -> np.ndarray:
    """A 3x3 (x, y, yaw) covariance as ROS's 6x6 (x, y, z, roll, pitch, yaw); unknown: -1 first."""
    out = np.zeros(36, dtype=np.float64)
    if cov3 is None or len(cov3) != 9 or any(v is None or not math.isfinite(v) for v in cov3):
        out[0] = -1.0  # REP: a covariance whose first element is -1 is unknown
        return out
    idx = (0, 1, 5)
    for i in range(3):
        for j in range(3):
            out[idx[i] * 6 + idx[j]] = float(cov3[i * 3 + j])  # type: ignore[arg-type]
    return out


def _odometry(bag: _Bag, d: dict[str, Any], frame: str, child: str, cov3: list[float | None] | None) -> Any:
    t = bag.t
    twist = t["geometry_msgs/msg/TwistWithCovariance"](
        twist=t["geometry_msgs/msg/Twist"](linear=bag.vec(0, 0, 0), angular=bag.vec(0, 0, 0)),
        covariance=_covariance6(None))
    return t["nav_msgs/msg/Odometry"](
        header=bag.header(d["timestamp"], frame), child_frame_id=child,
        pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=bag.pose(d["pose"]), covariance=_covariance6(cov3)),
        twist=twist)


def _stamp(t_ns: int) -> dict[str, int]:
    return {"sec": t_ns // 1_000_000_000, "nsec": t_ns % 1_000_000_000}


def _estimated_pose(bag: _Bag, cyc: dict[str, Any], t_ns: int) -> Any:
    x, y, th = cyc["estimate"]["pose"]
    d = {"timestamp": _stamp(t_ns), "pose": {"position": {"x": x, "y": y, "z": 0.0},
                                             "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(th / 2),
                                                             "w": math.cos(th / 2)}}}
    msg = _odometry(bag, d, "odom", "base_link", cyc["estimate"]["covariance"])
    od = cyc["odometry"]
    msg.twist.twist.linear.x, msg.twist.twist.angular.z = float(od["v_mps"]), float(od["w_radps"])
    return msg


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
