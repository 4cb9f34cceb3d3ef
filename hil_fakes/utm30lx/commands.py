"""The fake UTM-30LX's SCIP 2.0 command set: a request line parsed and answered (statuses, info
lines, the time-adjust mode, starting streams and single scans). A mixin of :class:`Utm30lxModel`,
which holds the state and the output these handlers use."""

from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING

from .config import _SS_RATES, _TAG_CHARS, Utm30lxConfig, _PendingSingle, _Stream
from .protocol import info_line, scip_sum, time_line

if TYPE_CHECKING:
    from collections.abc import Callable


class ScipCommands:
    """Each command's reply; the state it changes belongs to the model."""

    config: Utm30lxConfig
    commands_seen: list[str]
    _status_faults: dict[str, deque[str]]
    _time_mode: bool
    _laser_on: bool
    _stream: _Stream | None
    _singles: list[_PendingSingle]
    _rb_armed_at: float | None
    _clock_base_ms: int
    _silent_ack: bool
    _reply: Callable[..., None]
    device_ms: Callable[[float], int]
    _elapsed_ms: Callable[[float], int]
    _scan_index_after: Callable[[float], int]


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
