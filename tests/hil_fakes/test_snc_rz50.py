"""The fake SNC-RZ50 alone, driven with raw bytes (no driver code): the fact sheet's behaviour."""

from __future__ import annotations

import math
import socket
import time
import urllib.request
from collections.abc import Iterator

import numpy as np
import pytest

from hil_fakes.snc_rz50 import CameraHttpServer, FakeCamera, FakeCameraSpec, TestPatternRenderer, serve_visca
from hil_fakes.transport import DeviceServer, TcpEndpoint

H = bytes.fromhex


class Raw:
    def __init__(self, address: str) -> None:
        host, port = address.removeprefix("socket://").rsplit(":", 1)
        self.sock = socket.create_connection((host, int(port)), timeout=5.0)
        self.buf = b""

    def send(self, hexs: str) -> None:
        self.sock.sendall(H(hexs))

    def reply(self, timeout_s: float = 5.0) -> str:
        """The next packet (up to 0xFF) as spaced upper-case hex."""
        deadline = time.monotonic() + timeout_s
        while b"\xff" not in self.buf:
            self.sock.settimeout(max(0.01, deadline - time.monotonic()))
            chunk = self.sock.recv(256)
            if not chunk:
                raise ConnectionError("closed")
            self.buf += chunk
        i = self.buf.index(b"\xff") + 1
        packet, self.buf = self.buf[:i], self.buf[i:]
        return packet.hex(" ").upper()

    def ask(self, hexs: str) -> str:
        self.send(hexs)
        return self.reply()


@pytest.fixture
def cam() -> Iterator[tuple[FakeCamera, DeviceServer, Raw]]:
    camera = FakeCamera(FakeCameraSpec(zoom_full_travel_s=0.5))
    server = serve_visca(camera, TcpEndpoint())
    raw = Raw(server.address)
    try:
        yield camera, server, raw
    finally:
        raw.sock.close()
        server.stop()


def test_start_up_replies(cam) -> None:  # type: ignore[no-untyped-def]
    _, _, r = cam
    assert r.ask("88 30 01 FF") == "88 30 02 FF"
    assert r.ask("88 01 00 01 FF") == "88 01 00 01 FF"
    assert r.ask("81 01 00 01 FF") == "90 50 FF"
    assert r.ask("81 09 00 02 FF") == "90 50 00 20 05 10 01 00 02 FF"


def test_position_examples_and_inquiries(cam) -> None:  # type: ignore[no-untyped-def]
    _, _, r = cam
    # the fact sheet's examples: 1296 = 0x0510 (+90 deg at 14.4 counts/deg), -432 = 0xFE50 (-30 deg)
    assert r.ask("81 01 06 02 18 14 00 05 01 00 0F 0E 05 00 FF") == "90 41 FF"
    assert r.reply() == "90 51 FF"
    assert r.ask("81 09 06 12 FF") == "90 50 00 05 01 00 0F 0E 05 00 FF"
    assert r.ask("81 09 06 11 FF") == "90 50 18 14 FF"
    assert r.ask("81 09 04 47 FF") == "90 50 00 00 00 00 FF"
    assert r.ask("81 09 04 38 FF") == "90 50 02 FF"
    assert r.ask("81 09 04 00 FF") == "90 50 02 FF"
    assert r.ask("81 09 04 06 FF") == "90 50 03 FF"


def test_illegal_parameters_are_syntax_errors_without_ack(cam) -> None:  # type: ignore[no-untyped-def]
    _, _, r = cam
    assert r.ask("81 01 06 01 00 00 03 03 FF") == "90 60 02 FF"  # speed 0 even for a stop
    assert r.ask("81 01 06 01 13 00 02 03 FF") == "90 60 02 FF"  # obs-ptz#40's trace
    assert r.ask("81 01 06 01 19 01 02 03 FF") == "90 60 02 FF"  # pan speed above 0x18
    assert r.ask("81 01 06 02 18 14 00 15 01 00 00 00 00 00 FF") == "90 60 02 FF"  # nibble byte 0x15
    assert r.ask("81 01 7E FF") == "90 60 02 FF"
    assert r.ask("81 01 06 01 01 01 03 03 FF") == "90 41 FF"  # legal stop
    assert r.reply() == "90 51 FF"
    r.send("81" + " 01" * 20 + " FF")
    assert r.reply() == "90 60 01 FF"  # message length


def test_out_of_range_is_not_executable_after_the_ack(cam) -> None:  # type: ignore[no-untyped-def]
    _, _, r = cam
    assert r.ask("81 01 06 02 18 14 00 0A 00 00 00 00 00 00 FF") == "90 41 FF"  # pan 0x0A00 > 2448
    assert r.reply() == "90 61 41 FF"
    assert r.ask("81 01 04 47 05 00 00 00 FF") == "90 41 FF"  # digital range with digital zoom off
    assert r.reply() == "90 61 41 FF"


def test_two_sockets_buffer_full_and_cancel(cam) -> None:  # type: ignore[no-untyped-def]
    camera, _, r = cam
    assert r.ask("81 01 06 02 01 01 00 09 00 00 00 00 00 00 FF") == "90 41 FF"  # slow, long move
    assert r.ask("81 01 04 47 04 00 00 00 FF") == "90 42 FF"  # zoom in parallel
    assert r.ask("81 01 04 38 03 FF") == "90 60 03 FF"  # both busy
    assert r.ask("81 09 04 38 FF") == "90 50 02 FF"  # inquiries still answered
    assert r.ask("81 21 FF") == "90 61 04 FF"
    assert r.reply() == "90 52 FF"  # the zoom completes on its own
    assert r.ask("81 21 FF") == "90 61 05 FF"
    pan = camera.state.ptz(time.monotonic())[0]
    assert 0 < pan < 2304


def test_completion_comes_after_the_move_time(cam) -> None:  # type: ignore[no-untyped-def]
    camera, _, r = cam
    # 144 counts (10 deg) at speed 0x18 (300 deg/s): about 33 ms, and the fake says when
    r.send("81 01 06 02 18 14 00 00 09 00 00 00 00 00 FF")
    assert r.reply() == "90 41 FF"
    assert camera.state.ptz(time.monotonic())[0] <= 144
    assert r.reply() == "90 51 FF"
    assert camera.state.ptz(time.monotonic())[0] == 144


def test_faults_drop_garble_late(cam) -> None:  # type: ignore[no-untyped-def]
    camera, _, r = cam
    camera.visca.faults.drop_replies = 1
    r.send("81 09 04 00 FF")
    assert r.ask("81 09 04 38 FF") == "90 50 02 FF"  # the first answer never came
    camera.visca.faults.garble_replies = 1
    assert r.ask("81 09 04 00 FF") == "90 7E 02 FF"
    camera.visca.faults.late_completions = 1
    camera.visca.faults.late_extra_s = 0.3
    assert r.ask("81 01 04 38 03 FF") == "90 41 FF"
    assert r.reply() == "90 51 FF"
    assert camera.visca.faults.stats == {"dropped": 1, "garbled": 1, "late": 1}


def test_renderer_contract_and_view() -> None:
    rnd = TestPatternRenderer(320, 240)
    a = rnd.render(0.0, 0.0, 0.0, math.radians(54))
    b = rnd.render(0.0, math.radians(20), 0.0, math.radians(54))
    assert a.shape == (240, 320, 3) and a.dtype == np.uint8
    assert not np.array_equal(a, b)  # panning changes the view
    spec = FakeCameraSpec()
    assert math.degrees(spec.hfov_rad(0)) == pytest.approx(54)
    assert spec.hfov_rad(0x4000) < spec.hfov_rad(0x2000) < spec.hfov_rad(0)


def test_http_endpoints_and_basic_auth() -> None:
    camera = FakeCamera(username="u", password="p")
    http = CameraHttpServer(camera).start()
    try:
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(http.url + "/oneshotimage.jpg", timeout=5)
        assert err.value.code == 401 and "Basic" in err.value.headers["WWW-Authenticate"]
        mgr = urllib.request.HTTPPasswordMgrWithDefaultRealm()
        mgr.add_password(None, http.url, "u", "p")
        opener = urllib.request.build_opener(urllib.request.HTTPBasicAuthHandler(mgr))
        jpeg = opener.open(http.url + "/oneshotimage.jpg", timeout=5).read()
        assert jpeg[:2] == b"\xff\xd8" and jpeg[-2:] == b"\xff\xd9"
        assert b"ModelName=SNC-RZ50N" in opener.open(http.url + "/command/inquiry.cgi?inq=system", timeout=5).read()
        reply = opener.open(http.url + "/command/visca-ptzf.cgi?visca=81090612FF", timeout=5).read()
        assert reply == b"90500000000000000000FF"  # pan-tilt position (0, 0) as hex text
        with opener.open(http.url + "/image?speed=10&number=2", timeout=5) as resp:
            assert resp.headers["Content-Type"] == "multipart/x-mixed-replace;boundary=--myboundary"
            body = resp.read()
        assert body.count(b"--myboundary\r\n") == 2 and body.count(b"\xff\xd9\r\n") == 2
        assert camera.requested_rates == [10.0]
    finally:
        http.stop()
