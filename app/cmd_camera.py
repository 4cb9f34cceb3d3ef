"""`vipsm-robot` commands for the Sony SNC-RZ50: probe, ptz, fake camera, bench.

* ``vipsm-robot probe --camera URL [--camera-http URL] --json``: version, pan/tilt/zoom and one frame
* ``vipsm-robot ptz --camera URL --pan-deg 30 --tilt-deg -5 --zoom 0 --json``: move, read back
* ``vipsm-robot fake camera --visca-pty [--link PATH] | --visca-tcp 127.0.0.1:PORT  --http 127.0.0.1:PORT``
* ``vipsm-robot bench --only camera``: receive + decode one 320x240 MJPEG frame from the fake

Frames are decoded here with OpenCV (drivers do not import it): :func:`to_vipsm_frame` turns a
driver :class:`CameraFrame` into the estimator's :class:`vipsm.types.Frame` with intrinsics.
"""

from __future__ import annotations

import argparse
import math
import signal
import statistics
import subprocess
import sys
import time
from typing import Any

import cv2
import numpy as np

from drivers.ptz_cam import CameraFrame, HttpConfig, MjpegFrameSource, PtzCalibration, ViscaClient, ViscaConfig
from drivers.ptz_cam.errors import MjpegFormatError, ViscaError
from drivers.ptz_cam.frames import fetch_oneshot, inquiry_system
from vipsm.types import Frame, Intrinsics

from .cli import emit
from .errors import AppError


def decode_jpeg(jpeg: bytes, *, grey: bool = False) -> np.ndarray:
    """The one JPEG decoder of the app (BGR, or grey for the estimator: the daemon and replay use
    ``grey=True`` so both feed the estimator identical images)."""
    img = cv2.imdecode(np.frombuffer(jpeg, dtype=np.uint8), cv2.IMREAD_GRAYSCALE if grey else cv2.IMREAD_COLOR)
    if img is None:
        raise MjpegFormatError(f"OpenCV could not decode a {len(jpeg)}-byte JPEG", raw=jpeg[:16])
    return img


def to_vipsm_frame(
    frame: CameraFrame,
    calibration: PtzCalibration | None = None,
    *,
    fallback_ptz: tuple[float, float, int] = (0.0, 0.0, 0),
    grey: bool = False,
    distortion: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
) -> Frame:
    """Decode a driver frame and attach intrinsics for its size and the zoom in force at capture.

    ``fallback_ptz`` (pan_rad, tilt_rad, zoom position) is used when the frame carries no PTZ
    state (no VISCA link: the camera stays where the config put it). ``distortion``: (k1, k2, p1, p2)
    of the lens (config ``devices.camera_k1`` ...), 0 = pinhole."""
    cal = calibration or PtzCalibration()
    img = decode_jpeg(frame.jpeg, grey=grey)
    h, w = img.shape[:2]
    if frame.ptz is not None:
        pan, tilt, zoom = frame.ptz.pan_rad, frame.ptz.tilt_rad, frame.ptz.zoom_position
    else:
        pan, tilt, zoom = fallback_ptz
    k = cal.intrinsics(zoom, w, h)
    return Frame(
        image=img,
        stamp_s=frame.stamp_s,
        intrinsics=Intrinsics(k.fx_px, k.fy_px, k.cx_px, k.cy_px, w, h, *distortion),
        pan_rad=pan,
        tilt_rad=tilt,
        seq=frame.seq,
    )


def _visca_config(args: argparse.Namespace) -> ViscaConfig:
    t = float(getattr(args, "timeout_s", 5.0) or 5.0)
    return ViscaConfig(
        baudrate=int(getattr(args, "baud", 9600) or 9600), ack_timeout_s=min(t, 2.0), inquiry_timeout_s=min(t, 2.0)
    )


def _state_dict(client: ViscaClient) -> dict[str, Any]:
    s = client.position()
    return {
        "pan_deg": round(s.pan_deg, 3),
        "tilt_deg": round(s.tilt_deg, 3),
        "pan_counts": s.pan_counts,
        "tilt_counts": s.tilt_counts,
        "zoom_position": s.zoom_position,
        "magnification": round(client.calibration.magnification(s.zoom_position), 3),
        "hfov_deg": round(math.degrees(s.hfov_rad), 3),
    }


def probe(args: argparse.Namespace) -> dict[str, Any]:
    from .config import redact_text

    out: dict[str, Any] = {"url": redact_text(args.camera)}  # an http:// VISCA URL may carry the password
    with ViscaClient(args.camera, _visca_config(args)) as client:
        ver = client.version
        out["camera_count"] = client.camera_count
        out["version"] = (
            None
            if ver is None
            else {
                "vendor": f"0x{ver.vendor:04X}",
                "model": f"0x{ver.model:04X}",
                "rom": f"0x{ver.rom_version:04X}",
                "sockets": ver.sockets,
            }
        )
        out["max_speed"] = {"pan": client.pan_max_speed, "tilt": client.tilt_max_speed}
        out["power"] = client.power().name.lower()
        out["focus"] = client.focus_mode().name.lower()
        out.update(_state_dict(client))
        if client.stats.startup_warnings:
            out["warnings"] = list(client.stats.startup_warnings)
    http_url = getattr(args, "camera_http", None)
    if http_url:
        cfg = HttpConfig(base_url=http_url, timeout_s=float(args.timeout_s or 5.0))
        try:
            out["model"] = inquiry_system(cfg).get("ModelName")
        except ViscaError as exc:
            out["model"] = None
            out.setdefault("warnings", []).append(f"inquiry.cgi: {exc}")
        frame = fetch_oneshot(cfg)
        img = decode_jpeg(frame.jpeg)
        out["frame"] = {
            "width_px": int(img.shape[1]),
            "height_px": int(img.shape[0]),
            "stamp_s": round(frame.stamp_s, 6),
            "jpeg_bytes": len(frame.jpeg),
        }
    return out


def _cmd_ptz(args: argparse.Namespace) -> int:
    cal = PtzCalibration()
    with ViscaClient(args.camera, _visca_config(args)) as client:
        now = client.position()
        pan = math.radians(args.pan_deg) if args.pan_deg is not None else now.pan_rad
        tilt = math.radians(args.tilt_deg) if args.tilt_deg is not None else now.tilt_rad
        zoom = args.zoom
        if args.zoom_x is not None:
            zoom = cal.zoom_position_for(args.zoom_x)
        t0 = time.monotonic()
        handle = client.move_to(pan, tilt, args.speed, wait=False)  # socket 1
        zhandle = client.zoom_to(zoom, wait=False) if zoom is not None else None  # socket 2, in parallel
        handle.wait()
        if zhandle is not None:
            zhandle.wait()
        result = _state_dict(client)
        result["move_s"] = round(time.monotonic() - t0, 3)
    emit({"camera": result}, args.json)
    return 0


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("ptz", help="move the SNC-RZ50 (degrees, zoom position) and print the position read back")
    p.add_argument(
        "--camera",
        metavar="URL",
        required=True,
        help="VISCA port: a tty, a pty, socket://host:port, "
        "or http://[user:pw@]camera for the visca-ptzf.cgi pass-through",
    )
    p.add_argument("--pan-deg", type=float, help="pan, degrees, left positive (default: keep)")
    p.add_argument("--tilt-deg", type=float, help="tilt, degrees, up positive (default: keep)")
    p.add_argument("--zoom", type=int, help="zoom position 0 (wide) .. 16384 (optical tele)")
    p.add_argument("--zoom-x", type=float, help="zoom as magnification 1..26 (instead of --zoom)")
    p.add_argument("--speed", type=float, default=1.0, help="fraction of max pan/tilt speed, (0, 1]")
    p.add_argument("--baud", type=int, default=9600, choices=(9600, 38400))
    p.add_argument("--timeout-s", type=float, default=5.0, help="ACK/inquiry timeout cap")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_ptz)


def register_fake(fake_sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    from hil_fakes import snc_rz50

    p = fake_sub.add_parser("camera", help="fake Sony SNC-RZ50: VISCA on a pty or TCP, HTTP MJPEG/CGIs")
    snc_rz50.add_cli_arguments(p)
    p.set_defaults(func=lambda a: snc_rz50.run_cli(a))


def _percentile(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, max(0, math.ceil(q * len(s)) - 1))]


_FAKE_MAIN = (
    "import argparse, sys\n"
    "from hil_fakes import snc_rz50\n"
    "p = argparse.ArgumentParser()\n"
    "snc_rz50.add_cli_arguments(p)\n"
    "sys.exit(snc_rz50.run_cli(p.parse_args(sys.argv[1:])))\n"
)


def _start_fake_http_process() -> tuple[subprocess.Popen[str], str]:
    """The fake camera's HTTP side in its own process, as a real camera is its own device."""
    proc = subprocess.Popen(
        [sys.executable, "-c", _FAKE_MAIN, "--http", "127.0.0.1:0", "--size", "320x240"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline().strip()
    if not line.startswith("http "):
        proc.kill()
        raise AppError(f"fake camera did not start: {line!r} {proc.stderr.read() if proc.stderr else ''}")
    return proc, line.split(" ", 1)[1]


def bench(args: argparse.Namespace) -> dict[str, Any]:
    """Receive + decode 320x240 MJPEG frames from the fake (own process); median / p99 in ms.

    receive = host stamp of the complete part minus the fake's send stamp (``X-Send-Monotonic``,
    CLOCK_MONOTONIC is shared by processes on Linux); decode = ``cv2.imdecode``.
    """
    n = 120
    proc, url = _start_fake_http_process()
    recv_ms: list[float] = []
    decode_ms: list[float] = []
    total_ms: list[float] = []
    try:
        with MjpegFrameSource(HttpConfig(base_url=url, frame_rate=30, buffer_frames=n + 8)) as source:
            frames = [source.get(10.0) for _ in range(n)]
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    for f in frames[5:]:  # skip connection warm-up
        sent = float(f.headers.get("x-send-monotonic", "nan"))
        t0 = time.perf_counter()
        img = decode_jpeg(f.jpeg)
        dt = (time.perf_counter() - t0) * 1e3
        if img.shape[:2] != (240, 320):
            raise AppError(f"bench frame has size {img.shape}")
        recv = (f.stamp_s - sent) * 1e3
        recv_ms.append(recv)
        decode_ms.append(dt)
        total_ms.append(recv + dt)
    return {
        "frames": len(total_ms),
        "receive_ms_median": round(statistics.median(recv_ms), 3),
        "receive_ms_p99": round(_percentile(recv_ms, 0.99), 3),
        "decode_ms_median": round(statistics.median(decode_ms), 3),
        "decode_ms_p99": round(_percentile(decode_ms, 0.99), 3),
        "receive_decode_ms_median": round(statistics.median(total_ms), 3),
        "receive_decode_ms_p99": round(_percentile(total_ms, 0.99), 3),
        "target_ms": 3.0,
    }
