"""The fake SNC-RZ50's VISCA side: command parsing, sockets, replies and faults (independent of
drivers/ptz_cam)."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

from ..transport import DeviceModel
from .mechanics import CameraState


def _signed(nibs: bytes) -> int:
    v = 0
    for b in nibs:
        v = (v << 4) | b
    bits = 4 * len(nibs)
    return v - (1 << bits) if v >= 1 << (bits - 1) else v


def _nibs(value: int, count: int) -> bytes:
    value &= (1 << (4 * count)) - 1
    return bytes((value >> (4 * (count - 1 - i))) & 0xF for i in range(count))


class _Syntax(Exception):
    pass


@dataclass
class ViscaFaults:
    drop_replies: int = 0  # whole reply packets to swallow
    garble_replies: int = 0  # reply packets to mangle (one byte changed, framing kept)
    late_completions: int = 0  # how many completions to delay
    late_extra_s: float = 0.0  # by this much
    stats: dict[str, int] = field(default_factory=lambda: {"dropped": 0, "garbled": 0, "late": 0})


class ViscaCameraModel(DeviceModel):
    """The RZ50's VISCA port (see the module docstring)."""

    def __init__(self, state: CameraState) -> None:
        super().__init__()
        self.state = state
        self.spec = state.spec
        self.faults = ViscaFaults()
        self._buf = bytearray()
        self._overlong = False
        self._scheduled: list[tuple[float, int, bytes, int]] = []  # (due, order, packet, socket to free)
        self._order = 0
        self._sockets: dict[int, str] = {}  # socket -> what is running there ("pt", "zoom", "focus", "other")
        self.commands_seen: list[bytes] = []
        self.lock = threading.RLock()

    # -- output ---------------------------------------------------------------------------------

    def _out(self, packet: bytes) -> None:
        f = self.faults
        if f.drop_replies > 0:
            f.drop_replies -= 1
            f.stats["dropped"] += 1
            return
        if f.garble_replies > 0:
            f.garble_replies -= 1
            f.stats["garbled"] += 1
            buf = bytearray(packet)
            buf[1] = 0x7E  # no valid reply has this second byte
            packet = bytes(buf)
        self.emit(packet)

    def _schedule(self, due: float, packet: bytes, free_socket: int = 0) -> None:
        self._order += 1
        self._scheduled.append((due, self._order, packet, free_socket))
        self._scheduled.sort()

    def poll(self, now_s: float) -> float | None:
        with self.lock:
            while self._scheduled and self._scheduled[0][0] <= now_s:
                _, _, packet, sock = self._scheduled.pop(0)
                if sock:
                    self._sockets.pop(sock, None)
                self._out(packet)
            return self._scheduled[0][0] if self._scheduled else None

    def send_network_change(self) -> None:
        with self.lock:
            self._out(b"\x90\x38\xff")

    # -- input ----------------------------------------------------------------------------------

    def on_bytes(self, data: bytes, now_s: float) -> None:
        with self.lock:
            for byte in data:
                if byte == 0xFF:
                    packet = bytes(self._buf) + b"\xff"
                    self._buf.clear()
                    if self._overlong:
                        self._overlong = False
                        self._out(b"\x90\x60\x01\xff")
                    else:
                        self._packet(packet, now_s)
                    continue
                self._buf.append(byte)
                if len(self._buf) > 15:
                    self._overlong = True
                    self._buf.clear()
            self.poll(now_s)

    def on_client_change(self, connected: bool, now_s: float) -> None:
        with self.lock:
            self._buf.clear()
            self._overlong = False

    def _packet(self, p: bytes, now: float) -> None:
        if len(p) < 3:
            return
        self.commands_seen.append(p)
        if p[0] == 0x88:
            if p == b"\x88\x30\x01\xff":
                self._out(b"\x88\x30\x02\xff")
            elif p == b"\x88\x01\x00\x01\xff":
                self._clear(now)
                self._out(p)
            return
        if p[0] != 0x81:
            return  # not for camera 1: a real camera stays silent
        try:
            if p[1] == 0x01:
                self._command(p, now)
            elif p[1] == 0x09:
                self._inquiry(p, now)
            elif p[1] & 0xF0 == 0x20 and len(p) == 3:
                self._cancel(p[1] & 0x0F, now)
            else:
                raise _Syntax
        except _Syntax:
            self._out(b"\x90\x60\x02\xff")

    def _clear(self, now: float) -> None:
        st = self.state
        with st.lock:
            st.pan.stop(now)
            st.tilt.stop(now)
            st.zoom.stop(now)
        self._scheduled = [s for s in self._scheduled if not s[3]]
        self._sockets.clear()

    def _cancel(self, sock: int, now: float) -> None:
        if sock in self._sockets:
            what = self._sockets.pop(sock)
            self._scheduled = [s for s in self._scheduled if s[3] != sock]
            self._stop_axes(what, now)
            self._out(bytes([0x90, 0x60 | sock, 0x04, 0xFF]))
        else:
            self._out(bytes([0x90, 0x60 | sock, 0x05, 0xFF]))

    def _stop_axes(self, what: str, now: float) -> None:
        st = self.state
        with st.lock:
            if what == "pt":
                st.pan.stop(now)
                st.tilt.stop(now)
            elif what == "zoom":
                st.zoom.stop(now)

    def _speed(self, vv: int, ww: int) -> tuple[float, float]:
        s = self.spec
        if not (1 <= vv <= s.pan_speed_max and 1 <= ww <= s.tilt_speed_max):
            raise _Syntax
        pan_cps = s.max_dps * vv / s.pan_speed_max * s.pan_counts_per_deg
        tilt_cps = s.max_dps * ww / s.tilt_speed_max * s.tilt_counts_per_deg
        return pan_cps, tilt_cps

    @staticmethod
    def _check_nibbles(data: bytes) -> None:
        if any(b > 0x0F for b in data):
            raise _Syntax

    def _command(self, p: bytes, now: float) -> None:
        s, st = self.spec, self.state
        body = p[2:-1]
        if body[:1] == b"\x00" and body == b"\x00\x01":  # IF_Clear addressed
            self._clear(now)
            self._out(b"\x90\x50\xff")
            return
        # Validate fully first (syntax errors come without an ACK), then take a socket.
        action: tuple[str, float, bool] | None = None  # (what, duration, executable)
        plan = None
        if body[:2] == b"\x06\x01" and len(body) == 6:
            pan_cps, tilt_cps = self._speed(body[2], body[3])
            dp, dt = body[4], body[5]
            if dp not in (1, 2, 3) or dt not in (1, 2, 3):
                raise _Syntax
            plan = ("drive", pan_cps * {1: -1, 2: 1, 3: 0}[dp], tilt_cps * {1: 1, 2: -1, 3: 0}[dt])
            action = ("other", 0.0, True)
        elif body[:2] in (b"\x06\x02", b"\x06\x03") and len(body) == 4 + 2 * 4:
            pan_cps, tilt_cps = self._speed(body[2], body[3])
            self._check_nibbles(body[4:])
            pan_v, tilt_v = _signed(body[4:8]), _signed(body[8:12])
            cur_p, cur_t, _ = st.ptz(now)
            if body[1] == 0x03:
                pan_v, tilt_v = round(cur_p) + pan_v, round(cur_t) + tilt_v
            ok = s.pan_min_counts <= pan_v <= s.pan_max_counts and s.tilt_min_counts <= tilt_v <= s.tilt_max_counts
            dur = max(abs(pan_v - cur_p) / pan_cps, abs(tilt_v - cur_t) / tilt_cps)
            plan = ("abs", pan_v, tilt_v, dur)
            action = ("pt", dur, ok)
        elif body == b"\x06\x04":
            cur_p, cur_t, _ = st.ptz(now)
            pan_cps, tilt_cps = self._speed(s.pan_speed_max, s.tilt_speed_max)
            dur = max(abs(cur_p) / pan_cps, abs(cur_t) / tilt_cps)
            plan = ("abs", 0, 0, dur)
            action = ("pt", dur, True)
        elif body == b"\x06\x05":
            plan = ("abs", 0, 0, s.reset_duration_s)
            action = ("pt", s.reset_duration_s, True)
        elif body[:2] == b"\x06\x24" and len(body) == 3 and body[2] in (2, 3):
            plan = ("set", "auto_pt_speed", body[2] == 2)
            action = ("other", 0.0, True)
        elif body[:2] == b"\x04\x07" and len(body) == 3:
            c = body[2]
            if c == 0:
                plan = ("zoomdrive", 0.0)
            elif c in (2, 3) or 0x20 <= c <= 0x27 or 0x30 <= c <= 0x37:
                speed = 7 if c in (2, 3) else c & 0x0F
                rate = s.zoom_optical_max / s.zoom_full_travel_s * (speed + 1) / 8
                plan = ("zoomdrive", rate if c == 2 or c >> 4 == 2 else -rate)
            else:
                raise _Syntax
            action = ("other", 0.0, True)
        elif body[:2] == b"\x04\x47" and len(body) == 6:
            self._check_nibbles(body[2:])
            z = _signed(b"\x00" + body[2:])
            limit = s.zoom_digital_max if st.digital_zoom else s.zoom_optical_max
            cur_z = st.ptz(now)[2]
            dur = abs(z - cur_z) / s.zoom_optical_max * s.zoom_full_travel_s
            plan = ("zoom", z, dur)
            action = ("zoom", dur, z <= limit)
        elif body[:2] == b"\x04\x06" and len(body) == 3 and body[2] in (2, 3):
            plan = ("set", "digital_zoom", body[2] == 2)
            action = ("other", 0.0, True)
        elif body[:2] == b"\x04\x38" and len(body) == 3 and body[2] in (2, 3):
            plan = ("set", "focus_auto", body[2] == 2)
            action = ("focus", 0.3 if body[2] == 2 else 0.0, True)
        elif body == b"\x04\x18\x01":
            plan = ("none",)
            action = ("focus", 0.3, not st.focus_auto)
        elif body[:2] == b"\x04\x48" and len(body) == 6:
            self._check_nibbles(body[2:])
            plan = ("none",)
            action = ("focus", 0.1, not st.focus_auto)
        elif body[:2] == b"\x04\x00" and len(body) == 3 and body[2] in (2, 3):
            plan = ("set", "power_on", body[2] == 2)
            action = ("other", 0.0, True)
        else:
            raise _Syntax
        what, dur, ok = action
        # a new pan-tilt command supersedes a running one: the old socket completes now
        if what in ("pt", "zoom") or plan[0] in ("drive", "zoomdrive"):
            kind = "pt" if plan[0] in ("abs", "drive") else "zoom"
            for sock, running in list(self._sockets.items()):
                if running == kind:
                    self._sockets.pop(sock)
                    self._scheduled = [x for x in self._scheduled if x[3] != sock]
                    self._out(bytes([0x90, 0x50 | sock, 0xFF]))
        free = [y for y in range(1, s.sockets + 1) if y not in self._sockets]
        if not free:
            self._out(b"\x90\x60\x03\xff")
            return
        sock = free[0]
        self._out(bytes([0x90, 0x40 | sock, 0xFF]))
        if not ok:
            self._out(bytes([0x90, 0x60 | sock, 0x41, 0xFF]))
            return
        self._apply(plan, now)
        f = self.faults
        if f.late_completions > 0 and dur >= 0:
            f.late_completions -= 1
            f.stats["late"] += 1
            dur += f.late_extra_s
        if dur <= 0:
            self._out(bytes([0x90, 0x50 | sock, 0xFF]))
            return
        self._sockets[sock] = what
        self._schedule(now + dur, bytes([0x90, 0x50 | sock, 0xFF]), free_socket=sock)

    def _apply(self, plan: tuple, now: float) -> None:  # type: ignore[type-arg]
        st = self.state
        with st.lock:
            if plan[0] == "drive":
                st.pan.drive(now, plan[1])
                st.tilt.drive(now, plan[2])
            elif plan[0] == "abs":
                st.pan.move_to(now, plan[1], plan[3])
                st.tilt.move_to(now, plan[2], plan[3])
            elif plan[0] == "zoomdrive":
                if plan[1]:
                    st.zoom.lo, st.zoom.hi = 0, (self.spec.zoom_digital_max if st.digital_zoom
                                                 else self.spec.zoom_optical_max)
                    st.zoom.drive(now, plan[1])
                else:
                    st.zoom.stop(now)
            elif plan[0] == "zoom":
                st.zoom.move_to(now, plan[1], plan[2])
            elif plan[0] == "set":
                setattr(st, plan[1], plan[2])

    def _inquiry(self, p: bytes, now: float) -> None:
        s, st = self.spec, self.state
        body = p[2:-1]
        pan, tilt, zoom = st.ptz(now)
        if body == b"\x06\x12":
            data = _nibs(round(pan), s.pan_nibbles) + _nibs(round(tilt), 4)
        elif body == b"\x06\x11":
            data = bytes([s.pan_speed_max, s.tilt_speed_max])
        elif body == b"\x06\x10":
            moving = any(v in ("pt",) for v in self._sockets.values()) or bool(st.pan.rate or st.tilt.rate)
            data = bytes([0x00, 0x04 if moving else 0x00])
        elif body == b"\x04\x47":
            data = _nibs(round(zoom), 4)
        elif body == b"\x04\x38":
            data = bytes([2 if st.focus_auto else 3])
        elif body == b"\x04\x00":
            data = bytes([2 if st.power_on else 3])
        elif body == b"\x04\x06":
            data = bytes([2 if st.digital_zoom else 3])
        elif body == b"\x00\x02" and s.answers_version:
            data = bytes([s.vendor >> 8, s.vendor & 0xFF, s.model >> 8, s.model & 0xFF,
                          s.rom_version >> 8, s.rom_version & 0xFF, s.sockets])
        else:
            raise _Syntax
        self._out(b"\x90\x50" + data + b"\xff")
