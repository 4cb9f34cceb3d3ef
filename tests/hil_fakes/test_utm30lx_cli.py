"""`vipsm-robot fake scanner` served to other programs, probed with `vipsm-robot probe --scanner`."""

from __future__ import annotations

import json
import os
import select
import signal
import socket
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _run_cli(*args: str, timeout_s: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "app", *args], cwd=REPO, capture_output=True, text=True,
                          timeout=timeout_s)


@pytest.fixture
def fake_process(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[str], list[str], Path]]:
    link = tmp_path / "hokuyo"
    proc = subprocess.Popen(
        [sys.executable, "-m", "app", "fake", "scanner", "--pty", "--link", str(link), "--tcp", "127.0.0.1:0"],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], 30.0)
    assert ready, "the fake did not print its addresses"
    # both addresses are printed back to back (readline returns '' if the fake died)
    lines = [proc.stdout.readline().strip(), proc.stdout.readline().strip()]
    yield proc, lines, link
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)


def test_fake_prints_addresses_and_probe_reads_it(fake_process: tuple[subprocess.Popen[str], list[str], Path]) -> None:
    proc, lines, link = fake_process
    assert lines[0] == str(link) and link.is_symlink()
    assert lines[1].startswith("socket://127.0.0.1:")
    for url in lines:
        result = _run_cli("probe", "--scanner", url, "--json")
        assert result.returncode == 0, result.stderr
        out = json.loads(result.stdout)["scanner"]
        assert out["vv"]["SERI"] == "00903971" and out["vv"]["FIRM"] == "P.1.05(17/Apr./2009)"
        assert out["pp"]["AMAX"] == "1080" and out["pp"]["SCAN"] == "2400"
        assert out["ii"]["STAT"] == "Sensor works well."
        scan = out["scan"]
        assert scan["count"] == 1081 and scan["valid_count"] == 1081
        assert 0.5 < scan["min_range_m"] <= scan["max_range_m"] < 10.0
        assert scan["device_stamp_ms"] > 0 and scan["host_stamp_s"] > 0
    # SIGTERM ends the fake cleanly and removes its link
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(10) == 0
    assert not link.exists()


def test_probe_failure_is_one_line_and_nonzero(tmp_path: Path) -> None:
    result = _run_cli("probe", "--scanner", str(tmp_path / "absent"), "--json")
    assert result.returncode == 2
    assert result.stdout == ""
    assert len(result.stderr.strip().splitlines()) == 1 and "cannot open" in result.stderr


def test_probe_list_reports_devices_or_why_not() -> None:
    result = _run_cli("probe", "--list", "--json")
    assert result.returncode == 0, result.stderr
    devices = json.loads(result.stdout)["devices"]
    assert isinstance(devices, list)
    scanners = [d for d in devices if d.get("device") == "scanner"]
    for d in scanners:
        assert d["vendor_id"] == "0x15d1"
    if not scanners:
        # nothing attached here; where libusb is missing the reason is printed, not a traceback
        assert "Traceback" not in result.stderr


def test_fake_needs_a_transport() -> None:
    result = _run_cli("fake", "scanner")
    assert result.returncode == 2 and "--pty" in result.stderr


def test_fake_with_a_paper_scenario_world() -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "app", "fake", "scanner", "--tcp", "127.0.0.1:0", "--scenario", "1"],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        assert proc.stdout is not None
        ready, _, _ = select.select([proc.stdout], [], [], 30.0)
        assert ready, "the fake did not print its address"
        url = proc.stdout.readline().strip()
        result = _run_cli("probe", "--scanner", url, "--json")
        assert result.returncode == 0, result.stderr
        scan = json.loads(result.stdout)["scanner"]["scan"]
        # the room is walled on three sides: the open side gives no return (NaN, not a range)
        assert scan["count"] == 1081 and 0 < scan["valid_count"] < 1081
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)


# ---------------------------------------------------------------------------------------------
# readiness: READY=1 to systemd, then the addresses on stdout, only once every endpoint listens


@pytest.fixture
def notify_socket(tmp_path: Path) -> Iterator[socket.socket]:
    """A datagram socket standing in for systemd's $NOTIFY_SOCKET."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(str(tmp_path / "notify"))
    sock.setblocking(False)
    yield sock
    sock.close()


def _notifications(sock: socket.socket) -> list[str]:
    """The datagrams already delivered (sd_notify's sendto queues them at once; nothing is waited for)."""
    out = []
    while True:
        try:
            out.append(sock.recv(4096).decode())
        except BlockingIOError:
            return out


def _start_notifying_fake(notify: socket.socket, *args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "app", "fake", "scanner", *args], cwd=REPO, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1", "NOTIFY_SOCKET": notify.getsockname()},
    )


def _reply(send: Callable[[bytes], None], recv: Callable[[], bytes]) -> bytes:
    """VV sent once, its reply read to the empty line that ends it (reads time out: no retry, no sleep)."""
    send(b"VV\n")
    data = b""
    while b"\n\n" not in data:
        chunk = recv()
        assert chunk, f"the fake closed or went silent after {data!r}"
        data += chunk
    return data


def test_ready_is_notified_then_printed_once_every_endpoint_listens(
        tmp_path: Path, notify_socket: socket.socket) -> None:
    """The moment the addresses are printed, READY=1 has been sent, and both endpoints take a client at the
    first attempt: a client that waits for either never connects before the fake listens."""
    link = tmp_path / "hokuyo"
    proc = _start_notifying_fake(notify_socket, "--pty", "--link", str(link), "--tcp", "127.0.0.1:0")
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline().strip(), proc.stdout.readline().strip()]  # '' if the fake died
        assert lines[0] == str(link) and lines[1].startswith("socket://127.0.0.1:"), proc.stderr
        (ready,) = _notifications(notify_socket)
        assert ready.splitlines() == ["READY=1", f"STATUS=serving {lines[0]} {lines[1]}"]
        port = int(lines[1].rsplit(":", 1)[1])
        assert port != 0
        with socket.create_connection(("127.0.0.1", port), timeout=10.0) as conn:
            assert _reply(conn.sendall, lambda: conn.recv(4096)).startswith(b"VV\n00P\n")
        fd = os.open(link, os.O_RDWR | os.O_NOCTTY)
        try:
            def read_pty() -> bytes:
                ready_fds, _, _ = select.select([fd], [], [], 10.0)
                return os.read(fd, 4096) if ready_fds else b""
            assert _reply(lambda b: os.write(fd, b) and None, read_pty).startswith(b"VV\n00P\n")
        finally:
            os.close(fd)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(10) == 0
        assert _notifications(notify_socket) == ["STOPPING=1"] and not link.exists()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)


def test_an_endpoint_that_cannot_listen_gives_no_readiness(tmp_path: Path, notify_socket: socket.socket) -> None:
    """The TCP port is taken: the pty already up is closed again, nothing printed, no READY=1, exit 2."""
    taken = socket.create_server(("127.0.0.1", 0))
    link = tmp_path / "hokuyo"
    try:
        port = taken.getsockname()[1]
        proc = _start_notifying_fake(notify_socket, "--pty", "--link", str(link), "--tcp", f"127.0.0.1:{port}")
        out, err = proc.communicate(timeout=60)
    finally:
        taken.close()
    assert proc.returncode == 2 and out == ""
    assert "cannot listen" in err and len(err.strip().splitlines()) == 1
    assert _notifications(notify_socket) == ["STOPPING=1"] and not link.exists()


def test_help_documents_the_readiness_handshake() -> None:
    result = _run_cli("fake", "scanner", "--help")
    assert result.returncode == 0
    for words in ("READY=1", "NOTIFY_SOCKET", "port 0 picks a free", "prints one line per endpoint"):
        assert words in " ".join(result.stdout.split()), words
