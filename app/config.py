"""Daemon configuration: TOML into frozen dataclasses, with defaults shipped in code.

* ``load_config(path, overrides)`` reads a TOML file (``tomllib``), applies ``--set key=value``
  overrides, and builds :class:`Config`. Every bad value raises :class:`app.errors.ConfigError`
  whose message names the dotted key, e.g. ``config key 'loop.period_s': must be >= 0.01``.
* ``dump_toml(Config())`` prints the defaults as TOML (``vipsm-robot dump-config``); loading that
  text gives back the defaults exactly.

Field constraints live in the field metadata (``min``, ``max``, ``choices``) so the checks are
generic. Device entries are URLs, so a fake device needs no special code path.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import tomllib
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from vipsm.estimator import EstimatorConfig

from .errors import ConfigError

#: no setting (a URL, a path, a host) is longer than this; longer is a mistake or an attack
MAX_STRING_CHARS = 4096


def _f(default: Any, doc: str, **meta: Any) -> Any:
    return field(default=default, metadata={"doc": doc, **meta})


@dataclass(frozen=True)
class DevicesConfig:
    scanner_url: str = _f("/dev/hokuyo", "UTM-30LX: tty, pty or socket://host:10940 (Ethernet model); empty = none")
    scanner_intensity: bool = _f(False, "stream ME (ranges + intensities) instead of MD")
    robot_url: str = _f("/dev/pioneer", "Pioneer 3-DX: tty or socket://host:8101 (simulator); empty = none")
    robot_baud: int = _f(9600, "ARCOS serial rate", choices=(9600, 19200, 38400, 57600, 115200))
    robot_command_timeout_s: float = _f(
        1.0, "the base driver commands zero velocity when the loop sends nothing this long (a stalled loop)", min=0.2
    )
    robot_command_period_s: float = _f(
        0.1, "an unchanged velocity command is re-sent this often (a change goes out at once); the ARCOS "
        "server cycle is 100 ms, so a 40 Hz loop need not write every cycle; 0 = every cycle", min=0.0, max=0.5
    )
    camera_url: str = _f("/dev/ptzcam", "SNC-RZ50 VISCA: tty or socket://host:port; empty = no PTZ control")
    camera_baud: int = _f(9600, "VISCA serial rate", choices=(9600, 38400))
    camera_http_url: str = _f(
        "", "SNC-RZ50 HTTP base URL for frames, e.g. http://user:pw@192.168.0.100; empty = no camera"
    )
    camera_fps: int = _f(10, "MJPEG rate asked of the camera", min=1, max=30)
    camera_pan_deg: float = _f(0.0, "pan set at start-up (left positive)", min=-170.0, max=170.0)
    camera_tilt_deg: float = _f(0.0, "tilt set at start-up (up positive)", min=-25.0, max=90.0)
    camera_zoom: int = _f(0, "zoom position set at start-up (0 = wide)", min=0, max=0x4000)
    camera_k1: float = _f(0.0, "lens distortion k1 (Brown-Conrady, OpenCV's calibrateCamera) at the zoom used; "
                          "[?] unmeasured for the SNC-RZ50: 0 = pinhole", min=-2.0, max=2.0)
    camera_k2: float = _f(0.0, "lens distortion k2 [?]", min=-2.0, max=2.0)
    camera_p1: float = _f(0.0, "tangential distortion p1 [?]", min=-0.5, max=0.5)
    camera_p2: float = _f(0.0, "tangential distortion p2 [?]", min=-0.5, max=0.5)
    reconnect_max_s: float = _f(2.0, "longest wait between reconnect attempts", min=0.05)
    startup_wait_s: float = _f(
        10.0, "at start-up, wait this long at most for the devices to open before the loop runs", min=0.0, max=600.0
    )


@dataclass(frozen=True)
class LoopConfig:
    period_s: float = _f(0.1, "control period on monotonic deadlines (with trigger = scan: the longest wait)",
                         min=0.01, max=1.0)
    trigger: str = _f("timer", "timer: a cycle every period_s; scan: a cycle as each scan arrives (every UTM-30LX "
                      "scan, 40 Hz), or after period_s without one", choices=("timer", "scan"))
    max_scan_age_s: float = _f(0.0, "a newer scan than this is required, older = scanner stalled; 0 = "
                               "max_scan_age_periods of the scanner's own period (from the scan) + period_s",
                               min=0.0)
    max_scan_age_periods: float = _f(6.0, "with max_scan_age_s = 0: scan periods before the scanner counts as "
                                     "stalled (+ period_s: 0.25 s at 40 Hz, 0.9 s at 7.5 Hz)", min=1.0, max=100.0)
    max_frame_age_s: float = _f(0.3, "a scan is paired with the frame taken nearest it, at most this far from "
                                "its stamp (none: plain PSM for the cycle); no frame for this long: camera "
                                "stalled", min=0.01)
    max_odometry_age_s: float = _f(0.35, "odometry older than this = base lost", min=0.01)


@dataclass(frozen=True)
class MissionConfig:
    mode: str = _f("hold", "hold: observe without motion; cruise: straight ahead", choices=("hold", "cruise"))
    cruise_speed_mps: float = _f(0.2, "forward speed in cruise", min=0.0, max=1.5)
    safety_radius_m: float = _f(
        0.9, "stop when a tracked obstacle is predicted within this distance of the robot", min=0.0
    )
    safety_horizon_s: float = _f(2.0, "how far ahead obstacle paths are predicted", min=0.0, max=30.0)
    resume_after_clear_s: float = _f(1.0, "the zone must stay clear this long before motion resumes", min=0.0)


@dataclass(frozen=True)
class SafetyConfig:
    """The protective field (``app.protective_field``) and the loop's overload handling."""

    field_enabled: bool = _f(
        True, "protective field on the raw scan: in mission.mode = cruise, stop while a confirmed return lies in the "
        "corridor ahead within the stopping distance (hold never moves, so the field is not judged there)"
    )
    corridor_width_m: float = _f(
        0.625, "corridor width, centred on the heading: the Pioneer 3-DX's 0.425 m plus 0.10 m each side", min=0.1,
        max=5.0
    )
    front_m: float = _f(0.256, "robot origin to the front bumper (Pioneer 3-DX: half its 0.511 m length)",
                        min=0.0, max=5.0)
    deceleration_mps2: float = _f(
        0.3, "braking the stopping distance assumes (Pioneer 3-DX firmware TRANSDECEL: 300 mm/s^2)", min=0.05, max=10.0
    )
    latency_s: float = _f(
        0.3, "object appearing -> base decelerating: one scan (25 ms), one loop period (0.1 s), one ARCOS server "
        "cycle (0.1 s), serial and margin", min=0.0, max=5.0
    )
    margin_m: float = _f(0.2, "distance kept to the object after stopping (odometry and range errors)",
                         min=0.0, max=5.0)
    cluster_gap_m: float = _f(
        0.1, "two in-field returns of beams at most two apart belong to one object if closer than this", min=0.005,
        max=1.0
    )
    min_returns: int = _f(
        2, "returns one object must show in the field to stop the robot (1: any single return, even a mixed pixel "
        "or a spurious return)", min=1, max=50
    )


@dataclass(frozen=True)
class LogConfig:
    path: str = _f("vipsm-%Y%m%d-%H%M%S.mcap", "field log file (strftime pattern); empty = no log")
    compression: str = _f("zstd", "MCAP chunk compression", choices=("zstd", "lz4", "none"))
    rotate_bytes: int = _f(512 * 1024 * 1024, "start a new file past this size", min=1024 * 1024)
    rotate_s: float = _f(3600.0, "start a new file after this long", min=1.0)
    flush_s: float = _f(0.5, "close a chunk at least this often (bounds the loss on power cut)", min=0.05, max=1.0)
    queue_size: int = _f(512, "messages buffered for the writer thread; more are dropped and counted", min=8, max=65536)
    frames: bool = _f(True, "record camera frames (JPEG)")


@dataclass(frozen=True)
class StatusConfig:
    enabled: bool = _f(True, "serve the Modbus TCP status registers")
    host: str = _f("127.0.0.1", "Modbus TCP bind address")
    port: int = _f(5020, "Modbus TCP port (0: any free port)", min=0, max=65535)
    allow_stop_coil: bool = _f(False, "honour writes to the stop coil (coil 0)")
    max_connections: int = _f(8, "Modbus clients served at once; more are disconnected at once", min=1, max=256)
    idle_timeout_s: float = _f(30.0, "a Modbus connection that sends nothing this long is closed", min=1.0, max=3600.0)


@dataclass(frozen=True)
class LiveConfig:
    listen: str = _f("", "live view (Foxglove WebSocket) as [HOST:]PORT, e.g. 8765; empty = off; --live sets it")
    allow_remote: bool = _f(False, "allow a live view on a non-loopback address (anyone reaching it sees the robot)")
    max_clients: int = _f(8, "viewers served at once (a handshake under way counts); more get HTTP 503", min=1, max=256)
    handshake_timeout_s: float = _f(5.0, "a connection whose WebSocket upgrade is not complete this long is closed",
                                    min=0.5, max=60.0)
    send_queue_bytes: int = _f(1 << 20, "bytes queued for one viewer: past this its messages are dropped, past twice "
                               "this it is disconnected", min=64 * 1024, max=256 << 20)
    stall_timeout_s: float = _f(10.0, "a viewer whose queue stays full this long (it stopped reading) is disconnected",
                                min=1.0, max=3600.0)

    def __post_init__(self) -> None:
        if self.listen:  # checked here, so dump-config, run and sim refuse the same values
            from .listen_address import check_exposure, parse_listen

            check_exposure(parse_listen(self.listen)[0], self.allow_remote)


@dataclass(frozen=True)
class Ros2Config:
    enabled: bool = _f(False, "publish live ROS 2 topics over DDS (Cyclone DDS, no ROS install needed); --ros2 sets it")
    domain_id: int = _f(-1, "DDS domain (ROS_DOMAIN_ID of the ROS 2 machines); -1 = the ROS_DOMAIN_ID environment "
                        "variable, else 0", min=-1, max=232)
    namespace: str = _f("", "ROS namespace before every topic, tf's too (/robot1 -> /robot1/scan); empty = none")
    cyclonedds_config: str = _f("", "Cyclone DDS XML config file (interfaces, peers); empty = CYCLONEDDS_URI, "
                                "else Cyclone's defaults (multicast on the default interface)")
    queue_size: int = _f(64, "messages waiting for the publisher's thread; more drop the oldest (counted)",
                         min=8, max=4096)

    def __post_init__(self) -> None:
        from .ros2.qos import normalise_namespace

        normalise_namespace(self.namespace)  # ConfigError naming ros2.namespace


@dataclass(frozen=True)
class Config:
    devices: DevicesConfig = field(default_factory=DevicesConfig)
    loop: LoopConfig = field(default_factory=LoopConfig)
    mission: MissionConfig = field(default_factory=MissionConfig)
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    log: LogConfig = field(default_factory=LogConfig)
    status: StatusConfig = field(default_factory=StatusConfig)
    live: LiveConfig = field(default_factory=LiveConfig)
    ros2: Ros2Config = field(default_factory=Ros2Config)
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)


# ---------------------------------------------------------------------------------------------
# building dataclasses from dicts, with checks that name the key


def _check_scalar(key: str, value: Any, hint: Any, meta: typing.Mapping[str, Any]) -> Any:
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if value is None and len(args) < len(typing.get_args(hint)):
            return None
        hint = args[0] if len(args) == 1 else hint
        origin = typing.get_origin(hint)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ConfigError(key, f"expected an array, got {value!r}")
        args = typing.get_args(hint)
        item_hint = args[0] if args else Any
        value = tuple(_check_scalar(f"{key}[{i}]", v, item_hint, {}) for i, v in enumerate(value))
        if len(args) > 1 and args[1] is not Ellipsis and len(value) != len(args):
            raise ConfigError(key, f"expected {len(args)} values, got {len(value)}")
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(key, f"expected true or false, got {value!r}")
    elif hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(key, f"expected an integer, got {value!r}")
    elif hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(key, f"expected a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(key, f"must be finite, got {value!r}")
    elif hint is str:
        if not isinstance(value, str):
            raise ConfigError(key, f"expected a string, got {value!r}")
        if len(value) > MAX_STRING_CHARS:
            raise ConfigError(key, f"longer than {MAX_STRING_CHARS} characters ({len(value)})")
    if "choices" in meta and value not in meta["choices"]:
        raise ConfigError(key, f"must be one of {', '.join(map(str, meta['choices']))}; got {value!r}")
    if "min" in meta and value < meta["min"]:
        raise ConfigError(key, f"must be >= {meta['min']}, got {value!r}")
    if "max" in meta and value > meta["max"]:
        raise ConfigError(key, f"must be <= {meta['max']}, got {value!r}")
    return value


def from_dict(cls: type, data: typing.Mapping[str, Any], prefix: str = "") -> Any:
    """Build dataclass ``cls`` from ``data``; unknown keys and bad values raise ConfigError."""
    if not isinstance(data, dict):
        raise ConfigError(prefix.rstrip(".") or "<root>", f"expected a table, got {data!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        dotted = f"{prefix}{key}"
        if key not in fields:
            removed = getattr(cls, "REMOVED_KEYS", {}).get(key)  # a key an older version had
            if removed is not None:
                raise ConfigError(dotted, f"this key was removed ({removed}); delete it from the config file")
            raise ConfigError(dotted, f"unknown key (known: {', '.join(sorted(fields))})")
        hint = hints[key]
        if dataclasses.is_dataclass(hint):
            kwargs[key] = from_dict(hint, value, f"{dotted}.")
        else:
            kwargs[key] = _check_scalar(dotted, value, hint, fields[key].metadata)
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(prefix.rstrip(".") or "<root>", str(exc)) from exc


def parse_override(text: str) -> tuple[list[str], Any]:
    """``a.b.c=value`` -> (["a", "b", "c"], value); the value is read as TOML, else as a bare string."""
    if "=" not in text:
        raise ConfigError(text, "an override must be key=value")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key:
        raise ConfigError(text, "empty key in override")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key.split("."), value


def merge_override(data: dict[str, Any], path: list[str], value: Any) -> None:
    node = data
    for part in path[:-1]:
        child = node.setdefault(part, {})
        if not isinstance(child, dict):
            raise ConfigError(".".join(path), f"'{part}' is a value, not a table")
        node = child
    node[path[-1]] = value


def load_config(path: str | Path | None = None, overrides: typing.Sequence[str] = ()) -> Config:
    data: dict[str, Any] = {}
    if path is not None:
        p = Path(path)
        try:
            data = tomllib.loads(p.read_text(encoding="utf-8"))
        except FileNotFoundError as exc:
            raise ConfigError("--config", f"no such file: {p}") from exc
        except (OSError, UnicodeDecodeError) as exc:
            raise ConfigError("--config", f"cannot read {p}: {exc}") from exc
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError("--config", f"{p} is not valid TOML: {exc}") from exc
    for text in overrides:
        key_path, value = parse_override(text)
        merge_override(data, key_path, value)
    return from_dict(Config, data)


# ---------------------------------------------------------------------------------------------
# TOML output


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if value is None:
        raise ValueError("TOML has no null")
    raise TypeError(f"cannot write {type(value).__name__} as TOML")


def dump_toml(obj: Any, prefix: str = "") -> str:
    """The dataclass tree as TOML, with each field's doc as a comment."""
    lines: list[str] = []
    tables: list[str] = []
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if dataclasses.is_dataclass(value):
            tables.append(dump_toml(value, f"{prefix}{f.name}."))
            continue
        if value is None:
            continue
        doc = f.metadata.get("doc")
        if doc:
            lines.append(f"# {doc}")
        lines.append(f"{f.name} = {_toml_value(value)}")
    out = ""
    if lines:
        header = f"[{prefix.rstrip('.')}]\n" if prefix else ""
        out = header + "\n".join(lines) + "\n\n"
    return out + "".join(tables)


# ---------------------------------------------------------------------------------------------
# secrets: redacted in every logged or printed copy of the configuration and in every message line
# (the field log's /vipsm/config and so the live view, stderr, summaries); ``dump-config`` prints the
# configuration the user gave, in full, because it is the user's own file to edit

#: a key whose name holds one of these words holds a secret (any section, any future key)
SECRET_KEY_WORDS = ("password", "passwd", "secret", "token", "api_key", "apikey", "credential", "private_key")
REDACTED = "***"
#: ``scheme://netloc``: the user information is what precedes the netloc's last ``@``
_URL_NETLOC = re.compile(r"(?P<scheme>[A-Za-z][A-Za-z0-9+.\-]*://)(?P<netloc>[^/?#\s]*)")
#: a secret passed as a URL query parameter (``?password=...``, ``&token=...``)
_QUERY_SECRET = re.compile(r"(?P<key>[?&;](?:[A-Za-z_]*(?:password|passwd|pwd|token|secret|api_?key))=)[^&#;\s]*",
                           re.IGNORECASE)


def _redact_netloc(m: re.Match[str]) -> str:
    userinfo, at, host = m["netloc"].rpartition("@")
    if not at or ":" not in userinfo:
        return m.group(0)
    return f"{m['scheme']}{userinfo.partition(':')[0]}:{REDACTED}@{host}"


def redact_text(text: str) -> str:
    """``text`` with the password of every URL in it (``http://user:pw@host`` -> ``http://user:***@host``)
    and every secret query parameter replaced by ``***``."""
    return _QUERY_SECRET.sub(lambda m: m["key"] + REDACTED, _URL_NETLOC.sub(_redact_netloc, text))


def is_secret_key(key: str) -> bool:
    k = key.lower()
    return any(word in k for word in SECRET_KEY_WORDS)


def redacted(value: Any, key: str = "") -> Any:
    """A copy of a configuration tree (dicts, lists, tuples, scalars) with every secret replaced:
    the value of a key that names one (:data:`SECRET_KEY_WORDS`) when it is set, and the passwords in
    every string (:func:`redact_text`)."""
    if isinstance(value, dict):
        return {k: redacted(v, str(k)) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [redacted(v, key) for v in value]
    if isinstance(value, str):
        return REDACTED if value and is_secret_key(key) else redact_text(value)
    return value


def redacted_config(config: Config) -> dict[str, Any]:
    """The configuration as ``dataclasses.asdict`` gives it, secrets redacted: what the field log
    records (``/vipsm/config``) and what may be printed."""
    return redacted(dataclasses.asdict(config))  # type: ignore[no-any-return]
