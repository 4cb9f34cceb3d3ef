"""Modbus status server: a pymodbus client reads the registers; the stop coil only when enabled."""

from __future__ import annotations

import asyncio
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pymodbus.client import ModbusTcpClient

from app.errors import AppError
from app.status import (
    ObstacleStatus,
    StatusServer,
    StatusSnapshot,
    decode_int32,
    encode_registers,
    exposure_warning,
)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def signed16(v: int) -> int:
    return v - 0x10000 if v & 0x8000 else v


def test_register_image_scales_and_signs() -> None:
    snap = StatusSnapshot(
        cycle=70000,
        x_m=-1.234,
        y_m=2.0,
        theta_rad=-0.5,
        sigma_m=0.012,
        obstacles=(ObstacleStatus(3, 1.5, -2.25, 0.1, -0.15, 0.4),),
        flags=frozenset({"scanner_ok", "loop_healthy"}),
        scanner_state="ok",
        battery_v=12.6,
        mission_state="safety_stop",
        deadline_misses=70000,
    )
    r = encode_registers(snap)
    assert r[0] == (1 << 0) | (1 << 7)
    assert r[1] == 2
    assert decode_int32(r[2], r[3]) == 70000
    assert decode_int32(r[4], r[5]) == -1234 and decode_int32(r[6], r[7]) == 2000
    assert signed16(r[8]) == -500 and r[9] == 12
    assert r[10] == 1 and r[12] == 3
    assert decode_int32(r[13], r[14]) == 1500 and decode_int32(r[15], r[16]) == -2250
    assert signed16(r[17]) == 100 and signed16(r[18]) == -150 and r[19] == 400
    assert r[46] == 65535  # saturates
    assert r[48] == 2 and r[51] == 126
    with pytest.raises(AppError):
        encode_registers(StatusSnapshot(flags=frozenset({"bogus"})))


@pytest.mark.parametrize("allow", [False, True])
def test_client_reads_registers_and_coil_obeys_config(allow: bool) -> None:
    port = free_port()
    server = StatusServer(port=port, allow_stop_coil=allow).start()
    try:
        server.publish(StatusSnapshot(cycle=5, x_m=1.0, obstacles=(ObstacleStatus(1, 2.0, 0.0, 0.0, 0.0, 0.4),)))
        client = ModbusTcpClient("127.0.0.1", port=port, timeout=5)
        assert client.connect()
        regs = client.read_input_registers(0, count=52, device_id=1).registers
        assert decode_int32(regs[2], regs[3]) == 5 and decode_int32(regs[4], regs[5]) == 1000 and regs[10] == 1
        reply = client.write_coil(0, True, device_id=1)
        assert reply.isError() is (not allow)
        assert server.stop_requested is allow
        assert server.refused_writes == (0 if allow else 1)
        if allow:
            assert client.read_coils(0, count=1, device_id=1).bits[0] is True
            client.write_coil(0, False, device_id=1)
            assert server.stop_requested is False
        client.close()
    finally:
        server.stop()


def test_port_in_use_is_a_clear_error() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        with pytest.raises(AppError, match=str(port)) as info:
            StatusServer(port=port).start(timeout_s=5)
    assert "status.port" in str(info.value)  # the hint names the setting that resolves it


@pytest.mark.parametrize(
    ("host", "allow", "words"),
    [
        ("127.0.0.1", True, ""),
        ("::1", True, ""),
        ("localhost", True, ""),
        ("0.0.0.0", False, "reachable from the network (stop coil writes refused)"),
        ("0.0.0.0", True, "stop coil is honoured"),
        ("robot.lan", False, "reachable from the network"),
    ],
)
def test_a_status_server_reachable_from_the_network_is_warned_about(host: str, allow: bool, words: str) -> None:
    warning = exposure_warning(host, allow)
    assert (warning == "") if not words else (words in warning and host in warning)


def _raw_request(port: int, pdu: bytes) -> bytes:
    """One Modbus TCP request on a raw socket; returns the response PDU (after the MBAP header)."""
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(struct.pack(">HHHB", 7, 0, len(pdu) + 1, 1) + pdu)
        header = s.recv(7)
        _, _, length, _ = struct.unpack(">HHHB", header)
        body = b""
        while len(body) < length - 1:
            chunk = s.recv(length - 1 - len(body))
            assert chunk, "server closed mid-response"
            body += chunk
        return body


@pytest.mark.parametrize("allow", [False, True])
def test_holding_register_writes_are_refused_and_the_server_names_itself(allow: bool) -> None:
    port = free_port()
    server = StatusServer(port=port, allow_stop_coil=allow).start()
    try:
        writes = {
            6: bytes.fromhex("0600000007"),
            16: bytes.fromhex("1000000001020007"),
            22: bytes.fromhex("1600000000ffff"),
            23: bytes.fromhex("17000000010000000102000a"),
        }
        for code, pdu in writes.items():
            assert _raw_request(port, pdu) == bytes([0x80 | code, 1]), code  # exception 1: illegal function
        assert server.refused_writes == len(writes)
        assert _raw_request(port, bytes.fromhex("0300000001")) == bytes.fromhex("03020000")  # still 0
        report = _raw_request(port, b"\x11")
        assert report[0] == 0x11 and b"vipsm-robot" in report and b"ymodbus" not in report
    finally:
        server.stop()


_JUNK_SCRIPT = """
import socket
from app.status import StatusServer
server = StatusServer(port=0).start()
port = server._server.transport.sockets[0].getsockname()[1]
junk = [b"GET / HTTP/1.0\\r\\n\\r\\n", bytes.fromhex("0001000700ff01") + b"x" * 20, bytes(6), bytes(range(256))]
for data in junk:
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(data)
        s.settimeout(0.2)
        try:
            s.recv(64)
        except (TimeoutError, ConnectionError):
            pass
with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
    s.sendall(bytes.fromhex("000700000006010400000001"))
    print(s.recv(64).hex())
server.stop()
"""


def test_junk_from_clients_prints_nothing_and_the_server_keeps_answering() -> None:
    # a separate process: pytest's own log capture would hide what pymodbus prints to stderr
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run(
        [sys.executable, "-c", _JUNK_SCRIPT], cwd=root, capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().endswith("04020000")
    assert ">>>>>" not in done.stderr and "Invalid Modbus" not in done.stderr


# ---------------------------------------------------------------------------------------------
# issue 12 rows 3 and 7: the listener survives junk, connections are capped and timed out, a dead
# listener is restarted, FC 5 with an illegal value is refused


def _read_one(port: int) -> bytes:
    return _raw_request(port, bytes.fromhex("0400000001"))


def _junk(port: int, i: int) -> None:
    junk = [b"GET / HTTP/1.0\r\n\r\n", bytes.fromhex("00010007ffff01") + b"x" * 30, bytes.fromhex("000100000000"),
            bytes.fromhex("0001000700060104"), bytes((i * 7 + k) % 256 for k in range(97))]
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=2) as s:
            s.sendall(junk[i % len(junk)])
            s.shutdown(socket.SHUT_WR)  # end of input: the server answers or closes at once, not after a wait
            s.settimeout(0.05)
            try:
                s.recv(64)
            except (TimeoutError, ConnectionError):
                pass
    except ConnectionError:
        pass


def test_hundreds_of_junk_connections_leave_the_server_answering() -> None:
    server = StatusServer(port=0).start()
    try:
        for i in range(300):
            _junk(server.port, i)
        assert _read_one(server.port)[:2] == bytes.fromhex("0402")
        assert server.restarts == 0 and server.error is None
    finally:
        server.stop()


def test_connections_over_the_cap_are_closed_and_the_server_still_answers_others() -> None:
    server = StatusServer(port=0, max_connections=3).start()
    held = [socket.create_connection(("127.0.0.1", server.port), timeout=2) for _ in range(3)]
    try:
        extra = socket.create_connection(("127.0.0.1", server.port), timeout=2)
        extra.settimeout(2)
        assert extra.recv(16) == b""  # closed by the server at once
        extra.close()
        assert server.connection_counts()["refused_connections"] >= 1
        held.pop().close()
        for _ in range(100):  # the server notices the closed connection
            if len(server._server.active_connections) < 3:  # noqa: SLF001
                break
            time.sleep(0.05)
        assert _read_one(server.port)[:2] == bytes.fromhex("0402")
    finally:
        for s in held:
            s.close()
        server.stop()


def test_an_idle_connection_is_closed() -> None:
    server = StatusServer(port=0, idle_timeout_s=1.0).start()
    try:
        with socket.create_connection(("127.0.0.1", server.port), timeout=5) as s:
            s.settimeout(5)
            assert s.recv(16) == b""  # closed after about a second and a half of silence
        assert server.connection_counts()["idle_closed"] == 1
    finally:
        server.stop()


def test_a_listener_that_stops_listening_is_restarted_and_reported() -> None:
    events: list[tuple[str, str]] = []
    server = StatusServer(port=0)
    server.on_event = lambda level, msg: events.append((level, msg))
    server.start()
    try:
        port = server.port
        asyncio.run_coroutine_threadsafe(_stop_listening(server), server._loop).result(5)  # noqa: SLF001
        for _ in range(100):
            if server.restarts:
                break
            time.sleep(0.05)
        assert server.restarts == 1 and server.port == port
        assert events[0][0] == "error" and "restarting" in events[0][1]
        assert _read_one(port)[:2] == bytes.fromhex("0402")
    finally:
        server.stop()


async def _stop_listening(server: StatusServer) -> None:
    """What the audit saw: the listening socket gone while the server object lives on."""
    server._server.transport.close()  # noqa: SLF001


@pytest.mark.parametrize("allow", [False, True])
@pytest.mark.parametrize("value", [0x1234, 0x0001, 0xFFFF, 0x00FF])
def test_write_single_coil_with_an_illegal_value_is_refused(allow: bool, value: int) -> None:
    server = StatusServer(port=0, allow_stop_coil=allow).start()
    try:
        reply = _raw_request(server.port, struct.pack(">BHH", 5, 0, value))
        assert reply == bytes([0x85, 3])  # exception 3: illegal data value
        assert not server.stop_requested
        if allow:  # the legal values still work
            assert _raw_request(server.port, struct.pack(">BHH", 5, 0, 0xFF00)) == struct.pack(">BHH", 5, 0, 0xFF00)
            assert server.stop_requested
    finally:
        server.stop()


def test_an_illegal_fc5_value_in_a_segment_of_several_frames_never_sets_the_coil() -> None:
    """The value is checked when each request is decoded (not on the raw segment), so how the frames
    are packed does not matter. pymodbus answers only the first frame of a segment."""
    server = StatusServer(port=0, allow_stop_coil=True).start()
    try:
        bad = struct.pack(">HHHB", 1, 0, 6, 1) + struct.pack(">BHH", 5, 0, 0x1234)
        on = struct.pack(">HHHB", 2, 0, 6, 1) + struct.pack(">BHH", 5, 0, 0xFF00)
        with socket.create_connection(("127.0.0.1", server.port), timeout=5) as s:
            s.sendall(bad + bad + on)
            reply = s.recv(64)
        assert reply[7:9] == bytes([0x85, 3])  # the first frame: exception 3
        assert not server.stop_requested
    finally:
        server.stop()


# ---------------------------------------------------------------------------------------------
# issue 32 row 11: a status server answers reads of its registers, the stop coil and identification
# (FC 17), nothing else; diagnostics are refused before pymodbus acts on them


REFUSED_REQUESTS = {
    "FC 7 read exception status": b"\x07",
    "FC 8/0 return query data": bytes.fromhex("08 0000 a537"),
    "FC 8/1 restart communications": bytes.fromhex("08 0001 ff00"),
    "FC 8/4 force listen-only mode": bytes.fromhex("08 0004 0000"),
    "FC 8/10 clear counters": bytes.fromhex("08 000a 0000"),
    "FC 11 comm event counter": b"\x0b",
    "FC 12 comm event log": b"\x0c",
    "FC 20 read file record": bytes.fromhex("14 07 06 0004 0001 0002"),
    "FC 24 read FIFO queue": bytes.fromhex("18 0000"),
    "FC 43/14 read device identification": bytes.fromhex("2b 0e 01 00"),
    "FC 43/13 CANopen general reference": bytes.fromhex("2b 0d 00"),
    "FC 65 user defined": bytes.fromhex("41 0000"),
}


@pytest.mark.parametrize("name", sorted(REFUSED_REQUESTS))
def test_diagnostic_and_other_function_codes_are_refused(name: str) -> None:
    pdu = REFUSED_REQUESTS[name]
    server = StatusServer(port=0).start()
    try:
        assert _raw_request(server.port, pdu) == bytes([0x80 | pdu[0], 1]), name  # exception 1: illegal function
        assert server.refused_functions == 1
        # force listen-only mode (or any of these) left the server answering reads
        assert _read_one(server.port)[:2] == bytes.fromhex("0402")
    finally:
        server.stop()


def test_reads_and_identification_are_still_answered() -> None:
    server = StatusServer(port=0).start()
    try:
        assert _raw_request(server.port, bytes.fromhex("0100000001"))[:2] == bytes.fromhex("0101")
        assert _raw_request(server.port, bytes.fromhex("0200000001"))[:2] == bytes.fromhex("0201")
        assert _raw_request(server.port, bytes.fromhex("0300000001"))[:2] == bytes.fromhex("0302")
        assert _raw_request(server.port, bytes.fromhex("0400000034"))[:2] == bytes.fromhex("0468")
        assert b"vipsm-robot" in _raw_request(server.port, b"\x11")
        assert server.refused_functions == 0
    finally:
        server.stop()
