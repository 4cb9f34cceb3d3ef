"""The live view: every field-log channel reaches a WebSocket client that subscribes (Foxglove's
protocol, a test client on loopback); addresses are parsed and a remote one is refused by default."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
from websockets.sync.client import connect

from app import logmessages as lm
from app.errors import ConfigError
from app.fieldlog import FieldLog
from app.liveview import LiveView, check_exposure, layout_path, parse_listen
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
                                            ("[::1]:8765", ("::1", 8765)), ("localhost:1", ("localhost", 1))])
def test_listen_addresses(spec: str, want: tuple[str, int]) -> None:
    assert parse_listen(spec) == want


@pytest.mark.parametrize("spec", ["", "abc", "1:99999", ":80x", "-1"])
def test_bad_listen_addresses_are_config_errors(spec: str) -> None:
    with pytest.raises(ConfigError, match="live.listen"):
        parse_listen(spec)


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
