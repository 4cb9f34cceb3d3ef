"""The live view: every field-log channel reaches a WebSocket client that subscribes (Foxglove's
protocol, a test client on loopback); addresses are parsed and a remote one is refused by default."""

from __future__ import annotations

import base64
import json
import os
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import foxglove
import pytest
from websockets.exceptions import InvalidStatus, WebSocketException
from websockets.sync.client import connect

from app import logmessages as lm
from app.errors import AppError, ConfigError
from app.fieldlog import FieldLog
from app.livefront import Backend, FrontLimits, LiveFront
from app.liveview import LineBudget, LiveView, _SdkServer, check_exposure, layout_path, parse_listen
from app.wsframes import FrameReader
from vipsm.types import Obstacle


def _messages(t: float) -> dict[str, object]:
    return {
        "/scan": lm.laser_scan([1.0, 2.0, float("inf")], -0.5, 0.5, None, t),
        "/pose": lm.pose_in_frame(1.0, 2.0, 0.3, t),
        "/tf": lm.robot_transforms((1.0, 2.0, 0.3), lm.Mounts(0.16, 0, 0, 0.1, 0, 0.55), (0.2, 0.0), t),
        "/obstacles": lm.scene_update([Obstacle(3, 4.0, 1.0, 0.5, 0.0, 0.2, 0.1, 0.3, 10, 20)], t, 0.3),
        "/log": lm.log_line("info", "hello", t),
        "/diagnostics": {"cycle": 1},
    }


def test_each_channel_reaches_a_subscribed_websocket_client() -> None:
    log = FieldLog(None).start()  # no file: the channels only feed the live view
    live = LiveView(log.context, "127.0.0.1", 0).start()
    try:
        t = time.time()
        for topic, msg in _messages(t).items():  # the channels exist once something was logged
            log.log(topic, t, msg)
        time.sleep(0.3)
        with connect(live.url, subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"], open_timeout=5) as ws:
            channels: dict[str, int] = {}
            deadline = time.monotonic() + 5
            while len(channels) < 6 and time.monotonic() < deadline:
                m = json.loads(ws.recv(timeout=2))
                if m["op"] == "advertise":
                    channels.update({c["topic"]: c["id"] for c in m["channels"]})
            assert set(channels) == set(_messages(t))
            subs = {i: topic for i, topic in enumerate(sorted(channels))}
            ws.send(json.dumps({"op": "subscribe",
                                "subscriptions": [{"id": i, "channelId": channels[tp]} for i, tp in subs.items()]}))
            time.sleep(0.3)
            for topic, msg in _messages(time.time()).items():
                log.log(topic, time.time(), msg)
            got: set[str] = set()
            while got != set(subs.values()) and time.monotonic() < deadline + 5:
                m = ws.recv(timeout=2)
                if isinstance(m, bytes) and m[0] == 1:  # message data: opcode, subscription id, time, payload
                    got.add(subs[int.from_bytes(m[1:5], "little")])
            assert got == set(subs.values())
    finally:
        log.close()
        live.stop()
    assert log.stats.state == "off" and log.stats.lost_to_disk == 0


@pytest.mark.parametrize(("spec", "want"), [("8765", ("127.0.0.1", 8765)), ("0.0.0.0:9", ("0.0.0.0", 9)),
                                            ("[::1]:8765", ("::1", 8765)), ("localhost:1", ("localhost", 1)),
                                            (" 0 ", ("127.0.0.1", 0)), ("robot-1.lan:65535", ("robot-1.lan", 65535))])
def test_listen_addresses(spec: str, want: tuple[str, int]) -> None:
    assert parse_listen(spec) == want


@pytest.mark.parametrize("spec", ["", "abc", "1:99999", ":80x", "-1", "8_765", "\uff18\uff17\uff16\uff15", "+80",
                                  "1:", "[::1]", "[nothost]:80", "a b:80", "-bad-:80"])
def test_bad_listen_addresses_are_config_errors(spec: str) -> None:
    with pytest.raises(ConfigError, match="live.listen"):
        parse_listen(spec)


@pytest.mark.parametrize("spec", ["::1", "::1:8765", "fe80::1"])
def test_an_ipv6_host_without_brackets_is_refused_saying_brackets_are_needed(spec: str) -> None:
    with pytest.raises(ConfigError, match=r"IPv6 host needs brackets.*\[::1\]:8765"):
        parse_listen(spec)


@pytest.mark.parametrize(("value", "message"), [('"8_765"', "ASCII digits"), ('"::1"', "needs brackets"),
                                                ('"0.0.0.0:80"', "live.allow_remote")])
def test_dump_config_validates_live_listen(value: str, message: str) -> None:
    proc = subprocess.run([sys.executable, "-m", "app", "dump-config", "--set", f"live.listen={value}"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "live.listen" in proc.stderr and message in proc.stderr
    assert proc.stdout == "" and "Traceback" not in proc.stderr


def test_remote_live_view_is_refused_unless_allowed_then_warned() -> None:
    assert check_exposure("127.0.0.1", False) == "" and check_exposure("::1", False) == ""
    with pytest.raises(ConfigError, match="live.allow_remote"):
        check_exposure("0.0.0.0", False)
    assert "readable by anyone" in check_exposure("0.0.0.0", True)


def test_sim_refuses_a_remote_live_view_with_one_line_and_no_log_file(tmp_path: Path) -> None:
    log = tmp_path / "never.mcap"
    proc = subprocess.run([sys.executable, "-m", "app", "sim", "--duration", "1", "--live", "0.0.0.0:0",
                           "--log", str(log), "--set", "status.port=0"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "live.allow_remote" in proc.stderr and "Traceback" not in proc.stderr
    assert not log.exists()


def test_the_layout_file_names_the_logs_topics() -> None:
    layout = json.loads(open(layout_path(), encoding="utf-8").read())
    text = json.dumps(layout)
    for topic in ("/scan", "/obstacles", "/camera/image", "/diagnostics"):
        assert topic in text


# ---------------------------------------------------------------------------------------------
# the front: caps, timeouts, bounded queues, the older subprotocol, latched topics, shutdown

SDK = "foxglove.sdk.v1"


def _big_channel(context: object) -> foxglove.Channel:
    return foxglove.Channel("/big", message_encoding="json", context=context)  # type: ignore[arg-type]


def _raw_upgrade(port: int, subprotocol: str = SDK, rcvbuf: int = 0) -> tuple[socket.socket, bytes]:
    """A WebSocket handshake by hand; the socket is then read only when the test says so."""
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    if rcvbuf:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    s.settimeout(10)
    s.connect(("127.0.0.1", port))
    key = base64.b64encode(os.urandom(16)).decode()
    s.sendall((f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
               f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
               f"Sec-WebSocket-Protocol: {subprotocol}\r\n\r\n").encode())
    buf = b""
    while b"\r\n\r\n" not in buf:
        data = s.recv(4096)
        assert data, f"closed during the handshake: {buf!r}"
        buf += data
    head, rest = buf.split(b"\r\n\r\n", 1)
    assert head.startswith(b"HTTP/1.1 101"), head
    return s, rest


def _masked_text(payload: bytes) -> bytes:
    mask = os.urandom(4)
    body = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
    n = len(body)
    head = bytes([0x81, 0x80 | n]) if n < 126 else bytes([0x81, 0x80 | 126]) + n.to_bytes(2, "big")
    return head + mask + body


def _subscribe_raw(s: socket.socket, rest: bytes, *topics: str, timeout_s: float = 10.0) -> None:
    """Read frames until every topic is advertised, then subscribe to them (ids 7, 8, ...)."""
    reader = FrameReader(64 << 20)
    deadline = time.monotonic() + timeout_s
    s.settimeout(timeout_s)
    frames = reader.feed(rest)
    ids: dict[str, int] = {}
    while time.monotonic() < deadline:
        for f in frames:
            msg = json.loads(f.payload) if f.opcode == 1 else {}
            ids.update({ch["topic"]: ch["id"] for ch in msg.get("channels", []) if msg["op"] == "advertise"})
        if set(topics) <= set(ids):
            subs = [{"id": 7 + i, "channelId": ids[t]} for i, t in enumerate(topics)]
            s.sendall(_masked_text(json.dumps({"op": "subscribe", "subscriptions": subs}).encode()))
            return
        frames = reader.feed(s.recv(65536))
    raise AssertionError(f"{set(topics) - set(ids)} never advertised")


def _wait(predicate: Callable[[], bool], timeout_s: float = 20.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return predicate()


def test_port_0_names_the_bound_port_in_the_url_before_and_after_stop() -> None:
    live = LiveView(foxglove.Context(), "127.0.0.1", 0).start()
    try:
        port = live.port
        assert port > 0 and live.url == f"ws://127.0.0.1:{port}"
        socket.create_connection(("127.0.0.1", port), timeout=5).close()
    finally:
        live.stop()
    assert live.url == f"ws://127.0.0.1:{port}" and live.summary()["url"] == live.url


def test_ipv6_loopback_in_brackets_is_served() -> None:
    if not socket.has_ipv6:
        pytest.skip("no IPv6 on this machine")
    try:
        live = LiveView(foxglove.Context(), *parse_listen("[::1]:0")).start()
    except AppError as exc:
        pytest.skip(f"IPv6 loopback not available: {exc}")
    try:
        assert live.url == f"ws://[::1]:{live.port}"
        with connect(live.url, subprotocols=[SDK], open_timeout=5) as ws:
            assert json.loads(ws.recv(timeout=5))["op"] == "serverInfo"
    finally:
        live.stop()


@pytest.mark.parametrize("subprotocols", [["foxglove.websocket.v1"], [SDK], ["foxglove.websocket.v1", SDK]])
def test_the_older_subprotocol_name_is_served_like_the_sdks(subprotocols: list[str]) -> None:
    """@foxglove/ws-protocol 0.8 and Lichtblick before its foxglove.sdk.v1 support offer only
    foxglove.websocket.v1 (the same messages under the older name); the SDK alone answers 400."""
    live = LiveView(foxglove.Context(), "127.0.0.1", 0).start()
    try:
        with connect(live.url, subprotocols=subprotocols, open_timeout=5) as ws:  # type: ignore[arg-type]
            assert ws.subprotocol == (SDK if SDK in subprotocols else "foxglove.websocket.v1")
            assert json.loads(ws.recv(timeout=5))["op"] == "serverInfo"
        with pytest.raises(InvalidStatus) as info:
            connect(live.url, subprotocols=["chat"], open_timeout=5)  # type: ignore[list-item]
        assert info.value.response.status_code == 400 and b"foxglove.websocket.v1" in info.value.response.body
    finally:
        live.stop()


def test_the_config_is_latched_for_a_viewer_that_connects_after_it_was_logged() -> None:
    log = FieldLog(None).start()
    live = LiveView(log.context, "127.0.0.1", 0).start()
    config = {"log_version": 3, "live": {"listen": "0"}}
    try:
        t = time.time()
        log.log("/vipsm/config", t, config)
        live.latch("/vipsm/config", t, config)
        time.sleep(0.5)  # logged and gone: nobody was subscribed
        for _ in range(2):  # each later viewer gets it
            with connect(live.url, subprotocols=[SDK], open_timeout=5) as ws:
                channel = _advertised(ws, "/vipsm/config")
                ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 3, "channelId": channel}]}))
                m = ws.recv(timeout=5)
                while not isinstance(m, bytes):
                    m = ws.recv(timeout=5)
                assert m[0] == 1 and int.from_bytes(m[1:5], "little") == 3
                assert int.from_bytes(m[5:13], "little") == int(t * 1e9)
                assert json.loads(m[13:]) == config
    finally:
        log.close()
        live.stop()


def _advertised(ws: Any, topic: str) -> int:
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        m = json.loads(ws.recv(timeout=5))
        for ch in m.get("channels", []) if m["op"] == "advertise" else []:
            if ch["topic"] == topic:
                return int(ch["id"])
    raise AssertionError(f"{topic} never advertised")


def test_connections_over_the_cap_get_503_and_a_silent_one_is_closed_after_the_handshake_timeout() -> None:
    live = LiveView(foxglove.Context(), "127.0.0.1", 0,
                    limits=FrontLimits(max_clients=2, handshake_timeout_s=1.0)).start()
    try:
        silent = [socket.create_connection(("127.0.0.1", live.port), timeout=10) for _ in range(2)]
        assert _wait(lambda: live.summary()["clients"] == 2, 10)
        third = socket.create_connection(("127.0.0.1", live.port), timeout=10)
        assert third.recv(4096).startswith(b"HTTP/1.1 503")
        third.close()
        for s in silent:  # closed by the server once the handshake timeout passed
            assert s.recv(4096) == b""
            s.close()
        assert _wait(lambda: live.summary()["clients"] == 0, 10)
        with connect(live.url, subprotocols=[SDK], open_timeout=5) as ws:  # room again
            assert json.loads(ws.recv(timeout=5))["op"] == "serverInfo"
        s = live.summary()
        assert s["refused_full"] == 1 and s["handshake_failures"] == 2 and s["served"] == 1
    finally:
        live.stop()


def test_a_viewer_that_stops_reading_costs_a_bounded_queue_then_is_disconnected_while_others_see_all() -> None:
    ctx = foxglove.Context()
    big = _big_channel(ctx)
    limit = 64 * 1024
    live = LiveView(ctx, "127.0.0.1", 0, limits=FrontLimits(send_queue_bytes=limit, stall_timeout_s=2.0)).start()
    try:
        stalled, rest = _raw_upgrade(live.port, rcvbuf=4096)
        big.log(b'"warm"')  # advertised once it exists
        _subscribe_raw(stalled, rest, "/big")
        with connect(live.url, subprotocols=[SDK], open_timeout=5, max_size=None) as ws:
            ws.send(json.dumps({"op": "subscribe",
                                "subscriptions": [{"id": 1, "channelId": _advertised(ws, "/big")}]}))
            time.sleep(0.3)
            blob = json.dumps("x" * 20_000).encode()
            peak = 0
            for _ in range(300):
                big.log(blob)
                peak = max(peak, live._front.queued_bytes())  # type: ignore[union-attr]
                time.sleep(0.005)
            done = threading.Event()
            ender = threading.Thread(target=lambda: [big.log(b'"last"') for _ in iter(lambda: done.wait(0.1), True)])
            ender.start()  # repeated: the reader may miss one if it lags (its queue is bounded too)
            try:
                while (m := ws.recv(timeout=20)) and m[13:] != b'"last"':  # the reading viewer gets to the end
                    pass
            finally:
                done.set()
                ender.join()
        assert _wait(lambda: live.summary()["slow_disconnects"] == 1)
        s = live.summary()
        assert s["dropped_messages"] > 0 and peak <= 2 * (limit + len(blob) + 64)  # each: a limit and a message
        assert _wait(lambda: live._front.queued_bytes() == 0)  # type: ignore[union-attr]
        stalled.close()
    finally:
        live.stop()


def test_stop_returns_within_its_bound_with_five_clients_that_stopped_reading() -> None:
    ctx = foxglove.Context()
    big = _big_channel(ctx)
    live = LiveView(ctx, "127.0.0.1", 0).start()
    big.log(b'"warm"')
    clients = []
    for _ in range(5):
        s, rest = _raw_upgrade(live.port, rcvbuf=4096)
        _subscribe_raw(s, rest, "/big")
        clients.append(s)
    blob = json.dumps("y" * 100_000).encode()
    for _ in range(100):
        big.log(blob)
    time.sleep(0.5)
    stopper = threading.Thread(target=live.stop, daemon=True)  # the SDK alone never returned (> 100 s)
    stopper.start()
    stopper.join(2.0)
    assert not stopper.is_alive()
    for s in clients:
        s.close()


def test_connect_floods_give_a_bounded_number_of_lines_then_a_count() -> None:
    lines: list[str] = []
    live = LiveView(foxglove.Context(), "127.0.0.1", 0, on_event=lambda level, msg: lines.append(msg)).start()
    t0 = time.monotonic()
    try:
        for _ in range(200):  # junk requests and resets: each would have been one stderr line
            s = socket.create_connection(("127.0.0.1", live.port), timeout=10)
            s.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n")
            s.recv(4096)
            s.close()
        assert _wait(lambda: live.summary()["handshake_failures"] == 200)
    finally:
        live.stop()
    intervals = 1 + int((time.monotonic() - t0) // 60)
    shown = [m for m in lines if "more lines not shown" not in m]
    held = sum(int(m.split(": ")[1].split()[0]) for m in lines if "more lines not shown" in m)
    assert len(shown) <= LineBudget(print).lines["client"] * intervals
    assert held == live.summary()["lines_not_shown"] == 200 - len(shown) > 0


def test_the_line_budget_summarises_per_interval() -> None:
    now = [0.0]
    out: list[tuple[str, str]] = []
    budget = LineBudget(lambda level, msg: out.append((level, msg)), {"client": 2, "state": 1}, 60.0, lambda: now[0])
    for i in range(10):
        budget("client", "info", f"c{i}")
    budget("state", "error", "s0")
    budget("state", "error", "s1")
    assert [m for _, m in out] == ["c0", "c1", "s0"]
    now[0] = 61.0
    budget("client", "info", "c10")  # a new interval: the summary first, then the line
    assert out[3][1].startswith("live view: 9 more lines not shown") and "8 client, 1 state" in out[3][1]
    assert out[4][1] == "c10" and budget.suppressed == 9


_FD_CHILD = """
import json, os, resource, sys, foxglove
from app.liveview import LiveView

soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
resource.setrlimit(resource.RLIMIT_NOFILE, (min(256, soft), hard))
live = LiveView(foxglove.Context(), "127.0.0.1", 0).start()
print(live.port, flush=True)
held = []
try:
    while True:  # every descriptor taken, as ~1000 unfinished requests did under the default 1024
        held.append(os.open(os.devnull, os.O_RDONLY))
except OSError:
    pass
print("exhausted", flush=True)
sys.stdin.readline()
for fd in held:
    os.close(fd)
print("freed", flush=True)
sys.stdin.readline()
print(json.dumps(live.summary()), flush=True)
live.stop()
"""


def test_the_live_view_recovers_after_file_descriptors_ran_out_and_says_so(tmp_path: Path) -> None:
    """Before the front the SDK's listener was gone for good (connection refused) and nothing said so."""
    script = tmp_path / "child.py"
    script.write_text(_FD_CHILD)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    proc = subprocess.Popen([sys.executable, str(script)], env=env, text=True, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert proc.stdout is not None and proc.stdin is not None
        port = int(proc.stdout.readline())
        assert proc.stdout.readline().strip() == "exhausted"
        pending = []
        for _ in range(3):  # they wait in the listen backlog: accepting them fails
            s = socket.create_connection(("127.0.0.1", port), timeout=10)
            s.sendall(b"GET / HTTP/1.1\r\n")
            pending.append(s)
        time.sleep(1.5)
        for s in pending:
            s.close()
        proc.stdin.write("\n")
        proc.stdin.flush()
        assert proc.stdout.readline().strip() == "freed"
        assert _wait(lambda: _serves(port), 20.0)
        proc.stdin.write("\n")
        proc.stdin.flush()
        summary = json.loads(proc.stdout.readline())
        _, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
        proc.wait()
    assert summary["accept_errors"] > 0 and summary["state"] == "ok" and "Errno 24" in summary["last_failure"]
    assert "cannot accept connections" in err and "accepting connections again" in err


def _serves(port: int) -> bool:
    try:
        with connect(f"ws://127.0.0.1:{port}", subprotocols=[SDK], open_timeout=5) as ws:
            return json.loads(ws.recv(timeout=5))["op"] == "serverInfo"
    except (OSError, WebSocketException, TimeoutError):
        return False


def test_sim_exits_within_2_s_of_sigterm_with_five_viewers_that_stopped_reading(tmp_path: Path) -> None:
    """The daemon's exit used to wait ~65 s for them (the SDK's stop); systemd would kill it. A reading
    viewer meanwhile gets everything, /vipsm/config included though it was logged before it came.
    ``VIPSM_LIVE_SOAK_S=600`` makes this the 10-minute check (default 15 s: the queues fill)."""
    soak_s = float(os.environ.get("VIPSM_LIVE_SOAK_S", "15"))
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    proc = subprocess.Popen([sys.executable, "-m", "app", "sim", "--duration", str(soak_s + 300), "--no-progress",
                             "--json", "--live", "127.0.0.1:0", "--log", str(tmp_path / "s.mcap"), "--set",
                             "status.port=0", "--set", f"live.stall_timeout_s={soak_s + 600}"],  # kept connected
                            env=env, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stderr is not None and proc.stdout is not None
    port, err = _live_port(proc.stderr)
    clients = []
    try:
        for _ in range(5):
            s, rest = _raw_upgrade(port, rcvbuf=4096)
            _subscribe_raw(s, rest, "/camera/image", "/scan", "/odom", timeout_s=300.0)  # the loop runs
            clients.append(s)
        got: dict[str, int] = {}
        reader = threading.Thread(target=_read_everything, args=(port, got), daemon=True)
        reader.start()
        time.sleep(soak_s)  # the stalled clients' queues fill (~0.5 MB/s each; kernel buffers up to 4 MB)
        proc.send_signal(signal.SIGTERM)
        t0 = time.monotonic()
        proc.wait(timeout=60)
        took = time.monotonic() - t0
        out = proc.stdout.read()
    finally:
        proc.kill()
        proc.wait()
        for s in clients:
            s.close()
    assert proc.returncode == 0, "".join(err[-20:])
    print(f"exit {took:.2f} s after SIGTERM after {soak_s:g} s; the reading viewer got {got}")
    assert took < 2.0, f"exit took {took:.1f} s after SIGTERM"
    assert got.get("config") == 1 and got["messages"] > 0
    live = json.loads(out)["live_view"]
    assert json.loads(out)["live_url"] == f"ws://127.0.0.1:{port}" and live["url"] == f"ws://127.0.0.1:{port}"
    assert live["served"] == 6 and live["slow_disconnects"] == 0 and live["dropped_messages"] > 0


def _live_port(stderr: Any) -> tuple[int, list[str]]:
    """The live view's port from the daemon's stderr, which is then drained on a thread (kept)."""
    lines: list[str] = []
    while "live view on ws://127.0.0.1:" not in (line := stderr.readline()):
        assert line, "the daemon ended before its live view started"
        lines.append(line)
    threading.Thread(target=lambda: lines.extend(iter(stderr.readline, "")), daemon=True).start()
    return int(line.split("ws://127.0.0.1:")[1].split()[0]), lines


def _read_everything(port: int, got: dict[str, int]) -> None:
    """A viewer as Foxglove is one (the older subprotocol name): every channel, read until the end."""
    got.update(messages=0, bytes=0, config=0)
    with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.websocket.v1"], open_timeout=10,
                 max_size=None) as ws:
        topics: dict[int, str] = {}
        while True:
            try:
                m = ws.recv(timeout=10)
            except (TimeoutError, WebSocketException, OSError):
                return
            if isinstance(m, str):
                msg = json.loads(m)
                chans = msg.get("channels", []) if msg["op"] == "advertise" else []
                subs = [{"id": len(topics) + i, "channelId": c["id"]} for i, c in enumerate(chans)]
                topics.update({s["id"]: c["topic"] for s, c in zip(subs, chans, strict=True)})
                ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            else:
                got["messages"] += 1
                got["bytes"] += len(m)
                if topics.get(int.from_bytes(m[1:5], "little")) == "/vipsm/config":
                    got["config"] += 1



def test_viewers_that_vanish_mid_stream_cost_no_line_per_message(caplog: pytest.LogCaptureFixture) -> None:
    ctx = foxglove.Context()
    big = _big_channel(ctx)
    lines: list[str] = []
    live = LiveView(ctx, "127.0.0.1", 0, on_event=lambda level, msg: lines.append(msg)).start()
    try:
        big.log(b'"warm"')
        clients = []
        for _ in range(6):
            s, rest = _raw_upgrade(live.port, rcvbuf=4096)
            _subscribe_raw(s, rest, "/big")
            clients.append(s)
        blob = json.dumps("v" * 5000).encode()
        for i in range(400):
            big.log(blob)
            if i == 100:
                for s in clients:  # reset, not closed: the front's writes to them fail
                    s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                    s.close()
            time.sleep(0.002)
        assert _wait(lambda: live.summary()["clients"] == 0)
    finally:
        live.stop()
    assert not [r for r in caplog.records if r.name == "asyncio"]
    assert len(lines) <= LineBudget(print).lines["client"] + 1


def test_a_gone_sdk_server_is_restarted_and_said_so() -> None:
    """The SDK's listener can end (as it did after file descriptors ran out): the next viewer finds
    it refused, the front starts a new one and says so; later viewers are served."""
    lines: list[str] = []
    live = LiveView(foxglove.Context(), "127.0.0.1", 0, on_event=lambda level, msg: lines.append(msg)).start()
    try:
        live._backend._server.stop()  # the listener gone, its port refusing
        with pytest.raises(InvalidStatus) as info:
            connect(live.url, subprotocols=[SDK], open_timeout=10)
        assert info.value.response.status_code == 503
        assert _wait(lambda: _serves(live.port), 20.0)
        s = live.summary()
        assert s["backend_restarts"] == 1 and s["state"] == "ok" and "refused" in s["last_failure"]
        assert any("SDK server failed (connection refused); restarting it" in m for m in lines)
    finally:
        live.stop()


class _StuckThenServing(Backend):
    """An SDK server that accepts but never answers, until it is restarted."""

    def __init__(self, real: _SdkServer) -> None:
        self.real, self.stuck = real, True
        self.silent = socket.create_server(("127.0.0.1", 0))

    def port(self) -> int:
        return self.silent.getsockname()[1] if self.stuck else self.real.port()

    def restart(self) -> None:
        self.stuck = False


def test_an_sdk_server_that_stops_answering_is_restarted_after_three_viewers_found_it_so() -> None:
    real = _SdkServer(foxglove.Context())
    real.start()
    backend = _StuckThenServing(real)
    reports: list[tuple[str, str]] = []
    front = LiveFront("127.0.0.1", 0, backend, FrontLimits(handshake_timeout_s=0.5),
                      lambda kind, level, msg: reports.append((kind, msg)), lambda topic: None).start()
    try:
        url = f"ws://127.0.0.1:{front.port}"
        for _ in range(3):  # once or twice may be a busy machine: no restart
            with pytest.raises(InvalidStatus) as info:
                connect(url, subprotocols=[SDK], open_timeout=10)
            assert info.value.response.status_code == 503
        assert _wait(lambda: front.stats.backend_restarts == 1) and front.stats.backend_errors == 3
        assert [m for k, m in reports if k == "state"] == [
            "live view: the SDK server failed (no handshake answer (timed out)); restarting it"]
        assert _serves(front.port)
    finally:
        front.stop()
        real.stop(1.0)
        backend.silent.close()
