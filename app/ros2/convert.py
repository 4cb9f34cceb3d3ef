"""The daemon's data as ROS 2 messages (:mod:`app.ros2.msgs`): pure functions, run on the
publisher's thread.

Frames as in the field log (REP 105): ``odom`` (the estimator's frame), ``base_link``, ``laser``
(REP 117 scan, the first beam's time in the header), ``camera`` (the camera body, panned and tilted,
x forward) and ``camera_optical`` (REP 103's optical frame under it: z forward, x right, y down; the
images' frame); in simulated runs also ``world`` and ``truth/base_link``. Stamps are wall-clock time
(ROS's system time): a scan's is its first beam's (REP 117), an estimate's (``/odom``, ``/tf``, the
obstacles) its scan's, the time the pose and the obstacles' positions refer to, so that tf
transforms the scan with the pose matched to it.
"""

from __future__ import annotations

import math
import typing
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from .. import logmessages as lm
from . import msgs as m

if typing.TYPE_CHECKING:
    from vipsm.types import Estimate, Obstacle, Odometry

#: camera (x forward, y left, z up) -> camera_optical (z forward, x right, y down): rpy (-pi/2, 0, -pi/2)
OPTICAL_ROTATION = m.Quaternion(x=-0.5, y=0.5, z=-0.5, w=0.5)
OBSTACLE_COLOR = m.ColorRGBA(r=1.0, g=0.3, b=0.1, a=0.7)
PERSON_COLOR = m.ColorRGBA(r=0.2, g=0.6, b=1.0, a=0.7)
LABEL_COLOR = m.ColorRGBA(r=1.0, g=0.9, b=0.1, a=1.0)
#: what a planar estimate cannot know is said as in sensor_msgs: a covariance whose first element is -1
UNKNOWN_COVARIANCE = [-1.0] + [0.0] * 35


def stamp(wall_s: float) -> m.Time:
    ns = lm.stamp_ns(wall_s)
    return m.Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def header(wall_s: float, frame_id: str) -> m.Header:
    return m.Header(stamp=stamp(wall_s), frame_id=frame_id)


def yaw(theta_rad: float) -> m.Quaternion:
    return m.Quaternion(x=0.0, y=0.0, z=math.sin(theta_rad / 2.0), w=math.cos(theta_rad / 2.0))


def pan_tilt(pan_rad: float, tilt_rad: float) -> m.Quaternion:
    """The field log's pan/tilt rotation (:func:`app.logmessages.pan_tilt`, whose Foxglove quaternion
    is write-only): ``pan`` about z, then ``tilt`` about the panned y axis."""
    cp, sp = math.cos(pan_rad / 2.0), math.sin(pan_rad / 2.0)
    ct, st = math.cos(tilt_rad / 2.0), math.sin(tilt_rad / 2.0)
    return m.Quaternion(x=-sp * st, y=cp * st, z=sp * ct, w=cp * ct)


def planar_pose(x_m: float, y_m: float, theta_rad: float, z_m: float = 0.0) -> m.Pose:
    return m.Pose(position=m.Point(x=float(x_m), y=float(y_m), z=float(z_m)), orientation=yaw(theta_rad))


def laser_scan(ranges_m: np.ndarray, bearings_rad: np.ndarray, beam_dt_s: float, wall_s: float,
               scan_time_s: float, range_limits_m: tuple[float, float] | None) -> m.LaserScan:
    """REP 117: +inf no return, -inf too close, NaN erroneous (as the driver mapped them). Without the
    sensor's limits, range_min 0 and range_max +inf (every finite reading is valid)."""
    n = len(bearings_rad)
    lo, hi = range_limits_m if range_limits_m is not None else (0.0, math.inf)
    return m.LaserScan(
        header=header(wall_s, "laser"),
        angle_min=float(bearings_rad[0]) if n else 0.0,
        angle_max=float(bearings_rad[-1]) if n else 0.0,
        angle_increment=float(bearings_rad[1] - bearings_rad[0]) if n > 1 else 0.0,
        time_increment=float(beam_dt_s), scan_time=float(scan_time_s), range_min=float(lo), range_max=float(hi),
        ranges=np.asarray(ranges_m, np.float32).tolist(), intensities=[])


def covariance6(cov3: np.ndarray) -> list[float]:
    """A 3x3 (x, y, yaw) covariance as ROS's 6x6 (x, y, z, roll, pitch, yaw), row-major; z, roll and
    pitch are fixed by the floor (0); a non-finite one is unknown (-1 first)."""
    c = np.asarray(cov3, float)
    if c.shape != (3, 3) or not np.all(np.isfinite(c)):
        return list(UNKNOWN_COVARIANCE)
    out = np.zeros((6, 6))
    idx = [0, 1, 5]
    out[np.ix_(idx, idx)] = c
    return out.ravel().tolist()


def odometry(est: Estimate, odom: Odometry, wall_s: float) -> m.Odometry:
    """``odom -> base_link``: the estimator's pose with its covariance, the wheel odometry's twist at
    the scan's time (in ``base_link``; its covariance unknown: the base reports none)."""
    p = est.pose
    twist = m.Twist(linear=m.Vector3(x=float(odom.v_mps)), angular=m.Vector3(z=float(odom.w_radps)))
    return m.Odometry(
        header=header(wall_s, "odom"), child_frame_id="base_link",
        pose=m.PoseWithCovariance(pose=planar_pose(p.x_m, p.y_m, p.theta_rad), covariance=covariance6(est.covariance)),
        twist=m.TwistWithCovariance(twist=twist, covariance=list(UNKNOWN_COVARIANCE)))


def transform(parent: str, child: str, wall_s: float, xyz: Sequence[float],
              rotation: m.Quaternion) -> m.TransformStamped:
    return m.TransformStamped(header=header(wall_s, parent), child_frame_id=child, transform=m.Transform(
        translation=m.Vector3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])), rotation=rotation))


def dynamic_transforms(pose: tuple[float, float, float], mounts: lm.Mounts, pan_tilt_rad: tuple[float, float],
                       wall_s: float, truth: Mapping[str, typing.Any] | None) -> m.TFMessage:
    """``/tf``: odom -> base_link (the estimate), base_link -> camera (with pan and tilt); in simulated
    runs world -> odom and world -> truth/base_link (as the field log's ``/tf``)."""
    mt = mounts
    tfs = [transform("odom", "base_link", wall_s, (pose[0], pose[1], 0.0), yaw(pose[2])),
           transform("base_link", "camera", wall_s, (mt.camera_x_m, mt.camera_y_m, mt.camera_z_m),
                     pan_tilt(*pan_tilt_rad))]
    if truth is not None:
        ox, oy, oth = truth["origin"]
        rx, ry, rth = truth["robot"]
        tfs.append(transform("world", "odom", wall_s, (ox, oy, 0.0), yaw(oth)))
        tfs.append(transform("world", "truth/base_link", wall_s, (rx, ry, 0.0), yaw(rth)))
    return m.TFMessage(transforms=tfs)


def static_transforms(mounts: lm.Mounts, wall_s: float) -> m.TFMessage:
    """``/tf_static``: base_link -> laser (the estimator's laser mount), camera -> camera_optical."""
    return m.TFMessage(transforms=[
        transform("base_link", "laser", wall_s, (mounts.laser_x_m, mounts.laser_y_m, 0.0), yaw(mounts.laser_theta_rad)),
        transform("camera", "camera_optical", wall_s, (0.0, 0.0, 0.0), OPTICAL_ROTATION)])


def compressed_image(jpeg: bytes, wall_s: float) -> m.CompressedImage:
    return m.CompressedImage(header=header(wall_s, "camera_optical"), format="jpeg", data=jpeg)


def _lifetime(lifetime_s: float) -> m.Duration:
    ns = int(round(lifetime_s * 1e9))
    return m.Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def markers(obstacles: Iterable[Obstacle], wall_s: float, lifetime_s: float, ns: str,
            color: m.ColorRGBA) -> m.MarkerArray:
    """rviz2's view of the obstacles in ``odom``: every earlier marker deleted, then per obstacle a
    1 m cylinder of its radius, an arrow for its velocity (the distance covered in 1 s) and a label
    with its track id and speed; markers expire after ``lifetime_s`` if the daemon stops."""
    h, life = header(wall_s, "odom"), _lifetime(lifetime_s)
    out = [m.Marker(header=h, ns=ns, action=m.MarkerConst.DELETEALL)]
    for ob in obstacles:
        speed = math.hypot(ob.vx_mps, ob.vy_mps)
        d = 2.0 * ob.radius_m
        out.append(m.Marker(header=h, ns=ns, id=ob.track_id, type=m.MarkerConst.CYLINDER, action=m.MarkerConst.ADD,
                            pose=planar_pose(ob.x_m, ob.y_m, 0.0, 0.5), scale=m.Vector3(x=d, y=d, z=1.0),
                            color=color, lifetime=life))
        out.append(m.Marker(header=h, ns=f"{ns}/velocity", id=ob.track_id, type=m.MarkerConst.ARROW,
                            action=m.MarkerConst.ADD, scale=m.Vector3(x=0.04, y=0.12, z=0.1), color=LABEL_COLOR,
                            lifetime=life, points=[m.Point(x=ob.x_m, y=ob.y_m, z=1.0),
                                                   m.Point(x=ob.x_m + ob.vx_mps, y=ob.y_m + ob.vy_mps, z=1.0)]))
        out.append(m.Marker(header=h, ns=f"{ns}/label", id=ob.track_id, type=m.MarkerConst.TEXT_VIEW_FACING,
                            action=m.MarkerConst.ADD, pose=planar_pose(ob.x_m, ob.y_m, 0.0, 1.3),
                            scale=m.Vector3(z=0.2), color=LABEL_COLOR, lifetime=life,
                            text=f"#{ob.track_id} {speed:.2f} m/s"))
    return m.MarkerArray(markers=out)


def _upper_triangle(cov2: np.ndarray) -> list[float]:
    """A 2x2 (x, y) covariance as radar_msgs' upper triangle over x, y, z: xx, xy, xz, yy, yz, zz."""
    return [float(cov2[0, 0]), float(cov2[0, 1]), 0.0, float(cov2[1, 1]), 0.0, 0.0]


def track_uuid(run_id: bytes, track_id: int) -> m.UUID:
    """16 bytes: 8 random bytes per publisher run, then the track id (big-endian): ids restart each
    run, the UUID does not repeat."""
    return m.UUID(uuid=run_id[:8] + int(track_id).to_bytes(8, "big", signed=True))


def tracks(obstacles: Iterable[Obstacle], wall_s: float, run_id: bytes) -> m.RadarTracks:
    """radar_msgs/RadarTracks in ``odom``: per obstacle its position, velocity and their covariances
    (the tracker's 4x4 (x, y, vx, vy) covariance split into two 2x2 blocks: radar_msgs has no
    position-velocity cross terms), its diameter as size, classification DYNAMIC (the daemon reports
    moving obstacles). Acceleration is not estimated (constant-velocity models): 0 with covariance 0;
    a track without covariance gets NaN covariances."""
    out = []
    for ob in obstacles:
        if len(ob.covariance) == 16:
            c = np.asarray(ob.covariance, float).reshape(4, 4)
            pos, vel = _upper_triangle(c[:2, :2]), _upper_triangle(c[2:, 2:])
        else:
            pos = vel = [math.nan] * 6
        d = 2.0 * ob.radius_m
        out.append(m.RadarTrack(uuid=track_uuid(run_id, ob.track_id), position=m.Point(x=ob.x_m, y=ob.y_m),
                                velocity=m.Vector3(x=ob.vx_mps, y=ob.vy_mps), size=m.Vector3(x=d, y=d),
                                classification=m.RadarClassification.DYNAMIC, position_covariance=pos,
                                velocity_covariance=vel))
    return m.RadarTracks(header=header(wall_s, "odom"), tracks=out)


DEVICE_HARDWARE = {"scanner": "Hokuyo UTM-30LX", "base": "Pioneer 3-DX", "camera": "Sony SNC-RZ50"}


def _device_level(device: str, state: str) -> int:
    """ok: OK; connecting or stalled: WARN; failed: ERROR; absent: ERROR for the scanner and the base
    (the loop stops the base without them), OK for the camera (plain PSM)."""
    if state == "ok" or (state == "absent" and device == "camera"):
        return m.DiagnosticLevel.OK
    if state in ("connecting", "stalled"):
        return m.DiagnosticLevel.WARN
    return m.DiagnosticLevel.ERROR


def _kv(values: Mapping[str, typing.Any]) -> list[m.KeyValue]:
    return [m.KeyValue(key=k, value=str(v)) for k, v in values.items()]


def diagnostics(diag: Mapping[str, typing.Any], counters: Mapping[str, Mapping[str, int]],
                publisher: Mapping[str, typing.Any], wall_s: float) -> m.DiagnosticArray:
    """``/diagnostics``: one status per device (state, the driver's counters), the loop (health,
    mission, flags), the field log and this publisher, named ``vipsm-robot: <part>`` as
    rqt_robot_monitor and diagnostic_aggregator group them."""
    flags = set(diag["flags"])
    status = []
    for dev in ("scanner", "base", "camera"):
        state = diag[dev]
        status.append(m.DiagnosticStatus(level=_device_level(dev, state), name=f"vipsm-robot: {dev}",
                                         message=state, hardware_id=DEVICE_HARDWARE[dev],
                                         values=_kv({"state": state, **counters.get(dev, {})})))
    healthy = "loop_healthy" in flags
    status.append(m.DiagnosticStatus(
        level=m.DiagnosticLevel.OK if healthy else m.DiagnosticLevel.WARN, name="vipsm-robot: loop",
        message="healthy" if healthy else f"not healthy ({diag['mission']})",
        values=_kv({k: diag[k] for k in ("cycle", "compute_ms", "deadline_misses", "mission")}
                   | {"flags": " ".join(sorted(flags))})))
    log_level = m.DiagnosticLevel.ERROR if "log_error" in flags else m.DiagnosticLevel.OK
    status.append(m.DiagnosticStatus(level=log_level, name="vipsm-robot: field log", message=diag["log_state"],
                                     values=_kv({"state": diag["log_state"], "dropped": diag["log_dropped"]})))
    status.append(m.DiagnosticStatus(
        level=m.DiagnosticLevel.OK if not publisher.get("errors") else m.DiagnosticLevel.WARN,
        name="vipsm-robot: ros2 publisher", message=str(publisher.get("state", "")), values=_kv(publisher)))
    return m.DiagnosticArray(header=header(wall_s, ""), status=status)
