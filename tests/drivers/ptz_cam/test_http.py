"""Frames over HTTP from the fake SNC-RZ50 (MJPEG, one-shot, CGIs, Basic auth) and VISCA pass-through.

Rates are checked loosely: the fake must have been asked for >= 10 fps and frames must keep coming
with growing sequence numbers and the right PTZ state; no assertion depends on timing.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import dataclass

import cv2
import numpy as np
import pytest

from drivers.errors import DriverTimeoutError
from drivers.ptz_cam import HttpConfig, MjpegFrameSource, ViscaClient, ViscaConfig
from drivers.ptz_cam import visca as v
from drivers.ptz_cam.errors import AuthenticationError, HttpCameraError, MjpegFormatError, NotExecutableError
from drivers.ptz_cam.frames import CameraFrame, fetch_oneshot, inquiry_system
from drivers.ptz_cam.mjpeg import is_complete_jpeg
from hil_fakes.snc_rz50 import CameraHttpServer, FakeCamera, FakeCameraSpec, serve_visca
from hil_fakes.transport import DeviceServer, TcpEndpoint

USER, PASSWORD = "admin", "s3cret"


@dataclass
class HttpRig:
    camera: FakeCamera
    http: CameraHttpServer
    visca: DeviceServer

    def config(self, **kw: object) -> HttpConfig:
        base = dict(base_url=self.http.url, username=USER, password=PASSWORD, frame_rate=15, timeout_s=3.0,
                    buffer_frames=64, reconnect_initial_s=0.05, reconnect_max_s=0.5)
        base.update(kw)
        return HttpConfig(**base)  # type: ignore[arg-type]


@pytest.fixture
def http_rig() -> Iterator[HttpRig]:
    camera = FakeCamera(FakeCameraSpec(width_px=320, height_px=240), username=USER, password=PASSWORD)
    http = CameraHttpServer(camera).start()
    visca = serve_visca(camera, TcpEndpoint())
    try:
        yield HttpRig(camera, http, visca)
    finally:
        http.stop()
        visca.stop()


def collect(source: MjpegFrameSource, n: int, timeout_s: float = 20.0) -> list[CameraFrame]:
    deadline = time.monotonic() + timeout_s
    frames: list[CameraFrame] = []
    while len(frames) < n:
        frames.append(source.get(max(0.1, deadline - time.monotonic())))
    return frames


def decode(jpeg: bytes) -> np.ndarray:
    img = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
    assert img is not None
    return img


def test_mjpeg_frames_carry_sequence_and_ptz_state(http_rig: HttpRig) -> None:
    with ViscaClient(http_rig.visca.address, ViscaConfig(ack_timeout_s=2.0, inquiry_timeout_s=2.0)) as client:
        client.move_to(math.radians(30), math.radians(-5))
        with MjpegFrameSource(http_rig.config(frame_rate=15), ptz=lambda: client.last_state) as source:
            frames = collect(source, 12)
            assert max(http_rig.camera.requested_rates) >= 10
            seqs = [f.seq for f in frames]
            assert seqs == sorted(set(seqs))
            for f in frames:
                assert f.ptz is not None and not f.ptz.moving
                assert f.ptz.pan_deg == pytest.approx(30) and f.ptz.tilt_deg == pytest.approx(-5)
                assert decode(f.jpeg).shape == (240, 320, 3)
            # move while streaming: frames after the completion carry the new pan, during it "moving"
            h = client.move_to(math.radians(-10), 0, speed=0.05, wait=False)  # 40 deg at 25 deg/s
            source.buffer.clear()  # frames from before the ACK
            during = source.get(10.0)
            h.wait()
            source.buffer.clear()
            after = collect(source, 5)
            assert during.ptz is not None and during.ptz.moving
            for f in after:
                assert f.ptz is not None and f.ptz.pan_deg == pytest.approx(-10) and not f.ptz.moving
                assert f.seq > frames[-1].seq and f.stamp_s > h.completed_s  # type: ignore[operator]
    assert source.stats.truncated == 0


@pytest.mark.parametrize("mode", ["short_length", "lying_length"])
def test_truncated_jpegs_are_counted_and_never_delivered(http_rig: HttpRig, mode: str) -> None:
    with MjpegFrameSource(http_rig.config(frame_rate=30)) as source:
        collect(source, 2)
        http_rig.camera.truncate_frames(3, mode)
        deadline = time.monotonic() + 20
        delivered: list[CameraFrame] = []
        while source.stats.truncated < 3 and time.monotonic() < deadline:
            delivered.append(source.get(10.0))
        delivered += collect(source, 3)
    assert source.stats.truncated == 3
    assert all(is_complete_jpeg(f.jpeg) for f in delivered)
    assert all(decode(f.jpeg).shape == (240, 320, 3) for f in delivered)


def test_stalled_stream_reconnects(http_rig: HttpRig) -> None:
    with MjpegFrameSource(http_rig.config(timeout_s=0.5, frame_rate=20)) as source:
        first = collect(source, 2)
        http_rig.camera.stall_stream(1.5)
        deadline = time.monotonic() + 20
        while source.stats.reconnects < 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert source.stats.reconnects >= 1 and isinstance(source.last_error, TimeoutError)
        source.buffer.clear()
        later = collect(source, 3)
    assert later[0].seq > first[-1].seq


def test_dropped_connection_reconnects(http_rig: HttpRig) -> None:
    with MjpegFrameSource(http_rig.config(stream_path="/mjpeg")) as source:
        first = collect(source, 2)
        http_rig.camera.drop_connections()
        deadline = time.monotonic() + 20
        while source.stats.connections < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert source.stats.connections >= 2
        source.buffer.clear()
        assert collect(source, 2)[0].seq > first[-1].seq


def test_wrong_credentials_are_a_typed_error(http_rig: HttpRig) -> None:
    with MjpegFrameSource(http_rig.config(password="wrong")) as source:
        with pytest.raises(AuthenticationError):
            source.get(10.0)
    with pytest.raises(AuthenticationError):
        fetch_oneshot(http_rig.config(username=None, password=None))


@pytest.mark.parametrize(("path", "error"), [("/mjpeg", HttpCameraError), ("/image", MjpegFormatError)])
def test_mpeg4_mode_is_a_permanent_typed_error(http_rig: HttpRig, path: str, error: type) -> None:
    http_rig.camera.codec = "mpeg4"
    with MjpegFrameSource(http_rig.config(stream_path=path)) as source:
        with pytest.raises(error):
            source.get(10.0)
        assert source.stats.reconnects == 0


def test_oneshot_and_inquiry_with_credentials_in_the_url(http_rig: HttpRig) -> None:
    host = http_rig.http.url.removeprefix("http://")
    cfg = HttpConfig(base_url=f"http://{USER}:{PASSWORD}@{host}")
    frame = fetch_oneshot(cfg)
    assert decode(frame.jpeg).shape == (240, 320, 3)
    assert inquiry_system(cfg)["ModelName"] == "SNC-RZ50N"


def test_server_down_surfaces_as_timeout_and_keeps_retrying() -> None:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with MjpegFrameSource(HttpConfig(base_url=f"http://127.0.0.1:{port}", timeout_s=0.5,
                                     reconnect_initial_s=0.02, reconnect_max_s=0.05)) as source:
        with pytest.raises(DriverTimeoutError):
            source.get(0.5)
        deadline = time.monotonic() + 10
        while source.stats.reconnects < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        assert source.stats.reconnects >= 2 and isinstance(source.last_error, ConnectionError)


def test_visca_over_the_http_passthrough(http_rig: HttpRig) -> None:
    host = http_rig.http.url.removeprefix("http://")
    cfg = ViscaConfig(ack_timeout_s=3.0, inquiry_timeout_s=3.0)
    with ViscaClient(f"http://{USER}:{PASSWORD}@{host}", cfg) as client:
        assert client.camera_count == 1 and client.version is not None
        client.move_to(math.radians(12), math.radians(3))  # completion arrives through the idle poll
        s = client.position()
        assert (s.pan_deg, s.tilt_deg) == (pytest.approx(12, abs=0.07), pytest.approx(3, abs=0.07))  # 1 count
        with pytest.raises(NotExecutableError):
            client.command(v.pan_tilt_absolute(0x7000, 0))
        assert client.zoom_position() == 0
