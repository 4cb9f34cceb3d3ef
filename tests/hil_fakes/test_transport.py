"""hil_fakes.transport: pty and TCP endpoints, faults, and the device loop."""

from __future__ import annotations

import socket
import time

import pytest
import serial

from hil_fakes.transport import DeviceModel, DeviceServer, PtyEndpoint, TcpEndpoint


class Echo(DeviceModel):
    """Echoes what it gets, and says 'T' on each poll tick when ticking is on."""

    def __init__(self, tick_s: float | None = None) -> None:
        super().__init__()
        self.tick_s = tick_s
        self.next_s = 0.0
        self.clients: list[bool] = []

    def on_bytes(self, data: bytes, now_s: float) -> None:
        self.emit(data)

    def poll(self, now_s: float) -> float | None:
        if self.tick_s is None:
            return None
        if now_s >= self.next_s:
            self.emit(b"T")
            self.next_s = now_s + self.tick_s
        return self.next_s

    def on_client_change(self, connected: bool, now_s: float) -> None:
        self.clients.append(connected)


def read_until(port: serial.SerialBase, n: int, timeout_s: float = 5.0) -> bytes:
    out = b""
    deadline = time.monotonic() + timeout_s
    while len(out) < n and time.monotonic() < deadline:
        out += port.read(n - len(out))
    return out


def test_pty_echo_corrupt_drop_split(tmp_path) -> None:
    with DeviceServer(Echo(), PtyEndpoint(str(tmp_path / "fake"))) as srv:
        port = serial.serial_for_url(srv.address, timeout=0.1)
        port.write(b"hello")
        assert read_until(port, 5) == b"hello"
        srv.faults.corrupt(1, position=0)
        port.write(b"abc")
        assert read_until(port, 3) == b"`bc"
        srv.faults.drop(2)
        port.write(b"xyz")
        assert read_until(port, 1) == b"z"
        srv.faults.split(chunk_bytes=1, writes=1)
        port.write(b"split")
        assert read_until(port, 5) == b"split"
        assert srv.faults.stats.corrupted == 1 and srv.faults.stats.dropped_bytes == 2
        port.close()


def test_stall_silences_device() -> None:
    with DeviceServer(Echo(), TcpEndpoint()) as srv:
        port = serial.serial_for_url(srv.address, timeout=0.1)
        deadline = time.monotonic() + 5
        while not srv.endpoint.connected and time.monotonic() < deadline:
            time.sleep(0.01)
        srv.faults.stall(0.3)
        port.write(b"lost")
        assert port.read(4) == b""
        time.sleep(0.3)
        port.write(b"back")
        assert read_until(port, 4) == b"back"
        port.close()


def test_tcp_unplug_and_reconnect() -> None:
    with DeviceServer(Echo(tick_s=0.01), TcpEndpoint()) as srv:
        host, port_no = srv.address.removeprefix("socket://").split(":")
        s = socket.create_connection((host, int(port_no)), timeout=2)
        assert s.recv(1) == b"T"
        srv.faults.disconnect()
        s.settimeout(2)
        data = b"x"
        while data:  # drain until the fake closes the link
            data = s.recv(100)
        s.close()
        s2 = socket.create_connection((host, int(port_no)), timeout=2)
        assert s2.recv(1) == b"T"
        s2.close()
        assert srv.endpoint.accepted == 2


def test_model_error_surfaces_on_stop() -> None:
    class Broken(Echo):
        def on_bytes(self, data: bytes, now_s: float) -> None:
            raise ValueError("model bug")

    srv = DeviceServer(Broken(), TcpEndpoint()).start()
    s = socket.create_connection(("127.0.0.1", srv.endpoint.port), timeout=2)  # type: ignore[attr-defined]
    s.sendall(b"boom")
    deadline = time.monotonic() + 5
    while srv.error is None and time.monotonic() < deadline:
        time.sleep(0.01)
    s.close()
    with pytest.raises(RuntimeError, match="failed"):
        srv.stop()
