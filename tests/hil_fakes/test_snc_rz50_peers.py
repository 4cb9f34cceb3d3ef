"""Third-party VISCA clients against the fake camera over a real pty.

libvisca's ``visca_cli`` (the client the issue names) is not packaged in Debian (``apt-cache
search visca`` finds nothing), so that check is skipped unless the binary is on PATH.
``pyvisca`` (PyPI, a serial VISCA client) is used when installed; it is not a project dependency,
so these tests skip without it. The fake must serve both as a real camera would, including
rejecting what a real camera rejects: pyvisca sends its pan speed as the tilt speed too, and 0x15
as the idle axis's tilt speed, both above the 0x14 tilt maximum.
"""

from __future__ import annotations

import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from hil_fakes.snc_rz50 import FakeCamera, FakeCameraSpec, serve_visca
from hil_fakes.transport import DeviceServer, PtyEndpoint

H = bytes.fromhex


@pytest.fixture
def pty_camera(tmp_path: Path) -> Iterator[tuple[FakeCamera, DeviceServer]]:
    camera = FakeCamera(FakeCameraSpec(zoom_full_travel_s=0.3))
    server = serve_visca(camera, PtyEndpoint(str(tmp_path / "ptzcam")))
    try:
        yield camera, server
    finally:
        server.stop()


def _settle(camera: FakeCamera, command_prefix: str, timeout_s: float = 10.0) -> None:
    """Wait until the fake took the command and nothing runs (pyvisca waits for no reply itself)."""
    deadline = time.monotonic() + timeout_s
    prefix = H(command_prefix)
    while time.monotonic() < deadline and not camera.visca.commands_seen[-1].startswith(prefix):
        time.sleep(0.02)
    while time.monotonic() < deadline and (camera.visca._sockets or camera.visca._scheduled):
        time.sleep(0.02)
    time.sleep(0.1)  # let the completion bytes reach the pty before pyvisca flushes its input


def test_pyvisca_drives_the_fake_over_the_pty(pty_camera: tuple[FakeCamera, DeviceServer]) -> None:
    visca = pytest.importorskip("pyvisca.visca", reason="pyvisca (PyPI) is not installed")
    camera, server = pty_camera
    ptz = visca.PTZ(server.address)
    try:
        assert ptz.get_power() == 1
        ptz.set_zoom(0x2000)
        _settle(camera, "81 01 04 47")
        assert ptz.get_zoom() == 0x2000
        # pyvisca sends one speed for both axes: 0x18 is a legal pan speed but not a tilt speed
        ptz.set_pan(1296, speed=0x18)
        _settle(camera, "81 01 06 02 18 18")
        assert ptz.get_pan() == 0
        ptz.set_pan(1296, speed=0x14)  # +90 deg (VISCA right): the fact sheet's example
        _settle(camera, "81 01 06 02 14 14")
        assert ptz.get_pan() == 1296
        assert round(camera.state.ptz(time.monotonic())[0]) == 1296
        ptz.home()
        _settle(camera, "81 01 06 04")
        assert ptz.get_pan() == 0
        # pyvisca's left() sends tilt speed "15" as hex 0x15 on the idle axis: a real camera's
        # maximum is 0x14, so the fake rejects it as a syntax error and does not move
        ptz.left(5)
        _settle(camera, "81 01 06 01 05 15 01 03")
        assert H("81 01 06 01 05 15 01 03 FF") in camera.visca.commands_seen
        assert round(camera.state.ptz(time.monotonic())[0]) == 0
    finally:
        ptz.close()


@pytest.mark.skipif(shutil.which("visca_cli") is None, reason="libvisca's visca_cli is not installed "
                    "(no Debian package provides it)")
def test_libvisca_visca_cli_over_the_pty(pty_camera: tuple[FakeCamera, DeviceServer]) -> None:
    """`visca_cli -d DEV command args` (usage from libvisca's examples/visca_cli.c)."""
    camera, server = pty_camera

    def cli(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(["visca_cli", "-d", server.address, *args], capture_output=True, text=True,
                              timeout=30)

    out = cli("get_zoom_value")
    assert out.returncode == 0, out.stderr
    assert H("88 30 01 FF") in camera.visca.commands_seen and H("81 09 04 47 FF") in camera.visca.commands_seen
    # the fact sheet's absolute move (800, -200): the fake must receive the 4+4 nibble command and get there
    cli("set_pantilt_absolute_position", "24", "20", "800", "-200")
    assert H("81 01 06 02 18 14 00 03 02 00 0F 0F 03 08 FF") in camera.visca.commands_seen
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and camera.visca._sockets:
        time.sleep(0.02)
    pan, tilt, _ = camera.state.ptz(time.monotonic())
    assert (round(pan), round(tilt)) == (800, -200)
