"""The base adapter's command rate: a 40 Hz loop re-sends an unchanged velocity at most every
``devices.robot_command_period_s``; a change (a stop above all) goes out in the same cycle."""

from __future__ import annotations

import time

import pytest

from app.devices import BaseAdapter
from drivers.p2os.client import ArcosDisconnectedError


class _Client:
    def __init__(self) -> None:
        self.sent: list[tuple[float, float]] = []
        self.heartbeats = 0
        self.fail = False

    def heartbeat(self) -> None:
        self.heartbeats += 1

    def set_velocity(self, v: float, w: float) -> None:
        if self.fail:
            raise ArcosDisconnectedError("unplugged")
        self.sent.append((v, w))

    def stop(self) -> None:
        self.sent.append((0.0, 0.0))

    def close(self) -> None:
        pass


@pytest.fixture
def adapter():
    a = BaseAdapter("socket://127.0.0.1:1", 9600, 1.0, 5.0, command_period_s=0.2)  # nothing listens there
    yield a
    a.close()


def _with_client(a: BaseAdapter) -> _Client:
    c = _Client()
    a.opener.client = c  # type: ignore[assignment]
    return c


def test_an_unchanged_command_is_resent_only_after_the_period(adapter: BaseAdapter) -> None:
    c = _with_client(adapter)
    for _ in range(5):
        adapter.command(0.3, 0.0)
    assert c.sent == [(0.3, 0.0)] and c.heartbeats == 5  # alive every cycle, written once
    time.sleep(0.25)
    adapter.command(0.3, 0.0)
    assert c.sent == [(0.3, 0.0), (0.3, 0.0)]


def test_a_change_goes_out_in_the_same_cycle(adapter: BaseAdapter) -> None:
    c = _with_client(adapter)
    adapter.command(0.3, 0.0)
    adapter.command(0.0, 0.0)  # a safety stop
    adapter.command(0.0, 0.1)
    assert c.sent == [(0.3, 0.0), (0.0, 0.0), (0.0, 0.1)]


def test_a_failed_write_and_a_new_client_are_retried_at_once(adapter: BaseAdapter) -> None:
    c = _with_client(adapter)
    c.fail = True
    adapter.command(0.3, 0.0)
    c.fail = False
    adapter.command(0.3, 0.0)
    assert c.sent == [(0.3, 0.0)]
    c2 = _with_client(adapter)  # reconnected: the new session has not heard the command
    adapter.command(0.3, 0.0)
    assert c2.sent == [(0.3, 0.0)]


def test_period_zero_writes_every_cycle() -> None:
    a = BaseAdapter("socket://127.0.0.1:1", 9600, 1.0, 5.0, command_period_s=0.0)
    try:
        c = _with_client(a)
        for _ in range(3):
            a.command(0.3, 0.0)
        assert len(c.sent) == 3
    finally:
        a.close()


def test_the_period_is_a_config_key_with_its_bounds() -> None:
    from app.config import Config, load_config
    from app.errors import ConfigError

    assert Config().devices.robot_command_period_s == 0.1
    assert load_config(None, ["devices.robot_command_period_s=0"]).devices.robot_command_period_s == 0.0
    with pytest.raises(ConfigError, match="robot_command_period_s"):
        load_config(None, ["devices.robot_command_period_s=0.6"])  # above the maximum, 0.5 s
