"""The fake UTM-30LX: its state, the time stamp counter, the byte stream in and out, and the fault
hooks. The command set is :class:`~hil_fakes.utm30lx.commands.ScipCommands`, the mirror and the scan
replies :class:`~hil_fakes.utm30lx.sweep.MirrorSweep`; the configuration and state records are in
``hil_fakes.utm30lx.config``."""

from __future__ import annotations

import math
import threading
from collections import deque

import numpy as np

from ..transport import DeviceModel
from .commands import ScipCommands
from .config import _SWEEP_PARTS, Utm30lxConfig, _PendingSingle, _Stream
from .protocol import status_line
from .source import _MASK24, FixedRoom, RangeSource
from .sweep import MirrorSweep


class Utm30lxModel(ScipCommands, MirrorSweep, DeviceModel):
    """The UTM-30LX state machine; serve it with :func:`serve_pty` / :func:`serve_tcp` or a DeviceServer."""

    def __init__(self, config: Utm30lxConfig | None = None, source: RangeSource | None = None) -> None:
        super().__init__()
        self.config = config or Utm30lxConfig()
        self.source: RangeSource = source or FixedRoom()
        cfg = self.config
        self._lock = threading.RLock()
        self._inbuf = bytearray()
        self._boot_s: float | None = None
        self._clock_base_ms = cfg.initial_time_ms
        self._laser_on = cfg.laser_on_at_start
        self._time_mode = False
        self._stream: _Stream | None = None
        self._singles: list[_PendingSingle] = []
        self._next_scan = 0  # index of the next scan whose sweep has not been processed
        self._scan_cache: tuple[int, np.ndarray, np.ndarray] | None = None
        self._parts: tuple[int, list[tuple[np.ndarray, np.ndarray]]] | None = None  # scan k, measured parts
        self._out: deque[tuple[float, bytes]] = deque()
        self._link_free_s = -math.inf  # when the link has sent everything queued so far
        self._rb_armed_at: float | None = None
        self._status_faults: dict[str, deque[str]] = {}
        self._frame_status_faults: deque[str] = deque()
        self._checksum_faults: deque[str] = deque()
        self._silent_ack = False
        n = cfg.amax + 1
        self._all_angles = (np.arange(n, dtype=np.float64) - cfg.afrt) * (2.0 * math.pi / cfg.ares)
        self._part_edges = [round(j * n / _SWEEP_PARTS) for j in range(_SWEEP_PARTS + 1)]
        #: what the fake did, for tests
        self.frames_sent = 0
        self.scans_late = 0
        self.commands_seen: list[str] = []

    # ---------------------------------------------------------------- clock

    def _ensure_boot(self, now_s: float) -> None:
        if self._boot_s is None:
            self._boot_s = now_s
            self._next_scan = 0

    def device_ms(self, now_s: float) -> int:
        """The 24-bit counter at host time ``now_s``."""
        self._ensure_boot(now_s)
        assert self._boot_s is not None
        return (self._clock_base_ms + self._elapsed_ms(now_s)) & _MASK24

    def _elapsed_ms(self, now_s: float) -> int:
        """Whole device milliseconds since boot (the counter runs at 1 + drift against the host)."""
        assert self._boot_s is not None
        rate = 1.0 + self.config.clock_drift_ppm * 1e-6
        return int(math.floor((now_s - self._boot_s) * 1000.0 * rate + 1e-6))

    def host_time_of_device_ms(self, device_ms: int) -> float:
        """The host-clock time at which the counter showed ``device_ms`` (ground truth for tests)."""
        with self._lock:
            if self._boot_s is None:
                raise RuntimeError("the fake has not started its clock yet")
            delta = (device_ms - self._clock_base_ms) & _MASK24
            return self._boot_s + delta / 1000.0 / (1.0 + self.config.clock_drift_ppm * 1e-6)

    def _scan_start_s(self, k: int) -> float:
        assert self._boot_s is not None
        return self._boot_s + k * self.config.scan_period_s

    def _scan_done_s(self, k: int) -> float:
        return self._scan_start_s(k) + (self.config.amax + 1) * self.config.step_dt_s

    def _scan_index_after(self, now_s: float) -> int:
        """The first scan whose step 0 is not before ``now_s``."""
        assert self._boot_s is not None
        return max(self._next_scan, math.ceil((now_s - self._boot_s) / self.config.scan_period_s - 1e-9))

    # ---------------------------------------------------------------- DeviceModel

    def on_bytes(self, data: bytes, now_s: float) -> None:
        with self._lock:
            self._ensure_boot(now_s)
            self._inbuf += data
            while True:
                cut = -1
                for i, b in enumerate(self._inbuf):
                    if b in (0x0A, 0x0D):
                        cut = i
                        break
                if cut < 0:
                    break
                line = bytes(self._inbuf[:cut])
                del self._inbuf[: cut + 1]
                if line:  # an empty line (bare LF, or the LF of a CR+LF) is ignored [?]
                    self._handle(line, now_s)
            if len(self._inbuf) > 4096:  # no terminator in sight: a real command buffer would overflow
                self._inbuf.clear()
            self._flush(now_s)

    def poll(self, now_s: float) -> float | None:
        with self._lock:
            self._ensure_boot(now_s)
            self._advance(now_s)
            part_due = self._measure_due_parts(now_s)
            self._flush(now_s)
            nxt = self._scan_done_s(self._next_scan)
            if part_due is not None:
                nxt = min(nxt, part_due)
            if self._out:
                nxt = min(nxt, self._out[0][0])
            return nxt

    # ---------------------------------------------------------------- fault hooks

    def inject_status(self, command: str, code: str, times: int = 1) -> None:
        """The next ``times`` requests of ``command`` (``"BM"``, ``"MD"``, ``"TM"``...) get ``code``, no effect."""
        with self._lock:
            self._status_faults.setdefault(command, deque()).extend([code] * times)

    def inject_frame_status(self, code: str, frames: int = 1) -> None:
        """The next ``frames`` stream frames go out as echo + ``code`` + empty line (no data)."""
        with self._lock:
            self._frame_status_faults.extend([code] * frames)

    def inject_checksum_error(self, where: str = "data", frames: int = 1) -> None:
        """The next ``frames`` scan replies carry a wrong sum on the ``status``, ``timestamp`` or ``data`` line."""
        if where not in ("status", "timestamp", "data"):
            raise ValueError(f"where must be status, timestamp or data, not {where!r}")
        with self._lock:
            self._checksum_faults.extend([where] * frames)

    def leave_streaming(self, request: str = "MD0000108001000", now_s: float | None = None) -> None:
        """Start a stream as a previous client would have (its acknowledgement went to that client)."""
        with self._lock:
            if now_s is not None:
                self._ensure_boot(now_s)
            self._silent_ack = True
            try:
                self._handle(request.encode("ascii"), now_s if now_s is not None else (self._boot_s or 0.0))
            finally:
                self._silent_ack = False

    def enter_time_mode(self) -> None:
        """Leave the fake in time-adjust mode, as a client that died after TM0 would."""
        with self._lock:
            self._time_mode = True
            self._laser_on = False
            self._stream = None

    def power_cycle(self, now_s: float) -> None:
        """Clock back to 0, laser off, streams and TM mode gone (a reboot)."""
        with self._lock:
            self._ensure_boot(now_s)
            self._reset_clock(now_s)
            self._laser_on = False
            self._stream = None
            self._singles.clear()
            self._time_mode = False

    @property
    def streaming(self) -> bool:
        with self._lock:
            return self._stream is not None

    @property
    def laser_on(self) -> bool:
        with self._lock:
            return self._laser_on

    @property
    def time_mode(self) -> bool:
        with self._lock:
            return self._time_mode

    # ---------------------------------------------------------------- output

    def _send(self, data: bytes, now_s: float, latency_s: float | None = None) -> None:
        delay = self.config.reply_latency_s if latency_s is None else latency_s
        rate = self.config.link_bytes_per_s
        if rate <= 0.0:
            self._out.append((now_s + delay, data))
            return
        # the host has a message when its last byte has crossed the link, after everything queued before it
        self._link_free_s = max(now_s + delay, self._link_free_s) + len(data) / rate
        self._out.append((self._link_free_s, data))

    def _flush(self, now_s: float) -> None:
        while self._out and self._out[0][0] <= now_s:
            _, data = self._out.popleft()
            self.emit(data)

    def _reply(self, echo: bytes, code: str, now_s: float, payload: bytes = b"") -> None:
        self._send(echo + b"\n" + status_line(code) + payload + b"\n", now_s)
