"""Camera frames over HTTP: the MJPEG stream reader thread and the one-shot JPEG.

Frames stay JPEG bytes here (drivers do not import OpenCV); the app decodes them. Each frame
carries its host stamp (``time.monotonic()`` when its last byte arrived), a sequence number that
only grows (across reconnects too), and the pan/tilt/zoom in force at capture as the VISCA
client knew it (``ptz`` callable, e.g. ``lambda: client.last_state``), with its age.

Truncated JPEGs are counted (``stats.truncated``) and never delivered. A lost or stalled stream
(no byte within ``HttpConfig.timeout_s``) reconnects with exponential backoff; permanent
failures (wrong credentials, a 4xx, a non-multipart answer) are surfaced through the buffer's
``set_error`` and raised by the next ``get``.
"""

from __future__ import annotations

import http.client
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from drivers.common import Backoff, LatestBuffer

from .config import HttpConfig
from .errors import AuthenticationError, HttpCameraError, MjpegFormatError, ViscaDisconnectedError, ViscaError
from .http import Endpoint, check_status, endpoint, get
from .mjpeg import JpegPart, MjpegParser, TruncatedJpeg, boundary_from_content_type, is_complete_jpeg

if TYPE_CHECKING:
    from .state import PtzState


@dataclass(frozen=True)
class CameraFrame:
    jpeg: bytes
    stamp_s: float  # host monotonic time of receipt
    seq: int
    ptz: PtzState | None  # pan/tilt/zoom in force at capture (None: unknown)
    ptz_age_s: float | None  # stamp_s - ptz.stamp_s
    headers: dict[str, str]


@dataclass
class FrameStats:
    frames: int = 0
    truncated: int = 0
    skipped_bytes: int = 0
    reconnects: int = 0
    connections: int = 0
    bytes_received: int = 0


PtzSource = Callable[[], "PtzState | None"]


def _ptz_at(ptz: PtzSource | None, stamp: float) -> tuple[PtzState | None, float | None]:
    if ptz is None:
        return None, None
    state = ptz()
    return state, (None if state is None else stamp - state.stamp_s)


class MjpegFrameSource:
    """Reads ``/image?speed=N`` (or ``/mjpeg``) in a thread into a :class:`LatestBuffer` of frames."""

    def __init__(self, config: HttpConfig, ptz: PtzSource | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.config = config
        self._ep: Endpoint = endpoint(config)
        self._ptz = ptz
        self._clock = clock
        self.buffer: LatestBuffer[CameraFrame] = LatestBuffer(config.buffer_frames)
        self.stats = FrameStats()
        self.last_error: BaseException | None = None
        self._seq = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._conn: http.client.HTTPConnection | None = None
        self._conn_lock = threading.Lock()
        self.connected = False

    def __enter__(self) -> MjpegFrameSource:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def stream_path(self) -> str:
        return self._ep.path(self.config.stream_path, {"speed": str(self.config.frame_rate)})

    def start(self) -> MjpegFrameSource:
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="mjpeg-reader", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        with self._conn_lock:
            conn = self._conn
        if conn is not None:
            try:
                if conn.sock is not None:
                    conn.sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        if self._thread is not None:
            self._thread.join(timeout=self.config.timeout_s + 2.0)
        self._thread = None

    def get(self, timeout_s: float) -> CameraFrame:
        return self.buffer.get(timeout_s)

    def latest(self) -> CameraFrame | None:
        return self.buffer.latest()

    def _run(self) -> None:
        backoff = Backoff(self.config.reconnect_initial_s, self.config.reconnect_max_s)
        while not self._stop.is_set():
            try:
                self._stream_once(backoff)
            except (AuthenticationError, MjpegFormatError) as exc:
                self.last_error = exc
                self.buffer.set_error(exc)
                return
            except HttpCameraError as exc:
                self.last_error = exc
                if exc.status is not None and 400 <= exc.status < 500:
                    self.buffer.set_error(exc)  # /mjpeg answers 400 in MPEG-4 mode: not transient
                    return
            except (OSError, http.client.HTTPException, ViscaError) as exc:
                self.last_error = exc
            except BaseException as exc:  # noqa: BLE001 - surfaced to the consumer, never lost
                self.last_error = exc
                self.buffer.set_error(exc)
                return
            finally:
                self.connected = False
            if self._stop.is_set():
                return
            self.stats.reconnects += 1
            self._stop.wait(backoff.next_delay())

    def _stream_once(self, backoff: Backoff) -> None:
        conn = self._ep.connection(self.config.timeout_s)
        with self._conn_lock:
            self._conn = conn
        try:
            conn.request("GET", self.stream_path, headers=self._ep.headers())
            resp = conn.getresponse()
            check_status(resp.status, f"GET {self.config.stream_path}")
            parser = MjpegParser(boundary_from_content_type(resp.getheader("Content-Type") or ""),
                                 self.config.max_frame_bytes)
            self.connected = True
            self.stats.connections += 1
            while not self._stop.is_set():
                chunk = resp.read1(65536)
                if not chunk:
                    raise ViscaDisconnectedError("MJPEG stream ended")
                self.stats.bytes_received += len(chunk)
                for ev in parser.feed(chunk):
                    if isinstance(ev, JpegPart):
                        stamp = self._clock()
                        ptz, age = _ptz_at(self._ptz, stamp)
                        self._seq += 1
                        self.stats.frames += 1
                        backoff.reset()
                        self.buffer.put(CameraFrame(ev.jpeg, stamp, self._seq, ptz, age, ev.headers))
                    elif isinstance(ev, TruncatedJpeg):
                        self.stats.truncated += 1
                    else:
                        self.stats.skipped_bytes += ev.size
        finally:
            with self._conn_lock:
                self._conn = None
            conn.close()


def fetch_oneshot(config: HttpConfig, ptz: PtzSource | None = None, seq: int = 0) -> CameraFrame:
    """One JPEG from ``/oneshotimage.jpg``; raises :class:`MjpegFormatError` for a truncated JPEG."""
    status, body, _ = get(endpoint(config), config.oneshot_path, config.timeout_s)
    check_status(status, f"GET {config.oneshot_path}")
    stamp = time.monotonic()
    if not is_complete_jpeg(body):
        raise MjpegFormatError(f"one-shot image is not a complete JPEG ({len(body)} bytes)", raw=body[:16])
    state, age = _ptz_at(ptz, stamp)
    return CameraFrame(body, stamp, seq, state, age, {})


def inquiry_system(config: HttpConfig) -> dict[str, str]:
    """``/command/inquiry.cgi?inq=system`` as a dict (``ModelName=SNC-RZ50N`` ...)."""
    status, body, _ = get(endpoint(config), "/command/inquiry.cgi", config.timeout_s, {"inq": "system"})
    check_status(status, "inquiry.cgi?inq=system")
    out: dict[str, str] = {}
    for item in body.decode("latin-1").replace("\r\n", "&").replace("\n", "&").split("&"):
        key, sep, value = item.partition("=")
        if sep and key.strip():
            out[key.strip()] = value.strip().strip('"')
    return out
