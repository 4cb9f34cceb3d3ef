"""Fixtures: the fake SNC-RZ50 on a pty or loopback TCP, and a client connected to it."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import pytest

from drivers.ptz_cam import ViscaClient, ViscaConfig
from hil_fakes.snc_rz50 import FakeCamera, FakeCameraSpec, serve_visca
from hil_fakes.transport import DeviceServer, PtyEndpoint, TcpEndpoint

# generous: the machine is shared and loaded; nothing here asserts on time
FAST = ViscaConfig(ack_timeout_s=2.0, inquiry_timeout_s=2.0, default_completion_timeout_s=3.0)
# for tests that provoke timeouts: still far above a loopback round trip
FAULTY = ViscaConfig(ack_timeout_s=0.75, inquiry_timeout_s=0.75, default_completion_timeout_s=3.0)


@dataclass
class Rig:
    camera: FakeCamera
    server: DeviceServer
    client: ViscaClient
    transport: str


def make_server(camera: FakeCamera, transport: str, tmp_path) -> DeviceServer:  # type: ignore[no-untyped-def]
    endpoint = PtyEndpoint(str(tmp_path / "ptzcam")) if transport == "pty" else TcpEndpoint()
    return serve_visca(camera, endpoint)


@pytest.fixture(params=["pty", "tcp"])
def transport(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture
def spec() -> FakeCameraSpec:
    return FakeCameraSpec(reset_duration_s=0.3, zoom_full_travel_s=1.0)


@pytest.fixture
def config() -> ViscaConfig:
    return FAST


@pytest.fixture
def rig(transport: str, spec: FakeCameraSpec, config: ViscaConfig, tmp_path) -> Iterator[Rig]:  # type: ignore[no-untyped-def]
    camera = FakeCamera(spec)
    server = make_server(camera, transport, tmp_path)
    client = ViscaClient(server.address, config)
    try:
        client.open()
        yield Rig(camera, server, client, transport)
    finally:
        client.close()
        server.stop()
