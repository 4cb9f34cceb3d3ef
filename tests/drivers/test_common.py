"""drivers.common: newest-wins buffer, backoff, port opening errors."""

from __future__ import annotations

import threading

import pytest

from drivers.common import Backoff, LatestBuffer, open_port, read_some
from drivers.errors import ConfigError, DisconnectedError, DriverTimeoutError
from hil_fakes.transport import PtyEndpoint


def test_buffer_drops_oldest_and_counts() -> None:
    buf: LatestBuffer[int] = LatestBuffer(capacity=2)
    for i in range(5):
        buf.put(i)
    assert buf.dropped == 3
    assert buf.get(0.1) == 3
    assert buf.get(0.1) == 4
    assert buf.put_count == 5


def test_latest_skips_and_counts_older() -> None:
    buf: LatestBuffer[int] = LatestBuffer(capacity=4)
    assert buf.latest() is None
    for i in range(3):
        buf.put(i)
    assert buf.latest() == 2
    assert buf.dropped == 2
    assert buf.latest() is None


def test_get_times_out_with_typed_error_that_is_also_builtin() -> None:
    buf: LatestBuffer[int] = LatestBuffer()
    with pytest.raises(DriverTimeoutError):
        buf.get(0.01)
    with pytest.raises(TimeoutError):
        buf.get(0.01)


def test_producer_error_surfaces_to_consumer() -> None:
    buf: LatestBuffer[int] = LatestBuffer()
    threading.Timer(0.02, lambda: buf.set_error(DisconnectedError("gone"))).start()
    with pytest.raises(DisconnectedError):
        buf.get(2.0)


def test_bad_capacity_rejected() -> None:
    with pytest.raises(ConfigError):
        LatestBuffer(capacity=0)


def test_backoff_doubles_to_cap_and_resets() -> None:
    b = Backoff(initial_s=0.1, max_s=0.5)
    assert [round(b.next_delay(), 3) for _ in range(5)] == [0.1, 0.2, 0.4, 0.5, 0.5]
    b.reset()
    assert b.next_delay() == 0.1
    with pytest.raises(ConfigError):
        Backoff(initial_s=0.0)


def test_open_missing_device_is_disconnected_error(tmp_path) -> None:
    with pytest.raises(DisconnectedError):
        open_port(str(tmp_path / "no-such-tty"))
    with pytest.raises(ConfigError):
        open_port("/dev/null", timeout_s=0)


def test_exclusive_open_and_unplug_on_a_pty(tmp_path) -> None:
    ep = PtyEndpoint(link_path=str(tmp_path / "dev"))
    try:
        port = open_port(ep.address)
        with pytest.raises(DisconnectedError):
            open_port(ep.address)  # exclusive: a second client is refused
        ep.unplug()
        with pytest.raises(DisconnectedError):
            for _ in range(50):
                read_some(port)
        port.close()
        port2 = open_port(ep.address)  # replugged behind the same link
        port2.close()
    finally:
        ep.close()
