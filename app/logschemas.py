"""JSON schemas of the field log's own channels (``/vipsm/cycle``, ``/vipsm/config``,
``/vipsm/scanner``, ``/diagnostics``, ``/truth``): every field named, typed and required, no other field allowed, so a
reader (Foxglove, ``replay``, a user's script) can rely on them and a test can check every message.
The ``/vipsm/config`` schema is derived from the configuration dataclasses, so it cannot drift."""

from __future__ import annotations

import dataclasses
import typing
from typing import Any

NUMBER = {"type": "number"}
NUMBER_OR_NULL = {"type": ["number", "null"]}
INTEGER = {"type": "integer"}
STRING = {"type": "string"}
BOOLEAN = {"type": "boolean"}


def obj(description: str = "", **props: Any) -> dict[str, Any]:
    """An object with exactly these properties, all required."""
    out: dict[str, Any] = {"type": "object", "properties": props, "required": sorted(props),
                           "additionalProperties": False}
    if description:
        out["description"] = description
    return out


def array(items: dict[str, Any], n: int | None = None) -> dict[str, Any]:
    out: dict[str, Any] = {"type": "array", "items": items}
    if n is not None:
        out["minItems"] = out["maxItems"] = n
    return out


_OBSTACLE = obj(
    track_id=INTEGER, x_m=NUMBER, y_m=NUMBER, vx_mps=NUMBER, vy_mps=NUMBER, radius_m=NUMBER,
    bearing_min_rad=NUMBER, bearing_max_rad=NUMBER, scan_index_start=INTEGER, scan_index_stop=INTEGER,
)

_ESTIMATE = obj(
    "the estimator's output: pose [x_m, y_m, theta_rad] in odom, 3x3 covariance row-major",
    stamp_s=NUMBER, pose=array(NUMBER, 3), covariance=array(NUMBER_OR_NULL, 9), flags=INTEGER,
    quality=obj(beams_used=INTEGER, iterations=INTEGER, residual_m=NUMBER_OR_NULL, converged=BOOLEAN),
    obstacles=array(_OBSTACLE), restored=array(array(INTEGER, 2)),
)

_FRAME = obj(
    "the camera frame used (its JPEG is the /camera/image message logged at image_log_time_ns); intrinsics "
    "[fx, fy, cx, cy, width, height] in pixels, distortion [k1, k2, p1, p2]",
    seq=INTEGER, stamp_s=NUMBER, pan_rad=NUMBER, tilt_rad=NUMBER, intrinsics=array(NUMBER, 6),
    distortion=array(NUMBER, 4), image_log_time_ns=INTEGER,
)

CYCLE = obj(
    "one estimator cycle: its exact inputs and outputs (replay runs from these alone)",
    cycle=INTEGER,
    scan=obj(seq=INTEGER, stamp_s=NUMBER, beam_dt_s=NUMBER, first_bearing_rad=NUMBER, bearing_step_rad=NUMBER,
             ranges_m=array(NUMBER_OR_NULL)),
    odometry=obj(x_m=NUMBER, y_m=NUMBER, theta_rad=NUMBER, v_mps=NUMBER, w_radps=NUMBER, stamp_s=NUMBER),
    frame={"oneOf": [{"type": "null"}, _FRAME]},
    estimate=_ESTIMATE,
)

SCANNER_INFO = obj(
    "the laser scanner's geometry, timing and range limits as its data states them (the UTM-30LX's PP reply, a "
    "ROS bag's LaserScan fields), for the /scan messages that follow: written before the first scan and again "
    "whenever a value changes. beams and angle_*_rad describe those scans (bearing of beam i = angle_min_rad + "
    "i * angle_increment_rad); time_increment_s is the time from beam i to beam i + 1 (negative: taken in "
    "descending order) and scan_time_s the time between scans (one turn of the mirror), 0 where the data does "
    "not say; range_min_m / range_max_m are the limits of a valid reading, null where the data does not say",
    beams=INTEGER, angle_min_rad=NUMBER, angle_max_rad=NUMBER, angle_increment_rad=NUMBER,
    time_increment_s=NUMBER, scan_time_s=NUMBER, range_min_m=NUMBER_OR_NULL, range_max_m=NUMBER_OR_NULL,
)


DIAGNOSTICS = obj(
    "loop health and device states, every cycle",
    cycle=INTEGER, stamp_s=NUMBER, compute_ms=NUMBER, deadline_misses=INTEGER,
    scanner=STRING, base=STRING, camera=STRING, mission=STRING, log_dropped=INTEGER,
    log_state=STRING, flags=array(STRING),
)

GROUND_TRUTH = obj(
    "the simulated world's truth at the scan's stamp: origin = world pose of the odom frame, robot = "
    "world pose [x_m, y_m, theta_rad], obstacles = rows [x_m, y_m, vx_mps, vy_mps, radius_m, moving, in_view]",
    stamp_s=NUMBER, origin=array(NUMBER, 3), robot=array(NUMBER, 3),
    obstacles=array(array({"type": ["number", "boolean"]}, 7)),
)


def dataclass_schema(cls: type, description: str = "") -> dict[str, Any]:
    """The JSON schema of a configuration dataclass tree (as ``dataclasses.asdict`` writes it)."""
    hints = typing.get_type_hints(cls)
    props = {f.name: _type_schema(hints[f.name]) for f in dataclasses.fields(cls)}
    return obj(description, **props)


def _type_schema(tp: Any) -> dict[str, Any]:
    if dataclasses.is_dataclass(tp):
        return dataclass_schema(tp)  # type: ignore[arg-type]
    origin = typing.get_origin(tp)
    if origin in (tuple, list):
        args = [a for a in typing.get_args(tp) if a is not Ellipsis]
        return array(_type_schema(args[0]) if args else {})
    if origin is typing.Union or str(origin) == "<class 'types.UnionType'>":
        return {"anyOf": [_type_schema(a) for a in typing.get_args(tp)]}
    simple = {bool: BOOLEAN, int: INTEGER, float: NUMBER, str: STRING, type(None): {"type": "null"}}
    if tp in simple:
        return simple[tp]
    raise TypeError(f"no JSON schema for configuration type {tp!r}")


def config_schema() -> dict[str, Any]:
    from .config import Config

    schema = dataclass_schema(Config, "the daemon's whole configuration at start, and the log's layout version")
    schema["properties"]["log_version"] = INTEGER
    schema["required"] = sorted([*schema["required"], "log_version"])
    return schema
