"""The ROS 2 message types the daemon publishes, written as IDL structs for the ``cyclonedds``
Python binding, so that no ROS install is needed.

ROS 2 maps ``<package>/msg/<Type>`` to the DDS type ``<package>::msg::dds_::<Type>_`` (the name
``rmw_cyclonedds_cpp`` registers) with the fields in the ``.msg`` order and the ``.msg`` primitive
types (``float64`` -> double, ``byte`` -> octet, ``T[N]`` -> array, ``T[]`` -> unbounded sequence,
``string`` -> string). Every struct here is final (plain CDR, XCDR1, as ROS 2 writes). The field lists
are checked against the ``.msg`` definitions of ROS 2 Humble and Jazzy (``rosbags``' type stores) by
``tests/app/test_ros2_msgs.py``, which also decodes bytes written here with ``rosbags``' CDR reader.

``radar_msgs/RadarTrack(s)`` (ros-perception/radar_msgs, released for Humble and Jazzy) is not in
``rosbags``' stores: its ``.msg`` text is :data:`RADAR_MSGS` (the same check runs against it).

Constants of a ``.msg`` (``Marker.CYLINDER``) are not on the wire; the binding takes no class
attributes but fields, so they are the enums :class:`MarkerConst`, :class:`DiagnosticLevel` and
:class:`RadarClassification`.
"""

# no ``from __future__ import annotations``: the binding reads the field types at class creation

from dataclasses import dataclass, field
from enum import IntEnum

import cyclonedds.idl.types as t
from cyclonedds.idl import IdlStruct

#: the ``.msg`` files of ``radar_msgs`` (ros2 branch) for the obstacle tracks
RADAR_MSGS = {
    "radar_msgs/msg/RadarTrack": """
uint16 NO_CLASSIFICATION=0
uint16 STATIC=1
uint16 DYNAMIC=2
unique_identifier_msgs/UUID uuid
geometry_msgs/Point position
geometry_msgs/Vector3 velocity
geometry_msgs/Vector3 acceleration
geometry_msgs/Vector3 size
uint16 classification
float32[6] position_covariance
float32[6] velocity_covariance
float32[6] acceleration_covariance
float32[6] size_covariance
""",
    "radar_msgs/msg/RadarTracks": """
std_msgs/Header header
radar_msgs/RadarTrack[] tracks
""",
}


def _dds(ros_type: str) -> str:
    """``sensor_msgs/msg/LaserScan`` -> ``sensor_msgs::msg::dds_::LaserScan_``."""
    pkg, _, name = ros_type.split("/")
    return f"{pkg}::msg::dds_::{name}_"


# -- builtin_interfaces, std_msgs, unique_identifier_msgs -------------------------------------------


@dataclass
class Time(IdlStruct, typename=_dds("builtin_interfaces/msg/Time")):
    sec: t.int32 = 0
    nanosec: t.uint32 = 0


@dataclass
class Duration(IdlStruct, typename=_dds("builtin_interfaces/msg/Duration")):
    sec: t.int32 = 0
    nanosec: t.uint32 = 0


@dataclass
class Header(IdlStruct, typename=_dds("std_msgs/msg/Header")):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class ColorRGBA(IdlStruct, typename=_dds("std_msgs/msg/ColorRGBA")):
    r: t.float32 = 0.0
    g: t.float32 = 0.0
    b: t.float32 = 0.0
    a: t.float32 = 0.0


@dataclass
class UUID(IdlStruct, typename=_dds("unique_identifier_msgs/msg/UUID")):
    uuid: t.array[t.uint8, 16] = field(default_factory=lambda: [0] * 16)


# -- geometry_msgs --------------------------------------------------------------------------------


@dataclass
class Point(IdlStruct, typename=_dds("geometry_msgs/msg/Point")):
    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0


@dataclass
class Vector3(IdlStruct, typename=_dds("geometry_msgs/msg/Vector3")):
    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename=_dds("geometry_msgs/msg/Quaternion")):
    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0
    w: t.float64 = 1.0


@dataclass
class Pose(IdlStruct, typename=_dds("geometry_msgs/msg/Pose")):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseWithCovariance(IdlStruct, typename=_dds("geometry_msgs/msg/PoseWithCovariance")):
    pose: Pose = field(default_factory=Pose)
    covariance: t.array[t.float64, 36] = field(default_factory=lambda: [0.0] * 36)


@dataclass
class PoseArray(IdlStruct, typename=_dds("geometry_msgs/msg/PoseArray")):
    header: Header = field(default_factory=Header)
    poses: t.sequence[Pose] = field(default_factory=list)


@dataclass
class Twist(IdlStruct, typename=_dds("geometry_msgs/msg/Twist")):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class TwistWithCovariance(IdlStruct, typename=_dds("geometry_msgs/msg/TwistWithCovariance")):
    twist: Twist = field(default_factory=Twist)
    covariance: t.array[t.float64, 36] = field(default_factory=lambda: [0.0] * 36)


@dataclass
class Transform(IdlStruct, typename=_dds("geometry_msgs/msg/Transform")):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class TransformStamped(IdlStruct, typename=_dds("geometry_msgs/msg/TransformStamped")):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


# -- sensor_msgs, nav_msgs, tf2_msgs ----------------------------------------------------------------


@dataclass
class LaserScan(IdlStruct, typename=_dds("sensor_msgs/msg/LaserScan")):
    header: Header = field(default_factory=Header)
    angle_min: t.float32 = 0.0
    angle_max: t.float32 = 0.0
    angle_increment: t.float32 = 0.0
    time_increment: t.float32 = 0.0
    scan_time: t.float32 = 0.0
    range_min: t.float32 = 0.0
    range_max: t.float32 = 0.0
    ranges: t.sequence[t.float32] = field(default_factory=list)
    intensities: t.sequence[t.float32] = field(default_factory=list)


@dataclass
class CompressedImage(IdlStruct, typename=_dds("sensor_msgs/msg/CompressedImage")):
    header: Header = field(default_factory=Header)
    format: str = ""
    data: t.sequence[t.uint8] = field(default_factory=bytes)


@dataclass
class Odometry(IdlStruct, typename=_dds("nav_msgs/msg/Odometry")):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


@dataclass
class TFMessage(IdlStruct, typename=_dds("tf2_msgs/msg/TFMessage")):
    transforms: t.sequence[TransformStamped] = field(default_factory=list)


class MarkerConst(IntEnum):
    """visualization_msgs/Marker's constants (types, then actions: ``MODIFY`` is ``ADD``)."""

    ARROW = 0
    CUBE = 1
    SPHERE = 2
    CYLINDER = 3
    LINE_STRIP = 4
    LINE_LIST = 5
    CUBE_LIST = 6
    SPHERE_LIST = 7
    POINTS = 8
    TEXT_VIEW_FACING = 9
    MESH_RESOURCE = 10
    TRIANGLE_LIST = 11
    ADD = 0
    MODIFY = 0
    DELETE = 2
    DELETEALL = 3


class DiagnosticLevel(IntEnum):
    """diagnostic_msgs/DiagnosticStatus's levels."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


class RadarClassification(IntEnum):
    """radar_msgs/RadarTrack's classifications (vendor-specific ones from 32000 on)."""

    NO_CLASSIFICATION = 0
    STATIC = 1
    DYNAMIC = 2


# -- visualization_msgs -------------------------------------------------------------------------------


@dataclass
class UVCoordinate(IdlStruct, typename=_dds("visualization_msgs/msg/UVCoordinate")):
    u: t.float32 = 0.0
    v: t.float32 = 0.0


@dataclass
class MeshFile(IdlStruct, typename=_dds("visualization_msgs/msg/MeshFile")):
    filename: str = ""
    data: t.sequence[t.uint8] = field(default_factory=bytes)


@dataclass
class Marker(IdlStruct, typename=_dds("visualization_msgs/msg/Marker")):
    """visualization_msgs/Marker as of Humble (``texture_resource``, ``texture``, ``uv_coordinates``,
    ``mesh_file`` added then); Jazzy has the same fields (and the constant ``ARROW_STRIP``). Its
    constants are :class:`MarkerConst`."""

    header: Header = field(default_factory=Header)
    ns: str = ""
    id: t.int32 = 0
    type: t.int32 = 0
    action: t.int32 = 0
    pose: Pose = field(default_factory=Pose)
    scale: Vector3 = field(default_factory=Vector3)
    color: ColorRGBA = field(default_factory=ColorRGBA)
    lifetime: Duration = field(default_factory=Duration)
    frame_locked: bool = False
    points: t.sequence[Point] = field(default_factory=list)
    colors: t.sequence[ColorRGBA] = field(default_factory=list)
    texture_resource: str = ""
    texture: CompressedImage = field(default_factory=CompressedImage)
    uv_coordinates: t.sequence[UVCoordinate] = field(default_factory=list)
    text: str = ""
    mesh_resource: str = ""
    mesh_file: MeshFile = field(default_factory=MeshFile)
    mesh_use_embedded_materials: bool = False


@dataclass
class MarkerArray(IdlStruct, typename=_dds("visualization_msgs/msg/MarkerArray")):
    markers: t.sequence[Marker] = field(default_factory=list)


# -- diagnostic_msgs ------------------------------------------------------------------------------------


@dataclass
class KeyValue(IdlStruct, typename=_dds("diagnostic_msgs/msg/KeyValue")):
    key: str = ""
    value: str = ""


@dataclass
class DiagnosticStatus(IdlStruct, typename=_dds("diagnostic_msgs/msg/DiagnosticStatus")):

    level: t.byte = 0
    name: str = ""
    message: str = ""
    hardware_id: str = ""
    values: t.sequence[KeyValue] = field(default_factory=list)


@dataclass
class DiagnosticArray(IdlStruct, typename=_dds("diagnostic_msgs/msg/DiagnosticArray")):
    header: Header = field(default_factory=Header)
    status: t.sequence[DiagnosticStatus] = field(default_factory=list)


# -- radar_msgs: tracked objects with position, velocity and covariance -------------------------------


@dataclass
class RadarTrack(IdlStruct, typename=_dds("radar_msgs/msg/RadarTrack")):

    uuid: UUID = field(default_factory=UUID)
    position: Point = field(default_factory=Point)
    velocity: Vector3 = field(default_factory=Vector3)
    acceleration: Vector3 = field(default_factory=Vector3)
    size: Vector3 = field(default_factory=Vector3)
    classification: t.uint16 = 0
    position_covariance: t.array[t.float32, 6] = field(default_factory=lambda: [0.0] * 6)
    velocity_covariance: t.array[t.float32, 6] = field(default_factory=lambda: [0.0] * 6)
    acceleration_covariance: t.array[t.float32, 6] = field(default_factory=lambda: [0.0] * 6)
    size_covariance: t.array[t.float32, 6] = field(default_factory=lambda: [0.0] * 6)


@dataclass
class RadarTracks(IdlStruct, typename=_dds("radar_msgs/msg/RadarTracks")):
    header: Header = field(default_factory=Header)
    tracks: t.sequence[RadarTrack] = field(default_factory=list)


#: every message type here by its ROS 2 name (``sensor_msgs/msg/LaserScan``)
ROS_TYPES: dict[str, type[IdlStruct]] = {
    "builtin_interfaces/msg/Time": Time,
    "builtin_interfaces/msg/Duration": Duration,
    "std_msgs/msg/Header": Header,
    "std_msgs/msg/ColorRGBA": ColorRGBA,
    "unique_identifier_msgs/msg/UUID": UUID,
    "geometry_msgs/msg/Point": Point,
    "geometry_msgs/msg/Vector3": Vector3,
    "geometry_msgs/msg/Quaternion": Quaternion,
    "geometry_msgs/msg/Pose": Pose,
    "geometry_msgs/msg/PoseWithCovariance": PoseWithCovariance,
    "geometry_msgs/msg/PoseArray": PoseArray,
    "geometry_msgs/msg/Twist": Twist,
    "geometry_msgs/msg/TwistWithCovariance": TwistWithCovariance,
    "geometry_msgs/msg/Transform": Transform,
    "geometry_msgs/msg/TransformStamped": TransformStamped,
    "sensor_msgs/msg/LaserScan": LaserScan,
    "sensor_msgs/msg/CompressedImage": CompressedImage,
    "nav_msgs/msg/Odometry": Odometry,
    "tf2_msgs/msg/TFMessage": TFMessage,
    "visualization_msgs/msg/UVCoordinate": UVCoordinate,
    "visualization_msgs/msg/MeshFile": MeshFile,
    "visualization_msgs/msg/Marker": Marker,
    "visualization_msgs/msg/MarkerArray": MarkerArray,
    "diagnostic_msgs/msg/KeyValue": KeyValue,
    "diagnostic_msgs/msg/DiagnosticStatus": DiagnosticStatus,
    "diagnostic_msgs/msg/DiagnosticArray": DiagnosticArray,
    "radar_msgs/msg/RadarTrack": RadarTrack,
    "radar_msgs/msg/RadarTracks": RadarTracks,
}
