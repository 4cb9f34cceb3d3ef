"""Serving the fake UTM-30LX on a pty or TCP."""

from __future__ import annotations

from ..transport import DeviceServer, PtyEndpoint, TcpEndpoint
from .model import Utm30lxModel

# --------------------------------------------------------------------------------------------
# Serving
# --------------------------------------------------------------------------------------------


def serve_pty(model: Utm30lxModel | None = None, link_path: str | None = None) -> DeviceServer:
    """Start the fake on a pseudo-terminal (``server.address`` is the device path)."""
    return DeviceServer(model or Utm30lxModel(), PtyEndpoint(link_path)).start()


def serve_tcp(model: Utm30lxModel | None = None, host: str = "127.0.0.1", port: int = 0) -> DeviceServer:
    """Start the fake on a loopback TCP port (``server.address`` is ``socket://host:port``)."""
    return DeviceServer(model or Utm30lxModel(), TcpEndpoint(host, port)).start()
