"""The whole fake SNC-RZ50: state, VISCA sessions, the HTTP server with MJPEG and one-shot frames."""

from __future__ import annotations

import base64
import binascii
import threading
import time
import urllib.parse
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import cv2

from ..transport import DeviceServer, Endpoint
from .mechanics import CameraState, FakeCameraSpec
from .render import Renderer, TestPatternRenderer
from .visca import ViscaCameraModel

# ---------------------------------------------------------------------------------------------
# HTTP


@dataclass
class HttpFaults:
    stall_until: float = 0.0  # streams send nothing until then
    truncate_frames: int = 0  # next parts sent cut short
    truncate_mode: str = "short_length"  # or "lying_length": Content-Length of the full frame, bytes cut
    drop_generation: int = 0  # bumped by drop_connections(); streams of an older generation close
    stats: dict[str, int] = field(default_factory=lambda: {"truncated": 0, "dropped_connections": 0})


class FakeCamera:
    """The whole camera: state, VISCA model(s), renderer, HTTP settings."""

    def __init__(
        self,
        spec: FakeCameraSpec | None = None,
        renderer: Renderer | None = None,
        *,
        username: str | None = None,
        password: str | None = None,
        jpeg_quality: int = 80,
    ) -> None:
        self.spec = spec or FakeCameraSpec()
        self.state = CameraState(self.spec)
        self.renderer: Renderer = renderer or TestPatternRenderer(self.spec.width_px, self.spec.height_px)
        self.visca = ViscaCameraModel(self.state)
        self.visca_served = False
        # the pass-through CGI is its own VISCA "session" on the same mechanics
        self.passthrough = ViscaCameraModel(self.state)
        self._pt_out: list[bytes] = []
        self._pt_lock = threading.Lock()
        self.passthrough.attach(self._pt_emit)
        self.username = username
        self.password = password
        self.jpeg_quality = jpeg_quality
        self.http_faults = HttpFaults()
        self.requested_rates: list[float] = []
        self.frames_sent = 0
        #: the camera's current codec: in "mpeg4" mode /mjpeg answers 400 and /image is not MJPEG
        self.codec = "jpeg"
        self.lock = threading.Lock()

    def _pt_emit(self, data: bytes) -> None:
        self._pt_out.append(data)

    def passthrough_exchange(self, packet: bytes, wait_s: float = 0.05) -> bytes:
        """Feed a pass-through packet; return every reply byte produced since the last call."""
        with self._pt_lock:
            now = time.monotonic()
            self.passthrough.poll(now)
            if packet:
                self.passthrough.on_bytes(packet, now)
            if wait_s > 0 and packet:
                time.sleep(wait_s)
                self.passthrough.poll(time.monotonic())
            out, self._pt_out = b"".join(self._pt_out), []
            return out

    def encode_frame(self, now: float) -> bytes:
        pan, tilt, hfov = self.state.view(now)
        img = self.renderer.render(now, pan, tilt, hfov)
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        if not ok:
            raise RuntimeError("OpenCV could not encode the frame")
        return buf.tobytes()

    def stall_stream(self, seconds: float) -> None:
        self.http_faults.stall_until = time.monotonic() + seconds

    def truncate_frames(self, count: int, mode: str = "short_length") -> None:
        if mode not in ("short_length", "lying_length"):
            raise ValueError(mode)
        with self.lock:
            self.http_faults.truncate_frames += count
            self.http_faults.truncate_mode = mode

    def drop_connections(self) -> None:
        with self.lock:
            self.http_faults.drop_generation += 1
            self.http_faults.stats["dropped_connections"] += 1


class _Handler(BaseHTTPRequestHandler):
    server: CameraHttpServer
    protocol_version = "HTTP/1.0"

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - stdlib signature
        return

    @property
    def cam(self) -> FakeCamera:
        return self.server.camera

    def _authorised(self) -> bool:
        cam = self.cam
        if cam.username is None:
            return True
        expected = base64.b64encode(f"{cam.username}:{cam.password or ''}".encode()).decode()
        if self.headers.get("Authorization", "") == f"Basic {expected}":
            return True
        self.send_response(401)
        self.send_header("WWW-Authenticate", 'Basic realm="Sony Network Camera SNC-RZ50"')
        self.send_header("Content-Length", "0")
        self.end_headers()
        return False

    def _text(self, code: int, text: str, ctype: str = "text/plain") -> None:
        body = text.encode()
        self.send_response(code)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def do_POST(self) -> None:  # noqa: N802 - stdlib name
        length = int(self.headers.get("Content-Length") or 0)
        form = self.rfile.read(length).decode("latin-1") if length else ""
        self._dispatch(urllib.parse.urlsplit(self.path).path, urllib.parse.parse_qs(form))

    def do_GET(self) -> None:  # noqa: N802 - stdlib name
        url = urllib.parse.urlsplit(self.path)
        self._dispatch(url.path, urllib.parse.parse_qs(url.query))

    def _dispatch(self, path: str, query: dict[str, list[str]]) -> None:
        if not self._authorised():
            return
        try:
            if path in ("/image", "/mjpeg") and self.cam.codec == "mpeg4":
                if path == "/mjpeg":
                    self._text(400, "camera is in MPEG-4 mode")
                else:
                    self._text(200, "(an MPEG-4 stream would follow)", "video/mp4")
            elif path in ("/image", "/mjpeg"):
                self._stream(query)
            elif path in ("/oneshotimage.jpg", "/oneshotimage"):
                jpeg = self.cam.encode_frame(time.monotonic())
                self.send_response(200)
                self.send_header("Content-Type", "image/jpeg")
                self.send_header("Content-Length", str(len(jpeg)))
                self.end_headers()
                self.wfile.write(jpeg)
            elif path == "/command/inquiry.cgi":
                self._inquiry(query)
            elif path in ("/command/visca-ptzf.cgi", "/command/ptzf.cgi"):
                self._visca(query)
            else:
                self._text(404, "not found")
        except (BrokenPipeError, ConnectionResetError):
            return

    def _inquiry(self, query: dict[str, list[str]]) -> None:
        inq = (query.get("inq") or query.get("inqjs") or [""])[0]
        if inq == "system":
            self._text(200, "ModelName=SNC-RZ50N&Serial=00000001&SoftVersion=1.00&MacAddress=08-00-46-00-00-01")
        elif inq == "ptzf":
            p, t, z = self.cam.state.ptz(time.monotonic())
            self._text(200, f"AbsolutePTZF={round(p) & 0xFFFF:04x},{round(t) & 0xFFFF:04x},{round(z):04x},0000")
        else:
            self._text(400, "unknown inquiry")

    def _visca(self, query: dict[str, list[str]]) -> None:
        raw = (query.get("visca") or query.get("VISCA") or [""])[0].replace(" ", "")
        try:
            packet = binascii.unhexlify(raw) if raw else b""
        except (binascii.Error, ValueError):
            self._text(400, "visca must be hex")
            return
        reply = self.cam.passthrough_exchange(packet)
        self._text(200, reply.hex().upper())

    def _stream(self, query: dict[str, list[str]]) -> None:
        cam = self.cam
        try:
            speed = float((query.get("speed") or ["30"])[0])
        except ValueError:
            speed = 30.0
        if "interval" in query:
            try:
                speed = 1.0 / max(float(query["interval"][0]), 1e-3)
            except ValueError:
                pass
        speed = min(max(speed, 0.1), 30.0)
        number = int((query.get("number") or ["0"])[0] or 0)
        with cam.lock:
            cam.requested_rates.append(speed)
            generation = cam.http_faults.drop_generation
        self.send_response(200)
        self.send_header("Content-Type", "multipart/x-mixed-replace;boundary=--myboundary")
        self.send_header("Cache-Control", "no-cache")
        self.end_headers()
        period = 1.0 / speed
        next_t = time.monotonic()
        sent = 0
        while not self.server.stopping.is_set():
            now = time.monotonic()
            if now < next_t:
                time.sleep(min(next_t - now, 0.05))
                continue
            next_t = max(next_t + period, now - period)
            with cam.lock:
                if cam.http_faults.drop_generation != generation:
                    return
                stalled = now < cam.http_faults.stall_until
                truncate = cam.http_faults.truncate_frames > 0 and not stalled
                if truncate:
                    cam.http_faults.truncate_frames -= 1
                    cam.http_faults.stats["truncated"] += 1
                mode = cam.http_faults.truncate_mode
            if stalled:
                continue
            jpeg = cam.encode_frame(now)
            declared = len(jpeg)
            if truncate:
                jpeg = jpeg[: len(jpeg) // 2]
                if mode == "short_length":
                    declared = len(jpeg)
            head = (
                f"--myboundary\r\nContent-Type: image/jpeg\r\nContent-Length: {declared}\r\n"
                f"X-Send-Monotonic: {time.monotonic():.6f}\r\n\r\n"
            ).encode()
            self.wfile.write(head + jpeg + b"\r\n")
            self.wfile.flush()
            with cam.lock:
                cam.frames_sent += 1
            sent += 1
            if number and sent >= number:
                return


class CameraHttpServer(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, camera: FakeCamera, host: str = "127.0.0.1", port: int = 0) -> None:
        self.camera = camera
        self.stopping = threading.Event()
        super().__init__((host, port), _Handler)
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        return f"http://{host}:{port}"

    def start(self) -> CameraHttpServer:
        self._thread = threading.Thread(target=self.serve_forever, kwargs={"poll_interval": 0.05},
                                        name="fake-snc-rz50-http", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self.stopping.set()
        self.shutdown()
        self.server_close()
        if self._thread is not None:
            self._thread.join(timeout=2.0)


def serve_visca(camera: FakeCamera, endpoint: Endpoint) -> DeviceServer:
    """Run a VISCA port of the camera on an endpoint (pty or TCP); returns the started server.

    The first port serves ``camera.visca`` (where tests inject VISCA faults); each further port
    gets its own model (its own input buffer, sockets and replies) on the same mechanics.
    """
    model = camera.visca if not camera.visca_served else ViscaCameraModel(camera.state)
    camera.visca_served = True
    return DeviceServer(model, endpoint).start()
