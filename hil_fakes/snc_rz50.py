"""Byte-level fake Sony SNC-RZ50: VISCA on a pty or loopback TCP, JPEG/MJPEG and CGIs over HTTP.

An independent model written from the fact sheet (shared/protocols/visca_snc_rz50.md); it never
imports the driver, so a codec bug cannot hide behind a matching fake bug.

VISCA (:class:`ViscaCameraModel`, a :class:`hil_fakes.transport.DeviceModel`):
* packets framed by 0xFF, at most 16 bytes (longer: ``90 60 01 FF``); header 0x81, broadcast 0x88;
* AddressSet ``88 30 01 FF`` -> ``88 30 02 FF``; IF_Clear broadcast echoed, addressed -> ``90 50 FF``;
* two sockets: ACK ``90 4y FF`` at once, completion ``90 5y FF`` after the time the move takes at
  the commanded speed; a third command while both are busy -> ``90 60 03 FF``;
* illegal parameters (speed 0 or above the maximum, nibble byte > 0x0F, unknown command) ->
  ``90 60 02 FF`` with no ACK; out-of-range targets -> ACK then ``90 6y 41 FF``; cancel
  ``81 2y FF`` -> ``90 6y 04 FF`` or ``90 6y 05 FF``;
* inquiries answered at any time (4+4 nibble pan/tilt layout, or 5+4 with ``pan_nibbles=5``).

HTTP (:class:`CameraHttpServer`): ``/image?speed=N`` and ``/mjpeg?speed=N`` (multipart,
boundary ``--myboundary``, Content-Length per part), ``/oneshotimage.jpg``,
``/command/inquiry.cgi?inq=system|ptzf``, ``/command/visca-ptzf.cgi?visca=HEX`` (the reply bytes
the command produced within the request come back as hex text [?: what a real RZ50 returns is not
known]; a request without ``visca`` returns replies queued since, e.g. completions), HTTP Basic
auth. Frames come from a pluggable :class:`Renderer` at the requested rate, JPEG-encoded with OpenCV.

Faults: the transport's byte faults (``server.faults``), plus ``drop_replies``, ``garble_replies``,
``late_completions`` on the VISCA model and ``stall_stream``, ``truncate_frames``,
``drop_connections`` on the HTTP server.
"""

from __future__ import annotations

import argparse
import base64
import binascii
import math
import threading
import time
import urllib.parse
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Protocol

import cv2
import numpy as np

from .transport import DeviceModel, DeviceServer, Endpoint, PtyEndpoint, TcpEndpoint


class Renderer(Protocol):
    width_px: int
    height_px: int

    def render(self, t_s: float, pan_rad: float, tilt_rad: float, hfov_rad: float) -> np.ndarray:
        """uint8 BGR (height_px, width_px, 3) image seen at time t_s with the camera panned pan_rad (CCW/left
        positive, relative to the robot's x axis), tilted tilt_rad (up positive), horizontal field of view hfov_rad."""
        ...


class TestPatternRenderer:
    """A world-fixed pattern (stripes every 10 deg of azimuth, a horizon) plus a block moving with time."""

    __test__ = False  # not a pytest class

    def __init__(self, width_px: int = 320, height_px: int = 240) -> None:
        self.width_px = width_px
        self.height_px = height_px

    def render(self, t_s: float, pan_rad: float, tilt_rad: float, hfov_rad: float) -> np.ndarray:
        w, h = self.width_px, self.height_px
        f = (w / 2) / math.tan(hfov_rad / 2)
        u = np.arange(w, dtype=np.float64)
        v = np.arange(h, dtype=np.float64)
        azimuth = pan_rad - np.arctan((u - w / 2) / f)  # left positive
        elevation = tilt_rad - np.arctan((v - h / 2) / f)
        stripe = (np.floor(np.degrees(azimuth) / 10.0).astype(np.int64) & 1).astype(np.uint8)
        sky = elevation > 0
        img = np.empty((h, w, 3), dtype=np.uint8)
        img[:, :, 0] = (60 + 150 * stripe)[None, :]
        img[:, :, 1] = np.where(sky, 180, 80)[:, None]
        img[:, :, 2] = ((np.degrees(azimuth) * 4) % 256).astype(np.uint8)[None, :]
        # a block moving across the image once every 4 s
        bw = max(4, w // 10)
        x0 = int((t_s % 4.0) / 4.0 * (w - bw))
        y0 = h // 3
        img[y0 : y0 + bw, x0 : x0 + bw] = (255, 255, 255)
        return img


# ---------------------------------------------------------------------------------------------
# The camera's mechanics


@dataclass
class FakeCameraSpec:
    """The fake's own model of the RZ50 (fact sheet values; [?] ones are guesses, as on the real camera)."""

    pan_counts_per_deg: float = 14.4
    pan_min_counts: int = -2448  # -170 deg
    pan_max_counts: int = 2448
    tilt_counts_per_deg: float = 14.4  # [?]
    tilt_min_counts: int = -1296  # -90 deg  [?]
    tilt_max_counts: int = 360  # +25 deg  [?]
    pan_speed_max: int = 0x18
    tilt_speed_max: int = 0x14
    max_dps: float = 300.0  # at the maximum speed; linear in the speed value [?]
    zoom_optical_max: int = 0x4000
    zoom_digital_max: int = 0x7AC0
    zoom_full_travel_s: float = 2.0  # wide -> optical tele at the fastest speed [?]
    reset_duration_s: float = 1.5
    vendor: int = 0x0020
    model: int = 0x0510  # [?] not known for the RZ50
    rom_version: int = 0x0100
    sockets: int = 2
    pan_nibbles: int = 4  # 5 emulates the newer BRC/SRG answer layout
    answers_version: bool = True
    width_px: int = 320
    height_px: int = 240
    hfov_wide_deg: float = 54.0
    # magnification by zoom position (Sony 25x block table from the fact sheet, 26x at 0x4000)
    zoom_table: tuple[tuple[int, float], ...] = (
        (0x0000, 1.0), (0x1781, 2.0), (0x213B, 3.0), (0x2752, 4.0), (0x2BB3, 5.0), (0x2F03, 6.0),
        (0x3364, 8.0), (0x362C, 10.0), (0x386A, 12.0), (0x3AFA, 15.0), (0x3DF8, 20.0), (0x4000, 26.0),
    )

    def hfov_rad(self, zoom: float) -> float:
        table = self.zoom_table
        z = min(max(zoom, table[0][0]), table[-1][0])
        mag = table[-1][1]
        for (p0, m0), (p1, m1) in zip(table, table[1:]):
            if p0 <= z <= p1:
                mag = math.exp(math.log(m0) + (z - p0) / (p1 - p0) * (math.log(m1) - math.log(m0)))
                break
        if zoom > self.zoom_optical_max:  # digital: a crop, up to 12x more
            mag *= 1.0 + 11.0 * (zoom - self.zoom_optical_max) / (self.zoom_digital_max - self.zoom_optical_max)
        return 2 * math.atan(math.tan(math.radians(self.hfov_wide_deg) / 2) / mag)


class _Axis:
    """One axis: at rest, moving linearly to a target, or driving at a constant rate until stopped."""

    def __init__(self, lo: float, hi: float) -> None:
        self.lo, self.hi = lo, hi
        self.p0 = 0.0
        self.t0 = 0.0
        self.target = 0.0
        self.t1 = 0.0
        self.rate = 0.0  # counts/s while driving

    def position(self, now: float) -> float:
        if self.rate:
            return min(max(self.p0 + self.rate * (now - self.t0), self.lo), self.hi)
        if now >= self.t1 or self.t1 <= self.t0:
            return self.target
        return self.p0 + (self.target - self.p0) * (now - self.t0) / (self.t1 - self.t0)

    def move_to(self, now: float, target: float, duration_s: float) -> None:
        self.p0 = self.position(now)
        self.rate = 0.0
        self.t0, self.t1, self.target = now, now + duration_s, target

    def drive(self, now: float, rate: float) -> None:
        p = self.position(now)
        self.p0, self.t0, self.rate, self.target, self.t1 = p, now, rate, p, now

    def stop(self, now: float) -> None:
        p = self.position(now)
        self.p0 = self.target = p
        self.t0 = self.t1 = now
        self.rate = 0.0


class CameraState:
    """Pan, tilt, zoom, focus, power; shared by the VISCA port, the pass-through CGI and the renderer."""

    def __init__(self, spec: FakeCameraSpec) -> None:
        self.spec = spec
        self.lock = threading.RLock()
        self.pan = _Axis(spec.pan_min_counts, spec.pan_max_counts)
        self.tilt = _Axis(spec.tilt_min_counts, spec.tilt_max_counts)
        self.zoom = _Axis(0, spec.zoom_digital_max)
        self.focus_auto = True
        self.power_on = True
        self.digital_zoom = False
        self.auto_pt_speed = True

    def ptz(self, now: float) -> tuple[float, float, float]:
        """(pan counts, tilt counts, zoom position) at ``now``."""
        with self.lock:
            return self.pan.position(now), self.tilt.position(now), self.zoom.position(now)

    def view(self, now: float) -> tuple[float, float, float]:
        """(pan_rad CCW positive, tilt_rad up positive, hfov_rad) for the renderer."""
        p, t, z = self.ptz(now)
        s = self.spec
        return -math.radians(p / s.pan_counts_per_deg), math.radians(t / s.tilt_counts_per_deg), s.hfov_rad(z)


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


# ---------------------------------------------------------------------------------------------
# HTTP


@dataclass
class HttpFaults:
    stall_until: float = 0.0  # streams send nothing until then
    truncate_frames: int = 0  # next parts sent cut short
    truncate_mode: str = "short_length"  # or "lying_length": Content-Length of the full frame, bytes cut
    drop_generation: int = 0  # bumped by drop_connections(); streams of an older generation close
    stats: dict[str, int] = field(default_factory=lambda: {"truncated": 0, "dropped_connections": 0})


class FakeCamera:
    """The whole camera: state, VISCA model(s), renderer, HTTP settings."""

    def __init__(
        self,
        spec: FakeCameraSpec | None = None,
        renderer: Renderer | None = None,
        *,
        username: str | None = None,
        password: str | None = None,
        jpeg_quality: int = 80,
    ) -> None:
        self.spec = spec or FakeCameraSpec()
        self.state = CameraState(self.spec)
        self.renderer: Renderer = renderer or TestPatternRenderer(self.spec.width_px, self.spec.height_px)
        self.visca = ViscaCameraModel(self.state)
        self.visca_served = False
        # the pass-through CGI is its own VISCA "session" on the same mechanics
        self.passthrough = ViscaCameraModel(self.state)
        self._pt_out: list[bytes] = []
        self._pt_lock = threading.Lock()
        self.passthrough.attach(self._pt_emit)
        self.username = username
        self.password = password
        self.jpeg_quality = jpeg_quality
        self.http_faults = HttpFaults()
        self.requested_rates: list[float] = []
        self.frames_sent = 0
        #: the camera's current codec: in "mpeg4" mode /mjpeg answers 400 and /image is not MJPEG
        self.codec = "jpeg"
        self.lock = threading.Lock()

    def _pt_emit(self, data: bytes) -> None:
        self._pt_out.append(data)

    def passthrough_exchange(self, packet: bytes, wait_s: float = 0.05) -> bytes:
        """Feed a pass-through packet; return every reply byte produced since the last call."""
        with self._pt_lock:
            now = time.monotonic()
            self.passthrough.poll(now)
            if packet:
                self.passthrough.on_bytes(packet, now)
            if wait_s > 0 and packet:
                time.sleep(wait_s)
                self.passthrough.poll(time.monotonic())
            out, self._pt_out = b"".join(self._pt_out), []
            return out

    def encode_frame(self, now: float) -> bytes:
        pan, tilt, hfov = self.state.view(now)
        img = self.renderer.render(now, pan, tilt, hfov)
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        if not ok:
            raise RuntimeError("OpenCV could not encode the frame")
        return buf.tobytes()

    def stall_stream(self, seconds: float) -> None:
        self.http_faults.stall_until = time.monotonic() + seconds

    def truncate_frames(self, count: int, mode: str = "short_length") -> None:
        if mode not in ("short_length", "lying_length"):
            raise ValueError(mode)
        with self.lock:
            self.http_faults.truncate_frames += count
            self.http_faults.truncate_mode = mode

    def drop_connections(self) -> None:
        with self.lock:
            self.http_faults.drop_generation += 1
            self.http_faults.stats["dropped_connections"] += 1


class _Handler(BaseHTTPRequestHandler):
    server: CameraHttpServer
    protocol_version = "HTTP/1.0"

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - stdlib signature
        return

    @property
    def cam(self) -> FakeCamera:
        return self.server.camera

    def _authorised(self) -> bool:
        cam = self.cam
        if cam.username is None:
            return True
        expected = base64.b64encode(f"{cam.username}:{cam.password or ''}".encode()).decode()
        if self.headers.get("Authorization", "") == f"Basic {expected}":
            return True
        self.send_response(401)
        self.send_header("WWW-Authenticate", 'Basic realm="Sony Network Camera SNC-RZ50"')
        self.send_header("Content-Length", "0")
        self.end_headers()
        return False

    def _text(self, code: int, text: str, ctype: str = "text/plain") -> None:
        body = text.encode()
        self.send_response(code)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def do_POST(self) -> None:  # noqa: N802 - stdlib name
        length = int(self.headers.get("Content-Length") or 0)
        form = self.rfile.read(length).decode("latin-1") if length else ""
        self._dispatch(urllib.parse.urlsplit(self.path).path, urllib.parse.parse_qs(form))

    def do_GET(self) -> None:  # noqa: N802 - stdlib name
        url = urllib.parse.urlsplit(self.path)
        self._dispatch(url.path, urllib.parse.parse_qs(url.query))

    def _dispatch(self, path: str, query: dict[str, list[str]]) -> None:
        if not self._authorised():
            return
        try:
            if path in ("/image", "/mjpeg") and self.cam.codec == "mpeg4":
                if path == "/mjpeg":
                    self._text(400, "camera is in MPEG-4 mode")
                else:
                    self._text(200, "(an MPEG-4 stream would follow)", "video/mp4")
            elif path in ("/image", "/mjpeg"):
                self._stream(query)
            elif path in ("/oneshotimage.jpg", "/oneshotimage"):
                jpeg = self.cam.encode_frame(time.monotonic())
                self.send_response(200)
                self.send_header("Content-Type", "image/jpeg")
                self.send_header("Content-Length", str(len(jpeg)))
                self.end_headers()
                self.wfile.write(jpeg)
            elif path == "/command/inquiry.cgi":
                self._inquiry(query)
            elif path in ("/command/visca-ptzf.cgi", "/command/ptzf.cgi"):
                self._visca(query)
            else:
                self._text(404, "not found")
        except (BrokenPipeError, ConnectionResetError):
            return

    def _inquiry(self, query: dict[str, list[str]]) -> None:
        inq = (query.get("inq") or query.get("inqjs") or [""])[0]
        if inq == "system":
            self._text(200, "ModelName=SNC-RZ50N&Serial=00000001&SoftVersion=1.00&MacAddress=08-00-46-00-00-01")
        elif inq == "ptzf":
            p, t, z = self.cam.state.ptz(time.monotonic())
            self._text(200, f"AbsolutePTZF={round(p) & 0xFFFF:04x},{round(t) & 0xFFFF:04x},{round(z):04x},0000")
        else:
            self._text(400, "unknown inquiry")

    def _visca(self, query: dict[str, list[str]]) -> None:
        raw = (query.get("visca") or query.get("VISCA") or [""])[0].replace(" ", "")
        try:
            packet = binascii.unhexlify(raw) if raw else b""
        except (binascii.Error, ValueError):
            self._text(400, "visca must be hex")
            return
        reply = self.cam.passthrough_exchange(packet)
        self._text(200, reply.hex().upper())

    def _stream(self, query: dict[str, list[str]]) -> None:
        cam = self.cam
        try:
            speed = float((query.get("speed") or ["30"])[0])
        except ValueError:
            speed = 30.0
        if "interval" in query:
            try:
                speed = 1.0 / max(float(query["interval"][0]), 1e-3)
            except ValueError:
                pass
        speed = min(max(speed, 0.1), 30.0)
        number = int((query.get("number") or ["0"])[0] or 0)
        with cam.lock:
            cam.requested_rates.append(speed)
            generation = cam.http_faults.drop_generation
        self.send_response(200)
        self.send_header("Content-Type", "multipart/x-mixed-replace;boundary=--myboundary")
        self.send_header("Cache-Control", "no-cache")
        self.end_headers()
        period = 1.0 / speed
        next_t = time.monotonic()
        sent = 0
        while not self.server.stopping.is_set():
            now = time.monotonic()
            if now < next_t:
                time.sleep(min(next_t - now, 0.05))
                continue
            next_t = max(next_t + period, now - period)
            with cam.lock:
                if cam.http_faults.drop_generation != generation:
                    return
                stalled = now < cam.http_faults.stall_until
                truncate = cam.http_faults.truncate_frames > 0 and not stalled
                if truncate:
                    cam.http_faults.truncate_frames -= 1
                    cam.http_faults.stats["truncated"] += 1
                mode = cam.http_faults.truncate_mode
            if stalled:
                continue
            jpeg = cam.encode_frame(now)
            declared = len(jpeg)
            if truncate:
                jpeg = jpeg[: len(jpeg) // 2]
                if mode == "short_length":
                    declared = len(jpeg)
            head = (
                f"--myboundary\r\nContent-Type: image/jpeg\r\nContent-Length: {declared}\r\n"
                f"X-Send-Monotonic: {time.monotonic():.6f}\r\n\r\n"
            ).encode()
            self.wfile.write(head + jpeg + b"\r\n")
            self.wfile.flush()
            with cam.lock:
                cam.frames_sent += 1
            sent += 1
            if number and sent >= number:
                return


class CameraHttpServer(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, camera: FakeCamera, host: str = "127.0.0.1", port: int = 0) -> None:
        self.camera = camera
        self.stopping = threading.Event()
        super().__init__((host, port), _Handler)
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        return f"http://{host}:{port}"

    def start(self) -> CameraHttpServer:
        self._thread = threading.Thread(target=self.serve_forever, kwargs={"poll_interval": 0.05},
                                        name="fake-snc-rz50-http", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self.stopping.set()
        self.shutdown()
        self.server_close()
        if self._thread is not None:
            self._thread.join(timeout=2.0)


def serve_visca(camera: FakeCamera, endpoint: Endpoint) -> DeviceServer:
    """Run a VISCA port of the camera on an endpoint (pty or TCP); returns the started server.

    The first port serves ``camera.visca`` (where tests inject VISCA faults); each further port
    gets its own model (its own input buffer, sockets and replies) on the same mechanics.
    """
    model = camera.visca if not camera.visca_served else ViscaCameraModel(camera.state)
    camera.visca_served = True
    return DeviceServer(model, endpoint).start()


# ---------------------------------------------------------------------------------------------
# CLI: `vipsm-robot fake camera ...` (wired in app/cmd_camera.py)


def add_cli_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--visca-pty", action="store_true", help="serve VISCA on a pseudo-terminal")
    parser.add_argument("--link", metavar="PATH", help="stable symlink to the pty (like /dev/ptzcam)")
    parser.add_argument("--visca-tcp", metavar="HOST:PORT", help="serve raw VISCA on loopback TCP")
    parser.add_argument("--http", metavar="HOST:PORT", help="serve the HTTP interface (MJPEG, CGIs)")
    parser.add_argument("--user", help="HTTP Basic user (no auth when absent)")
    parser.add_argument("--password", default="", help="HTTP Basic password")
    parser.add_argument("--size", default="320x240", help="JPEG size WxH")
    parser.add_argument("--pan-nibbles", type=int, choices=(4, 5), default=4, help="position answer layout")


def _host_port(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit():
        raise SystemExit(f"expected HOST:PORT, got {text!r}")
    return host or "127.0.0.1", int(port)


def run_cli(args: argparse.Namespace, renderer: Renderer | None = None) -> int:
    """Serve until interrupted; prints the addresses (one line each) and flushes."""
    if not (args.visca_pty or args.visca_tcp or args.http):
        raise SystemExit("fake camera needs --visca-pty, --visca-tcp HOST:PORT and/or --http HOST:PORT")
    w, _, h = args.size.partition("x")
    spec = FakeCameraSpec(width_px=int(w), height_px=int(h), pan_nibbles=args.pan_nibbles)
    camera = FakeCamera(spec, renderer, username=args.user, password=args.password)
    servers: list[DeviceServer] = []
    http: CameraHttpServer | None = None
    try:  # Ctrl-C may come at any moment, even before everything is up
        if args.visca_pty:
            servers.append(serve_visca(camera, PtyEndpoint(args.link)))
            print(f"visca-pty {servers[-1].address}", flush=True)
        if args.visca_tcp:
            host, port = _host_port(args.visca_tcp)
            servers.append(serve_visca(camera, TcpEndpoint(host, port)))
            print(f"visca-tcp {servers[-1].address}", flush=True)
        if args.http:
            host, port = _host_port(args.http)
            http = CameraHttpServer(camera, host, port).start()
            print(f"http {http.url}", flush=True)
        while all(s.error is None for s in servers):
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        if http is not None:
            http.stop()
        for server in servers:
            server.stop()  # re-raises a model failure: a broken fake is never a silent one
    return 0
