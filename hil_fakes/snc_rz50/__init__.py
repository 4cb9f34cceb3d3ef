"""Byte-level fake Sony SNC-RZ50: VISCA on a pty or loopback TCP, JPEG/MJPEG and CGIs over HTTP.

An independent model written from the fact sheet (shared/protocols/visca_snc_rz50.md); it never
imports the driver, so a codec bug cannot hide behind a matching fake bug.

VISCA (:class:`ViscaCameraModel`, a :class:`hil_fakes.transport.DeviceModel`):
* packets framed by 0xFF, at most 16 bytes (longer: ``90 60 01 FF``); header 0x81, broadcast 0x88;
* AddressSet ``88 30 01 FF`` -> ``88 30 02 FF``; IF_Clear broadcast echoed, addressed -> ``90 50 FF``;
* two sockets: ACK ``90 4y FF`` at once, completion ``90 5y FF`` after the time the move takes at
  the commanded speed; a third command while both are busy -> ``90 60 03 FF``;
* illegal parameters (speed 0 or above the maximum, nibble byte > 0x0F, unknown command) ->
  ``90 60 02 FF`` with no ACK; out-of-range targets -> ACK then ``90 6y 41 FF``; cancel
  ``81 2y FF`` -> ``90 6y 04 FF`` or ``90 6y 05 FF``;
* inquiries answered at any time (4+4 nibble pan/tilt layout, or 5+4 with ``pan_nibbles=5``).

HTTP (:class:`CameraHttpServer`): ``/image?speed=N`` and ``/mjpeg?speed=N`` (multipart,
boundary ``--myboundary``, Content-Length per part), ``/oneshotimage.jpg``,
``/command/inquiry.cgi?inq=system|ptzf``, ``/command/visca-ptzf.cgi?visca=HEX`` (the reply bytes
the command produced within the request come back as hex text [?: what a real RZ50 returns is not
known]; a request without ``visca`` returns replies queued since, e.g. completions), HTTP Basic
auth. Frames come from a pluggable :class:`Renderer` at the requested rate, JPEG-encoded with OpenCV.

Faults: the transport's byte faults (``server.faults``), plus ``drop_replies``, ``garble_replies``,
``late_completions`` on the VISCA model and ``stall_stream``, ``truncate_frames``,
``drop_connections`` on the HTTP server."""

from __future__ import annotations

from .camera import CameraHttpServer, FakeCamera, HttpFaults, _Handler, serve_visca
from .cli import _host_port, add_cli_arguments, run_cli
from .mechanics import CameraState, FakeCameraSpec, _Axis
from .render import Renderer, TestPatternRenderer
from .visca import ViscaCameraModel, ViscaFaults, _nibs, _signed, _Syntax

__all__ = [
    "Renderer",
    "TestPatternRenderer",
    "FakeCameraSpec",
    "_Axis",
    "CameraState",
    "_signed",
    "_nibs",
    "_Syntax",
    "ViscaFaults",
    "ViscaCameraModel",
    "HttpFaults",
    "FakeCamera",
    "_Handler",
    "CameraHttpServer",
    "serve_visca",
    "add_cli_arguments",
    "_host_port",
    "run_cli",
]
