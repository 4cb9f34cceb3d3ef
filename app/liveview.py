"""The live view: the field log's channels served over the Foxglove SDK's WebSocket server, so
Foxglove or Lichtblick (``ws://HOST:PORT``) shows scans, pose, transforms, obstacles, the camera and
the loop's health while the robot runs. Loopback only unless ``live.allow_remote`` is set (the
camera image and the robot's position would be readable by anyone on the network)."""

from __future__ import annotations

import ipaddress
from typing import Any

from .errors import AppError, ConfigError

DEFAULT_HOST = "127.0.0.1"
LAYOUT_FILE = "foxglove-layout.json"


def parse_listen(spec: str) -> tuple[str, int]:
    """``[HOST:]PORT`` -> (host, port); host 127.0.0.1 when left out; ``[::1]:8765`` for IPv6."""
    text = spec.strip()
    host, sep, port_text = text.rpartition(":")
    host = host.strip("[]") if sep else DEFAULT_HOST
    try:
        port = int(port_text)
    except ValueError:
        raise ConfigError("live.listen", f"{spec!r}: expected [HOST:]PORT, e.g. 8765 or 127.0.0.1:8765") from None
    if not 0 <= port <= 65535 or not host:
        raise ConfigError("live.listen", f"{spec!r}: the port must be 0-65535 and the host not empty")
    return host, port


def is_loopback(host: str) -> bool:
    try:
        return host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a host name may resolve to any interface


def check_exposure(host: str, allow_remote: bool) -> str:
    """'' on loopback; a warning when a remote address is allowed; ConfigError when it is not."""
    if is_loopback(host):
        return ""
    if not allow_remote:
        raise ConfigError("live.listen", f"a live view on {host!r} is reachable from the network: refused unless "
                                         "config key 'live.allow_remote' is true")
    return (f"live view on {host!r}: scans, pose, obstacles and camera images are readable by anyone who can "
            "reach this port (live.allow_remote = true)")


def layout_path() -> str:
    """The Foxglove layout shipped with the package (3D scene, camera, loop health, obstacle speed)."""
    from importlib.resources import files

    return str(files("app") / "deploy" / LAYOUT_FILE)


class LiveView:
    """A WebSocket server on the field log's SDK context (every channel, as it is logged)."""

    def __init__(self, context: Any, host: str, port: int) -> None:
        self.context = context
        self.host = host
        self.requested_port = port
        self._server: Any = None

    @property
    def port(self) -> int:
        return int(self._server.port) if self._server is not None else self.requested_port

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    def start(self) -> LiveView:
        import foxglove

        try:
            self._server = foxglove.start_server(name="vipsm-robot", host=self.host, port=self.requested_port,
                                                 context=self.context, message_backlog_size=256)
        except (RuntimeError, OSError) as exc:
            raise AppError(f"live view on {self.host}:{self.requested_port} failed: {exc}") from exc
        return self

    def stop(self) -> None:
        if self._server is not None:
            self._server.stop()
            self._server = None
