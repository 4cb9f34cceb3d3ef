"""The fake UTM-30LX: the SCIP 2.0 command state machine, streaming, the time stamp counter and faults."""

from __future__ import annotations

import math
import threading
from collections import deque
from dataclasses import dataclass

import numpy as np

from ..transport import DeviceModel
from .protocol import data_block, encode, info_line, scip_sum, status_line, time_line
from .source import _MASK24, FixedRoom, RangeSource

# --------------------------------------------------------------------------------------------
# The device
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Utm30lxConfig:
    """Identity, parameters and unverified behaviour of the fake ([?] = not verified on hardware)."""

    vendor: str = "Hokuyo Automatic Co.,Ltd."
    product: str = "SOKUIKI Sensor TOP-URG UTM-30LX"
    firmware: str = "P.1.05(17/Apr./2009)"
    protocol: str = "SCIP 2.0"
    serial: str = "00903971"
    model: str = "UTM-30LX(Hokuyo Automatic Co.,Ltd.)"
    dmin_mm: int = 23
    dmax_mm: int = 60000
    ares: int = 1440
    amin: int = 0
    amax: int = 1080
    afrt: int = 540
    scan_rpm: int = 2400
    motor_speed_text: str = "Initial(2400[rpm])<-Default setting by user"
    measurement_mode: str = "CLASSIC"
    bit_rate_text: str = "USB Full Speed"
    status_text: str = "Sensor works well."
    #: the 24-bit ms counter at the moment the model first sees its clock (the recording's first II: 4821456)
    initial_time_ms: int = 4821456
    #: the recorded sensor had its laser on when the session began (BM answered 02) [? after power-up]
    laser_on_at_start: bool = True
    #: delay before a command's reply goes out (the real one answered after 3-25 ms) [?]
    reply_latency_s: float = 0.0
    #: status for any command other than TM while in time-adjust mode [?: urg_library expects 0E]
    time_mode_refusal: str = "0E"
    #: HS answer; "not supported on all UTM-30LX versions" [?]
    hs_status: str = "03"
    #: status for a known command with the wrong number of parameter characters [?: 0C or 0F]
    missing_parameter_status: str = "0C"
    #: some older firmware summed the II SCSP line only up to '<-' (P.1.05 sums all of it) [PEER]
    ii_sum_before_arrow: bool = False
    #: the sensor's ms counter runs this much fast (+) or slow (-) against the host clock
    clock_drift_ppm: float = 0.0
    #: bytes per second the link carries to the host: a message reaches the host when its last byte
    #: has crossed, after the ones queued before it (0: at once). USB Full Speed CDC-ACM: the recorded
    #: session's 6717-byte ME frame came in runs of 0.84-0.85 MB/s (theoretical bulk maximum 1.216
    #: MB/s) [DEV: one session; a host controller or hub may differ]; a 1081-step MD frame (3.4 kB)
    #: takes about 4 ms
    link_bytes_per_s: float = 840_000.0

    @property
    def scan_period_s(self) -> float:
        return 60.0 / self.scan_rpm

    @property
    def step_dt_s(self) -> float:
        return self.scan_period_s / self.ares


@dataclass
class _Stream:
    command: str  # MD / MS / ME
    params_prefix: str  # start+end+cluster+interval (11 chars)
    start: int
    end: int
    cluster: int
    interval: int
    count: int  # 0 = until QT
    remaining: int
    tag: str
    first_scan: int
    sent: int = 0


@dataclass
class _PendingSingle:
    echo: bytes
    command: str
    start: int
    end: int
    cluster: int
    not_before_scan: int


_SS_RATES = frozenset({"019200", "038400", "057600", "115200", "250000", "500000", "750000"})


_TAG_CHARS = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789 ._+@")


_MAX_CATCH_UP_SCANS = 8

#: a sweep is measured in this many parts, each as soon as its beams' times have passed, so a sweep's
#: data are ready when it ends, as on the sensor, instead of being computed all at once then
_SWEEP_PARTS = 8


class Utm30lxModel(DeviceModel):
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

    # ---------------------------------------------------------------- commands

    def _handle(self, line: bytes, now_s: float) -> None:
        echo = line
        try:
            text = line.decode("ascii")
        except UnicodeDecodeError:
            self._reply(echo, "0E", now_s)
            return
        self.commands_seen.append(text)
        body, sep, tag = text.partition(";")
        cmd = body[:3] if body.startswith("%") else body[:2]
        params = body[len(cmd) :]
        if sep:
            if len(tag) > 16:
                self._reply(echo, "0G", now_s)
                return
            if any(ch not in _TAG_CHARS for ch in tag):
                self._reply(echo, "0H", now_s)
                return
        faults = self._status_faults.get(cmd)
        if faults:
            self._reply(echo, faults.popleft(), now_s)
            return
        if self._time_mode and cmd != "TM":
            self._reply(echo, self.config.time_mode_refusal, now_s)
            return
        handler = {
            "VV": self._cmd_vv,
            "PP": self._cmd_pp,
            "II": self._cmd_ii,
            "BM": self._cmd_bm,
            "QT": self._cmd_qt,
            "RS": self._cmd_rs,
            "RT": self._cmd_rs,
            "RB": self._cmd_rb,
            "TM": self._cmd_tm,
            "SS": self._cmd_ss,
            "CR": self._cmd_cr,
            "HS": self._cmd_hs,
            "MD": self._cmd_stream,
            "MS": self._cmd_stream,
            "ME": self._cmd_stream,
            "GD": self._cmd_single,
            "GS": self._cmd_single,
            "GE": self._cmd_single,
        }.get(cmd)
        if handler is None:
            self._reply(echo, "0E", now_s)
            return
        handler(echo, cmd, params, tag, now_s)

    def _no_params(self, echo: bytes, params: str, now_s: float) -> bool:
        if params:
            self._reply(echo, self.config.missing_parameter_status, now_s)
            return False
        return True

    def _cmd_vv(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        if self._no_params(echo, params, now_s):
            c = self.config
            payload = b"".join(
                info_line(k, v)
                for k, v in (
                    ("VEND", c.vendor),
                    ("PROD", c.product),
                    ("FIRM", c.firmware),
                    ("PROT", c.protocol),
                    ("SERI", c.serial),
                )
            )
            self._reply(echo, "00", now_s, payload)

    def _cmd_pp(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        if self._no_params(echo, params, now_s):
            c = self.config
            rows = (
                ("MODL", c.model),
                ("DMIN", str(c.dmin_mm)),
                ("DMAX", str(c.dmax_mm)),
                ("ARES", str(c.ares)),
                ("AMIN", str(c.amin)),
                ("AMAX", str(c.amax)),
                ("AFRT", str(c.afrt)),
                ("SCAN", str(c.scan_rpm)),
            )
            self._reply(echo, "00", now_s, b"".join(info_line(k, v) for k, v in rows))

    def _cmd_ii(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        if self._no_params(echo, params, now_s):
            c = self.config
            rows = (
                ("MODL", c.model),
                ("LASR", "ON" if self._laser_on else "OFF"),
                ("SCSP", c.motor_speed_text),
                ("MESM", c.measurement_mode),
                ("SBPS", c.bit_rate_text),
                ("TIME", f"{self.device_ms(now_s):06X}"),
                ("STAT", c.status_text),
            )
            lines = []
            for k, v in rows:
                line = info_line(k, v)
                if c.ii_sum_before_arrow and "<-" in v:
                    content = f"{k}:{v}".encode("ascii")
                    line = content + b";" + scip_sum(content[: content.index(b"<-")]) + b"\n"
                lines.append(line)
            self._reply(echo, "00", now_s, b"".join(lines))

    def _cmd_bm(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        if self._no_params(echo, params, now_s):
            code = "02" if self._laser_on else "00"
            self._laser_on = True
            self._reply(echo, code, now_s)

    def _stop_measuring(self) -> None:
        self._stream = None
        self._singles.clear()
        self._laser_on = False

    def _cmd_qt(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        if self._no_params(echo, params, now_s):
            self._stop_measuring()
            self._reply(echo, "00", now_s)

    def _reset_clock(self, now_s: float) -> None:
        """The counter restarts at 0 now; the mirror keeps its phase."""
        self._clock_base_ms = -self._elapsed_ms(now_s)

    def _cmd_rs(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        if self._no_params(echo, params, now_s):
            self._stop_measuring()
            self._reset_clock(now_s)
            self._reply(echo, "00", now_s)

    def _cmd_rb(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        # First RB arms (01); a second within 1 s reboots (00). The link does not drop here [?].
        if not self._no_params(echo, params, now_s):
            return
        if self._rb_armed_at is not None and now_s - self._rb_armed_at <= 1.0:
            self._rb_armed_at = None
            self._reply(echo, "00", now_s)
            self._stop_measuring()
            self._time_mode = False
            self._reset_clock(now_s)
        else:
            self._rb_armed_at = now_s
            self._reply(echo, "01", now_s)

    def _cmd_tm(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        if len(params) != 1:
            self._reply(echo, self.config.missing_parameter_status, now_s)
        elif params == "0":
            if self._time_mode:
                self._reply(echo, "02", now_s)
            else:
                self._stop_measuring()
                self._time_mode = True
                self._reply(echo, "00", now_s)
        elif params == "1":
            if self._time_mode:
                self._reply(echo, "00", now_s, time_line(self.device_ms(now_s)))
            else:
                self._reply(echo, "04", now_s)
        elif params == "2":
            if self._time_mode:
                self._time_mode = False
                self._reply(echo, "00", now_s)
            else:
                self._reply(echo, "03", now_s)
        else:
            self._reply(echo, "01", now_s)

    def _cmd_ss(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        if len(params) != 6:
            self._reply(echo, self.config.missing_parameter_status, now_s)
        elif not params.isdigit():
            self._reply(echo, "01", now_s)
        elif params not in _SS_RATES:
            self._reply(echo, "02", now_s)
        else:
            self._reply(echo, "00", now_s)  # accepted, no effect over USB [SPEC]

    def _cmd_cr(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        if len(params) != 2:
            self._reply(echo, self.config.missing_parameter_status, now_s)
        else:
            self._reply(echo, "04", now_s)  # the real UTM-30LX answered CR00 with 04 [DEV]

    def _cmd_hs(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        if len(params) != 1:
            self._reply(echo, self.config.missing_parameter_status, now_s)
        elif params not in ("0", "1"):
            self._reply(echo, "01", now_s)
        else:
            self._reply(echo, self.config.hs_status, now_s)

    def _check_scan_params(self, fields: list[tuple[str, str]]) -> str | None:
        """SCIP error status for the first bad field, or the range checks; None when valid."""
        for code, value in fields:
            if not value.isdigit():
                return code
        start, end = int(fields[0][1]), int(fields[1][1])
        if end > self.config.amax or start > self.config.amax or start < self.config.amin:
            return "04"
        if end < start:
            return "05"
        return None

    def _cmd_stream(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        if len(params) != 13:
            self._reply(echo, self.config.missing_parameter_status, now_s)
            return
        fields = [
            ("01", params[0:4]),
            ("02", params[4:8]),
            ("03", params[8:10]),
            ("06", params[10:11]),
            ("07", params[11:13]),
        ]
        error = self._check_scan_params(fields)
        if error is not None:
            self._reply(echo, error, now_s)
            return
        count = int(params[11:13])
        # A second MD while streaming replaces the first [?: urg_library leaves this case as a TODO].
        self._stream = _Stream(
            command=cmd,
            params_prefix=params[:11],
            start=int(params[0:4]),
            end=int(params[4:8]),
            cluster=int(params[8:10]),
            interval=int(params[10:11]),
            count=count,
            remaining=count,
            tag=tag,
            first_scan=self._scan_index_after(now_s),
        )
        self._laser_on = True
        if not self._silent_ack:
            self._reply(echo, "00", now_s)

    def _cmd_single(self, echo: bytes, cmd: str, params: str, tag: str, now_s: float) -> None:
        if len(params) != 10:
            self._reply(echo, self.config.missing_parameter_status, now_s)
            return
        error = self._check_scan_params([("01", params[0:4]), ("02", params[4:8]), ("03", params[8:10])])
        if error is not None:
            self._reply(echo, error, now_s)
            return
        if not self._laser_on:
            self._reply(echo, "10", now_s)
            return
        # The reply carries the first scan that starts after the request (so a scan taken with the laser
        # just switched on, or after RS restarted the clock): it goes out 19-44 ms later.
        first = self._scan_index_after(now_s)
        self._singles.append(_PendingSingle(echo, cmd, int(params[0:4]), int(params[4:8]), int(params[8:10]), first))

    # ---------------------------------------------------------------- scanning

    def _advance(self, now_s: float) -> None:
        """Complete every scan whose sweep ended by ``now_s`` (skipping far-behind ones)."""
        assert self._boot_s is not None
        period = self.config.scan_period_s
        behind = int((now_s - self._scan_done_s(self._next_scan)) // period) + 1
        if behind > _MAX_CATCH_UP_SCANS:
            self._next_scan += behind - _MAX_CATCH_UP_SCANS
        while self._scan_done_s(self._next_scan) <= now_s:
            k = self._next_scan
            self._next_scan += 1
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
