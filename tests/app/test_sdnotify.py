"""sd_notify over a real AF_UNIX datagram socket, as systemd provides it."""

from __future__ import annotations

import os
import socket
from pathlib import Path

from app.sdnotify import SystemdNotifier


def test_notifications_reach_the_socket(tmp_path: Path) -> None:
    path = str(tmp_path / "notify")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(path)
    sock.settimeout(2)
    try:
        n = SystemdNotifier({"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "2000000", "WATCHDOG_PID": str(os.getpid())})
        assert n.enabled and n.watchdog_interval_s == 1.0
        assert n.ready() and n.watchdog() and n.status("cycle 3")
        assert [sock.recv(100) for _ in range(3)] == [b"READY=1", b"WATCHDOG=1", b"STATUS=cycle 3"]
        n.close()
    finally:
        sock.close()


def test_outside_systemd_everything_is_a_no_op() -> None:
    n = SystemdNotifier({})
    assert not n.enabled and n.watchdog_interval_s is None
    assert n.ready() is False and n.failures == 0


def test_watchdog_for_another_pid_is_ignored_and_send_failures_counted(tmp_path: Path) -> None:
    n = SystemdNotifier({"NOTIFY_SOCKET": str(tmp_path / "absent"), "WATCHDOG_USEC": "1000", "WATCHDOG_PID": "1"})
    assert n.watchdog_interval_s is None
    assert n.ready() is False and n.failures == 1
