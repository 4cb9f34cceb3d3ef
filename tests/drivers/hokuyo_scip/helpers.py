"""Shared helpers for the UTM-30LX driver tests: recorded sessions, fake servers, client configs."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from drivers.hokuyo_scip.client import ClientConfig
from hil_fakes.transport import DeviceServer, PtyEndpoint, TcpEndpoint
from hil_fakes.utm30lx import FixedRoom, Utm30lxConfig, Utm30lxModel

SESSION_DIR = "hokuyo_utm30lx_session"


def load_session(shared_data: Path, name: str) -> list[tuple[float, str, bytes]]:
    """(t_s, direction, payload) records of a recorded session, in time order."""
    path = shared_data / SESSION_DIR / f"{name}.jsonl"
    records = []
    with path.open(encoding="utf-8") as fh:
        for line in fh:
            obj = json.loads(line)
            records.append((float(obj["t_s"]), obj["dir"], bytes.fromhex(obj["hex"])))
    return records


def sensor_bytes(records: list[tuple[float, str, bytes]]) -> bytes:
    return b"".join(p for _, d, p in records if d == "sensor_to_host")


def host_bytes(records: list[tuple[float, str, bytes]]) -> bytes:
    return b"".join(p for _, d, p in records if d == "host_to_sensor")


def fast_config(**overrides: object) -> ClientConfig:
    """Short silence windows and backoff so fault tests finish quickly; reply timeouts stay generous."""
    base: dict[str, object] = {
        "reply_timeout_s": 2.0,
        "frame_timeout_s": 0.2,
        "silent_windows_before_reconnect": 4,
        "backoff_initial_s": 0.05,
        "backoff_max_s": 0.4,
        "time_sync_rounds": 3,
        "buffer_capacity": 8,
    }
    base.update(overrides)
    return ClientConfig(**base)  # type: ignore[arg-type]


def start_fake(transport: str, tmp_path: Path, model: Utm30lxModel | None = None) -> DeviceServer:
    model = model or Utm30lxModel(Utm30lxConfig())
    endpoint = PtyEndpoint(str(tmp_path / "hokuyo")) if transport == "pty" else TcpEndpoint()
    return DeviceServer(model, endpoint).start()


def room_truth_mm(model: Utm30lxModel) -> np.ndarray:
    """The device values the fake's default room gives for every step (the fake is deterministic)."""
    cfg = model.config
    angles = (np.arange(cfg.amin, cfg.amax + 1) - cfg.afrt) * (2 * np.pi / cfg.ares)
    ranges, _ = FixedRoom().sweep(0.0, angles, cfg.step_dt_s)
    return np.round(ranges * 1000.0).astype(np.int64)


def wait_until(predicate: Callable[[], bool], timeout_s: float, poll_s: float = 0.01) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(poll_s)
    return predicate()
