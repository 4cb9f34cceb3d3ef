"""The daemon's camera adapter applies the configured pan, tilt and zoom to a camera that powered on
elsewhere (a camera can power on panned or zoomed: the realistic world's fake does)."""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path

import pytest

from app.config import Config
from app.devices import CameraAdapter
from hil_fakes.snc_rz50 import CameraHttpServer, FakeCamera, serve_visca
from hil_fakes.transport import PtyEndpoint


def test_the_daemon_sets_the_configured_pan_tilt_and_zoom_at_start_up(tmp_path: Path) -> None:
    cam = FakeCamera()
    cam.state.pan.move_to(0.0, -12.0 * cam.spec.pan_counts_per_deg, 0.0)  # powered on panned 12 deg left
    cam.state.zoom.move_to(0.0, float(0x0600), 0.0)  # ... and zoomed in
    visca = serve_visca(cam, PtyEndpoint(str(tmp_path / "camera")))
    http = CameraHttpServer(cam).start()
    cfg = Config()
    devices = dataclasses.replace(cfg.devices, camera_url=visca.address, camera_http_url=http.url,
                                  camera_pan_deg=5.0, camera_tilt_deg=0.0, camera_zoom=0x0200)
    adapter = CameraAdapter(dataclasses.replace(cfg, devices=devices))
    try:
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and (adapter.visca is None or adapter.visca.client is None):
            time.sleep(0.05)
        assert adapter.visca is not None and adapter.visca.client is not None, adapter.visca.last_error
        pan_rad, _tilt_rad, _hfov = cam.state.view(time.monotonic() + 10.0)
        assert math.degrees(pan_rad) == pytest.approx(5.0, abs=0.2)
        assert cam.state.ptz(time.monotonic() + 10.0)[2] == pytest.approx(0x0200, abs=2)
    finally:
        adapter.close()
        http.stop()
        visca.stop()
