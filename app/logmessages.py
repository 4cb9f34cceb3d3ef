"""What goes on each field-log channel: the official Foxglove messages, built with the Foxglove SDK's
typed classes (so each ``foxglove.*`` channel carries the official protobuf schema by construction),
and the JSON schemas of the project's own channels (every field typed, every field required).

Frames (REP 105): ``odom`` (the estimator's frame: the odometry frame of its first scan),
``base_link`` (the robot), ``laser`` and ``camera`` (the sensors on the robot); in simulated runs
also ``world`` (the simulated world) and ``truth/base_link`` (the robot's true pose).
"""

from __future__ import annotations

import dataclasses
import math
import typing
from typing import Any

from foxglove.messages import (
    ArrowPrimitive,
    Color,
    CompressedImage,
    CylinderPrimitive,
    Duration,
    FrameTransform,
    FrameTransforms,
    KeyValuePair,
    LaserScan,
    Log,
    LogLevel,
    Pose,
    PoseInFrame,
    Quaternion,
    SceneEntity,
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
    TextPrimitive,
    Timestamp,
    Vector3,
)

from vipsm.sensor import scan_period_s
from vipsm.types import Obstacle, Person, Scan

#: the field-log layout this version writes (recorded in ``/vipsm/config`` as ``log_version``);
#: 1 = JSON everywhere (written before the Foxglove SDK), 2 = official protobuf schemas + ``/tf``,
#: 3 = + ``/vipsm/scanner`` (the scanner's geometry, timing and range limits for ``/scan``)
LOG_VERSION = 3

LOG_LEVELS = {"debug": LogLevel.Debug, "info": LogLevel.Info, "warning": LogLevel.Warning,
              "error": LogLevel.Error, "fatal": LogLevel.Fatal}

OBSTACLE_COLOR = Color(r=1.0, g=0.3, b=0.1, a=0.7)
ARROW_COLOR = Color(r=1.0, g=0.9, b=0.1, a=1.0)


def timestamp(t_wall_s: float) -> Timestamp:
    """A Foxglove timestamp from seconds since the epoch (the same rounding as the log time)."""
    ns = stamp_ns(t_wall_s)
    return Timestamp(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000)


def stamp_ns(t_wall_s: float) -> int:
    return int(round(t_wall_s * 1e9))


def yaw(theta_rad: float) -> Quaternion:
    return Quaternion(x=0.0, y=0.0, z=math.sin(theta_rad / 2.0), w=math.cos(theta_rad / 2.0))


def pan_tilt(pan_rad: float, tilt_rad: float) -> Quaternion:
    """Rotation by ``pan`` about z, then ``tilt`` about the panned y axis (positive tilt looks down,
    as REP 103's right-handed y-left axes give)."""
    cp, sp = math.cos(pan_rad / 2.0), math.sin(pan_rad / 2.0)
    ct, st = math.cos(tilt_rad / 2.0), math.sin(tilt_rad / 2.0)
    return Quaternion(x=-sp * st, y=cp * st, z=sp * ct, w=cp * ct)


def planar_pose(x_m: float, y_m: float, theta_rad: float, z_m: float = 0.0) -> Pose:
    return Pose(position=Vector3(x=x_m, y=y_m, z=z_m), orientation=yaw(theta_rad))


# ---------------------------------------------------------------------------------------------
# foxglove.* messages


def laser_scan(ranges_m: list[float], first_rad: float, last_rad: float, intensities: list[float] | None,
               wall_s: float) -> LaserScan:
    """``ranges_m`` as the driver gave them with invalid returns already mapped to REP 117's values
    (+inf no return, -inf too close, NaN erroneous): protobuf doubles carry all three."""
    return LaserScan(
        timestamp=timestamp(wall_s), frame_id="laser", pose=planar_pose(0.0, 0.0, 0.0),
        start_angle=first_rad, end_angle=last_rad, ranges=ranges_m, intensities=intensities or [],
    )


#: the channel of :func:`scanner_info` (schema ``vipsm.ScannerInfo``, :data:`app.logschemas.SCANNER_INFO`)
SCANNER_TOPIC = "/vipsm/scanner"


def scanner_info(scan: Scan, range_limits_m: tuple[float, float] | None,
                 scan_time_s: float | None = None) -> dict[str, Any]:
    """The ``/vipsm/scanner`` record of the scanner that took ``scan``: beams and bearings from the scan,
    ``time_increment_s`` its ``beam_dt_s`` (signed), ``scan_time_s`` as given (a ROS bag's own ``scan_time``) or
    else one turn of the mirror (``beam_dt_s`` times the beams a full turn holds: 25 ms from the UTM-30LX's
    PP), ``range_min_m``/``range_max_m`` from ``range_limits_m`` (the PP reply's DMIN/DMAX, a bag's
    limits); what the data does not state is 0 (times) or null (limits), never a model's constant."""
    b = scan.bearings_rad
    n = int(b.size)
    step = float(b[1] - b[0]) if n > 1 else 0.0
    dt = float(scan.beam_dt_s)  # negative: beam 0 taken last (a clockwise scanner, reversed by bagread)
    dt = dt if math.isfinite(dt) else 0.0
    period = scan_period_s(dt, step) if scan_time_s is None else float(scan_time_s)
    lo, hi = range_limits_m if range_limits_m is not None else (None, None)
    return {"beams": n, "angle_min_rad": float(b[0]) if n else 0.0, "angle_max_rad": float(b[-1]) if n else 0.0,
            "angle_increment_rad": step, "time_increment_s": dt,
            "scan_time_s": period if math.isfinite(period) and period > 0.0 else 0.0,
            "range_min_m": _finite_or_none(lo), "range_max_m": _finite_or_none(hi)}


def _finite_or_none(v: float | None) -> float | None:
    return float(v) if v is not None and math.isfinite(v) else None


class ScannerInfoLog:
    """Writes ``/vipsm/scanner`` before a scan whose scanner differs from the one last written (the first
    scan, a reconnect to another scanner or window): counts and limits exactly, times and angles beyond
    ``rel_tol`` (so a bag whose ``scan_time`` is measured per scan, jittering by microseconds, does not
    write one record per scan). A record the log refused (queue full) is tried again with the next scan."""

    def __init__(self, rel_tol: float = 1e-3) -> None:
        self.rel_tol = rel_tol
        self._written: dict[str, Any] | None = None

    def changed(self, info: dict[str, Any]) -> bool:
        last = self._written
        if last is None or last.keys() != info.keys():
            return True
        for k, v in info.items():
            w = last[k]
            if isinstance(v, float) and isinstance(w, float):
                if not math.isclose(v, w, rel_tol=self.rel_tol, abs_tol=1e-9):
                    return True
            elif v != w:
                return True
        return False

    def before_scan(self, log: typing.Callable[[str, float, Any], bool | None], wall_s: float,
                    info: dict[str, Any]) -> None:
        """``log(topic, wall_s, payload)`` (False: refused) is called when ``info`` is new."""
        if self.changed(info) and log(SCANNER_TOPIC, wall_s, info) is not False:
            self._written = info


def pose_in_frame(x_m: float, y_m: float, theta_rad: float, wall_s: float, frame_id: str = "odom") -> PoseInFrame:
    return PoseInFrame(timestamp=timestamp(wall_s), frame_id=frame_id, pose=planar_pose(x_m, y_m, theta_rad))


def compressed_image(jpeg: bytes, wall_s: float) -> CompressedImage:
    return CompressedImage(timestamp=timestamp(wall_s), frame_id="camera", data=jpeg, format="jpeg")


def log_line(level: str, message: str, wall_s: float) -> Log:
    return Log(timestamp=timestamp(wall_s), level=LOG_LEVELS[level], message=message, name="vipsm-robot",
               file="", line=0)


def scene_update(obstacles: typing.Iterable[Obstacle], wall_s: float, lifetime_s: float) -> SceneUpdate:
    """All previous obstacles deleted, then one entity per obstacle: a 1 m cylinder of its radius,
    an arrow for its velocity (length = the distance covered in 1 s) and its speed as text."""
    return _replace_scene(_obstacle_entity, obstacles, wall_s, lifetime_s)


def _replace_scene(entity: typing.Callable[[typing.Any, Timestamp, Duration], SceneEntity],
                   items: typing.Iterable[typing.Any], wall_s: float, lifetime_s: float) -> SceneUpdate:
    """Every previous entity deleted, then one ``entity(item, ...)`` per item, all with one lifetime."""
    ts = timestamp(wall_s)
    life = Duration(sec=int(lifetime_s), nsec=int(round((lifetime_s % 1.0) * 1e9)))
    return SceneUpdate(
        deletions=[SceneEntityDeletion(timestamp=ts, type=SceneEntityDeletionType.All, id="")],
        entities=[entity(item, ts, life) for item in items],
    )


def _velocity_arrows(x_m: float, y_m: float, vx_mps: float, vy_mps: float) -> list[ArrowPrimitive]:
    """An arrow as long as the distance covered in 1 s (none when standing)."""
    speed = math.hypot(vx_mps, vy_mps)
    if speed <= 1e-3:
        return []
    return [ArrowPrimitive(pose=planar_pose(x_m, y_m, math.atan2(vy_mps, vx_mps), 1.0),
                           shaft_length=max(speed - 0.1, 0.01), shaft_diameter=0.04, head_length=0.1,
                           head_diameter=0.12, color=ARROW_COLOR)]


def _obstacle_entity(ob: Obstacle, ts: Timestamp, life: Duration) -> SceneEntity:
    speed = math.hypot(ob.vx_mps, ob.vy_mps)
    arrows = _velocity_arrows(ob.x_m, ob.y_m, ob.vx_mps, ob.vy_mps)
    return SceneEntity(
        timestamp=ts, frame_id="odom", id=f"obstacle-{ob.track_id}", lifetime=life, frame_locked=False,
        metadata=[KeyValuePair(key="vx_mps", value=f"{ob.vx_mps:.3f}"),
                  KeyValuePair(key="vy_mps", value=f"{ob.vy_mps:.3f}")],
        cylinders=[CylinderPrimitive(pose=planar_pose(ob.x_m, ob.y_m, 0.0, 0.5),
                                     size=Vector3(x=2 * ob.radius_m, y=2 * ob.radius_m, z=1.0),
                                     bottom_scale=1.0, top_scale=1.0, color=OBSTACLE_COLOR)],
        arrows=arrows,
        texts=[TextPrimitive(pose=planar_pose(ob.x_m, ob.y_m, 0.0, 1.2), billboard=True, font_size=14.0,
                             scale_invariant=True, color=ARROW_COLOR, text=f"#{ob.track_id} {speed:.2f} m/s")],
    )


#: a standing person (``/people``): blue; a moving one has the obstacles' colour
STANDING_COLOR = Color(r=0.2, g=0.5, b=1.0, a=0.6)


def people_scene_update(people: typing.Iterable[Person], wall_s: float, lifetime_s: float) -> SceneUpdate:
    """``/people``: all previous entities deleted, then one per person: a cylinder of a person's size
    (moving: the obstacles' colour with a velocity arrow; standing: ``STANDING_COLOR``), a text with its
    id and P(moving), and every field of :class:`vipsm.types.Person` as metadata."""
    return _replace_scene(_person_entity, people, wall_s, lifetime_s)


def _person_entity(p: Person, ts: Timestamp, life: Duration) -> SceneEntity:
    arrows = _velocity_arrows(p.x_m, p.y_m, p.vx_mps, p.vy_mps) if p.moving else []
    meta = {"vx_mps": f"{p.vx_mps:.3f}", "vy_mps": f"{p.vy_mps:.3f}", "p_moving": f"{p.p_moving:.4f}",
            "moving": str(p.moving).lower(), "existence": f"{p.existence:.4f}",
            "covariance_m2": ",".join(f"{v:.6g}" for v in p.covariance),
            "legs": ";".join(f"{x:.3f},{y:.3f}" for x, y in p.legs)}
    return SceneEntity(
        timestamp=ts, frame_id="odom", id=f"person-{p.track_id}", lifetime=life, frame_locked=False,
        metadata=[KeyValuePair(key=k, value=v) for k, v in meta.items()],
        cylinders=[CylinderPrimitive(pose=planar_pose(p.x_m, p.y_m, 0.0, 0.85), size=Vector3(x=0.5, y=0.5, z=1.7),
                                     bottom_scale=1.0, top_scale=1.0,
                                     color=OBSTACLE_COLOR if p.moving else STANDING_COLOR)],
        arrows=arrows,
        texts=[TextPrimitive(pose=planar_pose(p.x_m, p.y_m, 0.0, 1.9), billboard=True, font_size=14.0,
                             scale_invariant=True, color=ARROW_COLOR,
                             text=f"person {p.track_id} P(moving) {p.p_moving:.2f}")],
    )


def transform(parent: str, child: str, wall_s: float, x_m: float, y_m: float, z_m: float,
              rotation: Quaternion) -> FrameTransform:
    return FrameTransform(timestamp=timestamp(wall_s), parent_frame_id=parent, child_frame_id=child,
                          translation=Vector3(x=x_m, y=y_m, z=z_m), rotation=rotation)


@dataclasses.dataclass(frozen=True)
class Mounts:
    """Where the sensors sit on the robot (``base_link``), from the estimator's configuration."""

    laser_x_m: float
    laser_y_m: float
    laser_theta_rad: float
    camera_x_m: float
    camera_y_m: float
    camera_z_m: float


def robot_transforms(pose: tuple[float, float, float], mounts: Mounts, pan_tilt_rad: tuple[float, float],
                     wall_s: float, truth: dict[str, Any] | None = None) -> FrameTransforms:
    """``odom -> base_link`` (the estimated pose), ``base_link -> laser``, ``base_link -> camera``
    (with the camera's pan and tilt); with the simulated truth also ``world -> odom`` and
    ``world -> truth/base_link``."""
    m = mounts
    tfs = [
        transform("odom", "base_link", wall_s, pose[0], pose[1], 0.0, yaw(pose[2])),
        transform("base_link", "laser", wall_s, m.laser_x_m, m.laser_y_m, 0.0, yaw(m.laser_theta_rad)),
        transform("base_link", "camera", wall_s, m.camera_x_m, m.camera_y_m, m.camera_z_m, pan_tilt(*pan_tilt_rad)),
    ]
    if truth is not None:
        ox, oy, oth = truth["origin"]
        rx, ry, rth = truth["robot"]
        tfs.append(transform("world", "odom", wall_s, ox, oy, 0.0, yaw(oth)))
        tfs.append(transform("world", "truth/base_link", wall_s, rx, ry, 0.0, yaw(rth)))
    return FrameTransforms(transforms=tfs)
