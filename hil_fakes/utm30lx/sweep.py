"""The fake UTM-30LX's mirror: which scans are measured and when (in parts, as their beams are
taken), their device values, and the scan replies sent to a stream or a single request when a sweep
ends. A mixin of :class:`Utm30lxModel`, which holds the clock, the range source and the output."""

from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING

import numpy as np

from .config import _MAX_CATCH_UP_SCANS, _SWEEP_PARTS, Utm30lxConfig, _PendingSingle, _Stream
from .protocol import data_block, encode, status_line, time_line
from .source import RangeSource

if TYPE_CHECKING:
    from collections.abc import Callable


class MirrorSweep:
    """Scans measured on the model's clock and sent when their sweep is complete."""

    config: Utm30lxConfig
    source: RangeSource
    frames_sent: int
    #: scans a stream wanted that were completed more than a period after their sweep ended, or skipped:
    #: the model's clock ran while its thread could not (a host too busy for a real-time fake), no device fault
    scans_late: int
    _boot_s: float | None
    _next_scan: int
    _laser_on: bool
    _stream: _Stream | None
    _singles: list[_PendingSingle]
    _scan_cache: tuple[int, np.ndarray, np.ndarray] | None
    _parts: tuple[int, list[tuple[np.ndarray, np.ndarray]]] | None
    _part_edges: list[int]
    _all_angles: np.ndarray
    _checksum_faults: deque[str]
    _frame_status_faults: deque[str]
    _send: Callable[..., None]
    device_ms: Callable[[float], int]
    _scan_start_s: Callable[[int], float]
    _scan_done_s: Callable[[int], float]


    def _advance(self, now_s: float) -> None:
        """Complete every scan whose sweep ended by ``now_s`` (skipping far-behind ones)."""
        assert self._boot_s is not None
        period = self.config.scan_period_s
        behind = int((now_s - self._scan_done_s(self._next_scan)) // period) + 1
        if behind > _MAX_CATCH_UP_SCANS:
            skipped = range(self._next_scan, self._next_scan + behind - _MAX_CATCH_UP_SCANS)
            self._next_scan = skipped.stop
            self.scans_late += sum(map(self._stream_wants, skipped))
        while self._scan_done_s(self._next_scan) <= now_s:
            k = self._next_scan
            self._next_scan += 1
            if now_s - self._scan_done_s(k) > period and self._stream_wants(k):
                self.scans_late += 1
            self._complete_scan(k, self._scan_done_s(k))  # on the link from the sweep's end

    def _wanted(self, k: int) -> bool:
        """Scan ``k`` will be sent (to a stream or a pending single request)."""
        return self._laser_on and (self._stream_wants(k) or any(k >= s.not_before_scan for s in self._singles))

    def _stream_wants(self, k: int) -> bool:
        st = self._stream
        return st is not None and k >= st.first_scan and (k - st.first_scan) % (st.interval + 1) == 0

    def _part_end_s(self, k: int, j: int) -> float:
        """When the last beam of part ``j`` of scan ``k`` has been taken."""
        return self._scan_start_s(k) + self._part_edges[j + 1] * self.config.step_dt_s

    def _parts_of(self, k: int) -> list[tuple[np.ndarray, np.ndarray]]:
        if self._parts is None or self._parts[0] != k:
            self._parts = (k, [])
        return self._parts[1]

    def _measure_part(self, k: int, j: int) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = self._part_edges[j], self._part_edges[j + 1]
        dt = self.config.step_dt_s
        ranges_m, intensity = self.source.sweep(self._scan_start_s(k) + lo * dt, self._all_angles[lo:hi], dt)
        return np.asarray(ranges_m, dtype=np.float64), np.asarray(intensity, dtype=np.float64)

    def _measure_due_parts(self, now_s: float) -> float | None:
        """Measure the parts of the next scan (if it will be sent) whose beams were taken by ``now_s``;
        return when the next part is due (None: nothing to measure)."""
        k = self._next_scan
        if not self._wanted(k):
            return None
        parts = self._parts_of(k)
        while len(parts) < _SWEEP_PARTS and self._part_end_s(k, len(parts)) <= now_s:
            parts.append(self._measure_part(k, len(parts)))
        return self._part_end_s(k, len(parts)) if len(parts) < _SWEEP_PARTS else None

    def _sweep(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Device values (mm codes) and intensities of every step 0..AMAX of scan ``k`` (cached)."""
        if self._scan_cache is not None and self._scan_cache[0] == k:
            return self._scan_cache[1], self._scan_cache[2]
        cfg = self.config
        parts = self._parts_of(k)
        while len(parts) < _SWEEP_PARTS:
            parts.append(self._measure_part(k, len(parts)))
        self._parts = None
        ranges_m = np.concatenate([p[0] for p in parts])
        intensity = np.concatenate([p[1] for p in parts])
        mm = np.round(np.nan_to_num(ranges_m, nan=-1.0) * 1000.0)
        codes = np.where(np.isnan(ranges_m) | (mm > cfg.dmax_mm), 1, np.where(mm < cfg.dmin_mm, 2, mm))
        codes = codes.astype(np.int64)
        codes[: cfg.amin] = 1
        inten = np.clip(np.round(np.nan_to_num(np.asarray(intensity, dtype=np.float64))), 0, (1 << 18) - 1)
        self._scan_cache = (k, codes, inten.astype(np.int64))
        return codes, self._scan_cache[2]

    def _window(self, k: int, start: int, end: int, cluster: int, with_intensity: bool) -> bytes:
        codes, inten = self._sweep(k)
        c = max(cluster, 1)
        d = codes[start : end + 1]
        i = inten[start : end + 1]
        if c > 1:
            n = -(-d.size // c)
            pad = n * c - d.size
            big = np.iinfo(np.int64).max
            valid = np.where(d >= self.config.dmin_mm, d, big)
            grouped = np.concatenate([valid, np.full(pad, big)]).reshape(n, c).min(axis=1)
            first_codes = np.concatenate([d, np.full(pad, 1)]).reshape(n, c)[:, 0]
            d = np.where(grouped == big, first_codes, grouped)  # nearest valid echo, else the error code
            i = np.concatenate([i, np.zeros(pad, dtype=np.int64)]).reshape(n, c).max(axis=1)
        if with_intensity:
            pairs = np.stack([d, i], axis=1).reshape(-1)
            return encode(pairs, 3)
        return encode(d, 3)

    def _scan_payload(self, k: int, start: int, end: int, cluster: int, command: str, echo: bytes, code: str) -> bytes:
        if command in ("MS", "GS"):
            codes, _ = self._sweep(k)
            c = max(cluster, 1)
            d = codes[start : end + 1][::c]
            chars = encode(np.minimum(d, 4095), 2)  # what the sensor sends above 4095 mm is unknown [?]
        else:
            chars = self._window(k, start, end, cluster, command in ("ME", "GE"))
        fault = self._checksum_faults.popleft() if self._checksum_faults else None
        ts = self.device_ms(self._scan_start_s(k))  # computed once; characters and sum both from it
        status = status_line(code)
        tline = time_line(ts)
        block = data_block(chars)
        if fault == "status":
            status = status[:2] + bytes([((status[2] - 0x30 + 1) & 0x3F) + 0x30]) + b"\n"
        elif fault == "timestamp":
            tline = tline[:4] + bytes([((tline[4] - 0x30 + 1) & 0x3F) + 0x30]) + b"\n"
        elif fault == "data":
            pos = block.index(b"\n") - 1
            block = block[:pos] + bytes([((block[pos] - 0x30 + 1) & 0x3F) + 0x30]) + block[pos + 1 :]
        return echo + b"\n" + status + tline + block + b"\n"

    def _complete_scan(self, k: int, done_s: float) -> None:
        if not self._laser_on:
            return
        if self._singles:
            ready = [s for s in self._singles if k >= s.not_before_scan]
            self._singles = [s for s in self._singles if k < s.not_before_scan]
            for s in ready:
                self._send(self._scan_payload(k, s.start, s.end, s.cluster, s.command, s.echo, "00"), done_s, 0.0)
                self.frames_sent += 1
        st = self._stream
        if st is None or not self._stream_wants(k):
            return
        if st.count:
            st.remaining -= 1
            remaining = st.remaining
        else:
            remaining = 0
        echo_text = f"{st.command}{st.params_prefix}{remaining:02d}" + (f";{st.tag}" if st.tag else "")
        echo = echo_text.encode("ascii")
        if self._frame_status_faults:
            self._send(echo + b"\n" + status_line(self._frame_status_faults.popleft()) + b"\n", done_s, 0.0)
        else:
            self._send(self._scan_payload(k, st.start, st.end, st.cluster, st.command, echo, "99"), done_s, 0.0)
            self.frames_sent += 1
        st.sent += 1
        if st.count and st.remaining <= 0:
            self._stream = None
            self._laser_on = False  # the laser goes off after the last scan of a finite run [SPEC]
