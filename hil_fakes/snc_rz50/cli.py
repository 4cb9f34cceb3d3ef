"""``vipsm-robot fake camera``: serving the fake SNC-RZ50, its command-line options."""

from __future__ import annotations

import argparse
import time

from ..transport import DeviceServer, PtyEndpoint, TcpEndpoint
from .camera import CameraHttpServer, FakeCamera, serve_visca
from .mechanics import FakeCameraSpec
from .render import Renderer

# ---------------------------------------------------------------------------------------------
# CLI: `vipsm-robot fake camera ...` (wired in app/cmd_camera.py)


def add_cli_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--visca-pty", action="store_true", help="serve VISCA on a pseudo-terminal")
    parser.add_argument("--link", metavar="PATH", help="stable symlink to the pty (like /dev/ptzcam)")
    parser.add_argument("--visca-tcp", metavar="HOST:PORT", help="serve raw VISCA on loopback TCP")
    parser.add_argument("--http", metavar="HOST:PORT", help="serve the HTTP interface (MJPEG, CGIs)")
    parser.add_argument("--user", help="HTTP Basic user (no auth when absent)")
    parser.add_argument("--password", default="", help="HTTP Basic password")
    parser.add_argument("--size", default="320x240", help="JPEG size WxH")
    parser.add_argument("--pan-nibbles", type=int, choices=(4, 5), default=4, help="position answer layout")


def _host_port(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit():
        raise SystemExit(f"expected HOST:PORT, got {text!r}")
    return host or "127.0.0.1", int(port)


def run_cli(args: argparse.Namespace, renderer: Renderer | None = None) -> int:
    """Serve until interrupted; prints the addresses (one line each) and flushes."""
    if not (args.visca_pty or args.visca_tcp or args.http):
        raise SystemExit("fake camera needs --visca-pty, --visca-tcp HOST:PORT and/or --http HOST:PORT")
    w, _, h = args.size.partition("x")
    spec = FakeCameraSpec(width_px=int(w), height_px=int(h), pan_nibbles=args.pan_nibbles)
    camera = FakeCamera(spec, renderer, username=args.user, password=args.password)
    servers: list[DeviceServer] = []
    http: CameraHttpServer | None = None
    try:  # Ctrl-C may come at any moment, even before everything is up
        if args.visca_pty:
            servers.append(serve_visca(camera, PtyEndpoint(args.link)))
            print(f"visca-pty {servers[-1].address}", flush=True)
        if args.visca_tcp:
            host, port = _host_port(args.visca_tcp)
            servers.append(serve_visca(camera, TcpEndpoint(host, port)))
            print(f"visca-tcp {servers[-1].address}", flush=True)
        if args.http:
            host, port = _host_port(args.http)
            http = CameraHttpServer(camera, host, port).start()
            print(f"http {http.url}", flush=True)
        while all(s.error is None for s in servers):
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        if http is not None:
            http.stop()
        for server in servers:
            server.stop()  # re-raises a model failure: a broken fake is never a silent one
    return 0
