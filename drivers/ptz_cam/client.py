"""VISCA client for the SNC-RZ50: owns the port, matches every reply to its request, angles in radians.

Transports: a serial port (9600 or 38400 8N1, a tty or pty path), raw VISCA over TCP
(``socket://host:port``, for serial-over-IP bridges), or the camera's HTTP pass-through CGI
(``http://user:pw@camera``; see :class:`drivers.ptz_cam.http.HttpViscaPort`).

Reply matching (the fact sheet's pitfalls 2, 3, 6, 7):

* only one request waits for its *immediate* reply at a time (VISCA replies carry no request id);
  that reply is an ACK (a command), an inquiry answer of the expected length (an inquiry), a
  socket-0 completion (addressed IF_Clear), the AddressSet / IF_Clear echo, or an error;
* an ACK ``4y`` hands the command to socket y; from then on only a completion ``5y`` or an error
  ``6y`` for *that* socket finishes it, so up to two commands are in flight while inquiries go on;
* a completion for a socket nobody waits on (e.g. the late completion of a command whose wait
  timed out) frees that socket and is counted, and is never taken as the answer to another request;
* errors after the ACK (``6y 41`` not executable) fail the command that holds socket y;
* completion timeouts scale with the commanded move (distance / predicted speed, up to 300 deg/s);
* after a request went unanswered, input is drained for ``stale_drain_s`` before the next one.

Every reply error surfaces as a typed :class:`ViscaReplyError` subclass; a lost port as
:class:`ViscaDisconnectedError` (the next call reopens it with backoff); no reply as
:class:`ViscaTimeoutError`. The reader thread's own failures are kept in ``last_error`` and raised
by the next call.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import serial

from drivers.common import Backoff, close_quietly, open_port, read_some, run_guarded, write_all
from drivers.errors import DisconnectedError, DriverTimeoutError

from . import visca as v
from .config import CameraIntrinsics, HttpConfig, PtzCalibration, ViscaConfig
from .errors import (
    CommandCancelledError,
    NotExecutableError,
    SyntaxReplyError,
    ViscaConfigError,
    ViscaDisconnectedError,
    ViscaError,
    ViscaProtocolError,
    ViscaTimeoutError,
)
from .frames import CameraFrame, MjpegFrameSource, fetch_oneshot, inquiry_system
from .http import HttpViscaPort
from .state import PtzState

__all__ = [
    "CameraFrame",
    "CommandHandle",
    "MjpegFrameSource",
    "PtzState",
    "ViscaClient",
    "fetch_oneshot",
    "inquiry_system",
]


class CommandHandle:
    """A command the camera accepted into a socket; ``wait()`` blocks until it completes or fails."""

    def __init__(self, request: v.Request, socket: int, acked_s: float, timeout_s: float) -> None:
        self.request = request
        self.socket = socket
        self.acked_s = acked_s
        self.timeout_s = timeout_s
        self.deadline_s = acked_s + timeout_s
        self.abandoned = False
        self.completed_s: float | None = None
        self._done = threading.Event()
        self._error: BaseException | None = None

    def _finish(self, error: BaseException | None, now: float) -> None:
        if self._done.is_set():
            return
        self._error = error
        self.completed_s = now
        self._done.set()

    @property
    def done(self) -> bool:
        return self._done.is_set()

    def wait(self, timeout_s: float | None = None) -> None:
        """Block until completion; raises the command's error, or :class:`ViscaTimeoutError`.

        Without ``timeout_s`` the wait lasts until the deadline set from the predicted move time.
        After a timeout the socket stays tracked, so its late completion is recognised as such.
        """
        remaining = self.deadline_s - time.monotonic() if timeout_s is None else timeout_s
        if not self._done.wait(max(0.0, remaining)):
            self.abandoned = True
            raise ViscaTimeoutError(
                f"{self.request.name}: no completion in socket {self.socket} within {self.timeout_s:.2f} s"
            )
        if self._error is not None:
            raise self._error


@dataclass
class _Pending:
    request: v.Request
    done: bool = False
    result: object = None
    error: BaseException | None = None


@dataclass
class ClientStats:
    requests: int = 0
    stray_replies: int = 0  # replies nobody was waiting for (counted, dropped)
    late_completions: int = 0  # completions of commands whose wait had timed out
    stale_answers: int = 0  # inquiry answers of the wrong length for the pending inquiry
    discarded_bytes: int = 0  # garbage dropped by the codec while resynchronising
    timeouts: int = 0
    reconnects: int = 0
    network_changes: int = 0
    startup_warnings: list[str] = field(default_factory=list)


class ViscaClient:
    """SNC-RZ50 over VISCA (see the module docstring). Use as a context manager or call open()/close()."""

    def __init__(
        self,
        url: str,
        config: ViscaConfig | None = None,
        *,
        http: HttpConfig | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.url = url
        self.config = config or ViscaConfig()
        self.http_config = http
        self.calibration: PtzCalibration = self.config.calibration
        self._clock = clock
        self._port: serial.SerialBase | HttpViscaPort | None = None
        self._parser = v.ViscaParser()
        self._cv = threading.Condition()
        self._exchange_lock = threading.Lock()
        self._write_lock = threading.Lock()
        self._pending: _Pending | None = None
        self._sockets: dict[int, CommandHandle] = {}
        self._reader: threading.Thread | None = None
        self._stop = threading.Event()
        self._error: BaseException | None = None
        self._suspect_stale = False
        self._network_changed = False
        self._backoff = Backoff(initial_s=0.1, max_s=2.0)
        self._next_reconnect_s = 0.0
        self._driving = False
        self._last_pt: tuple[int, int] | None = None
        self._last_zoom: int | None = None
        self._last_state: PtzState | None = None
        self.pan_max_speed = self.config.pan_max_speed
        self.tilt_max_speed = self.config.tilt_max_speed
        self.version: v.Version | None = None
        self.camera_count: int | None = None
        self.stats = ClientStats()
        self._poller: threading.Thread | None = None
        self._poller_stop = threading.Event()

    # -- lifecycle ----------------------------------------------------------------------------

    def __enter__(self) -> ViscaClient:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def connected(self) -> bool:
        return self._port is not None and self._reader is not None and self._reader.is_alive()

    @property
    def last_error(self) -> BaseException | None:
        """The reader thread's error (a lost port), also raised by the next call."""
        return self._error

    def _open_port(self) -> None:
        if self.url.startswith(("http://", "https://")):
            self._port = HttpViscaPort(self.url, self.http_config or HttpConfig(base_url=self.url))
        else:
            self._port = open_port(self.url, baudrate=self.config.baudrate, timeout_s=0.02)
            try:
                self._port.reset_input_buffer()  # stale replies of a previous client (pitfall 4)
            except (serial.SerialException, OSError) as exc:
                close_quietly(self._port)
                self._port = None
                raise ViscaDisconnectedError(f"cannot flush {self.url}: {exc}") from exc
        self._parser.reset()
        self._error = None
        self._stop.clear()
        self._reader = threading.Thread(
            target=run_guarded(self._read_loop, self._reader_failed), name="visca-reader", daemon=True
        )
        self._reader.start()

    def open(self, start_up: bool = True) -> ViscaClient:
        """Open the port and (by default) run the start-up sequence (:meth:`start_up`)."""
        try:
            self._open_port()
        except DisconnectedError as exc:
            raise ViscaDisconnectedError(str(exc)) from exc
        if start_up:
            try:
                self.start_up()
            except BaseException:
                self.close()
                raise
        return self

    def close(self) -> None:
        self.stop_state_poller()
        self._stop.set()
        reader, self._reader = self._reader, None
        if reader is not None and reader is not threading.current_thread():
            reader.join(timeout=2.0)
        port, self._port = self._port, None
        if isinstance(port, HttpViscaPort):
            port.close()
        else:
            close_quietly(port)
        self._fail_all(ViscaDisconnectedError("client closed"))

    def _reader_failed(self, exc: BaseException) -> None:
        err = exc if isinstance(exc, ViscaError) else ViscaDisconnectedError(f"VISCA port lost: {exc}")
        if err is not exc:
            err.__cause__ = exc
        self._error = err
        self._fail_all(err)

    def _fail_all(self, err: BaseException) -> None:
        now = self._clock()
        with self._cv:
            if self._pending is not None and not self._pending.done:
                self._pending.error = err
                self._pending.done = True
            for handle in self._sockets.values():
                handle._finish(err, now)
            self._sockets.clear()
            self._driving = False
            self._cv.notify_all()

    def _ensure_open(self) -> None:
        """Reopen a lost port (the reader died or a write failed); failed attempts back off."""
        if self.connected and self._error is None:
            return
        if self._port is None and self._reader is None and self._error is None:
            raise ViscaDisconnectedError("client is not open (call open())")
        now = self._clock()
        if now < self._next_reconnect_s:
            raise ViscaDisconnectedError(f"VISCA port down, next reconnect in {self._next_reconnect_s - now:.2f} s") \
                from self._error
        self._stop.set()
        if self._reader is not None and self._reader is not threading.current_thread():
            self._reader.join(timeout=2.0)
        port, self._port, self._reader = self._port, None, None
        if isinstance(port, HttpViscaPort):
            port.close()
        else:
            close_quietly(port)
        try:
            self._open_port()
        except DisconnectedError as exc:
            self._next_reconnect_s = self._clock() + self._backoff.next_delay()
            raise ViscaDisconnectedError(f"reconnect failed: {exc}") from exc
        self._backoff.reset()
        self.stats.reconnects += 1
        self._suspect_stale = True

    # -- reader -------------------------------------------------------------------------------

    def _read_loop(self) -> None:
        port = self._port
        assert port is not None
        while not self._stop.is_set():
            data = port.read_some() if isinstance(port, HttpViscaPort) else read_some(port)
            if data:
                self._dispatch(self._parser.feed(data))
            elif isinstance(port, serial.SerialBase) and not port.is_open:
                raise ViscaDisconnectedError("VISCA port closed")

    def _dispatch(self, events: list[v.Event]) -> None:
        now = self._clock()
        with self._cv:
            for ev in events:
                self._dispatch_one(ev, now)
            self._cv.notify_all()

    def _stray(self, ev: object) -> None:
        self.stats.stray_replies += 1

    def _dispatch_one(self, ev: v.Event, now: float) -> None:  # noqa: C901 - one branch per reply kind
        pending = self._pending if (self._pending is not None and not self._pending.done) else None
        kind = pending.request.kind if pending else None
        if isinstance(ev, v.Discarded):
            self.stats.discarded_bytes += len(ev.raw)
        elif isinstance(ev, v.Ack):
            if pending is not None and kind is v.ReplyKind.COMMAND:
                old = self._sockets.pop(ev.socket, None)
                if old is not None:  # the camera reused the socket: the old command is over
                    old._finish(None, now)
                handle = CommandHandle(pending.request, ev.socket, now, self.completion_timeout_s(pending.request))
                self._sockets[ev.socket] = handle
                pending.result, pending.done = handle, True
            else:
                self._stray(ev)
        elif isinstance(ev, v.Completion):
            if ev.socket == 0:
                if pending is not None and kind is v.ReplyKind.IF_CLEAR:
                    pending.result, pending.done = ev, True
                    self._cleared(now)
                else:
                    self._stray(ev)
            elif ev.socket in self._sockets:
                handle = self._sockets.pop(ev.socket)
                if handle.abandoned:
                    self.stats.late_completions += 1
                self._completed(handle, now)
                handle._finish(None, now)
            else:
                self._stray(ev)
        elif isinstance(ev, v.InquiryAnswer):
            if pending is not None and kind is v.ReplyKind.INQUIRY:
                if len(ev.data) in pending.request.answer_lengths:
                    pending.result, pending.done = ev, True
                else:
                    self.stats.stale_answers += 1
            else:
                self._stray(ev)
        elif isinstance(ev, v.ErrorReply):
            self._on_error(ev, pending, now)
        elif isinstance(ev, v.AddressSetReply):
            if pending is not None and kind is v.ReplyKind.ADDRESS_SET:
                pending.result, pending.done = ev, True
            else:
                self._stray(ev)
        elif isinstance(ev, v.IfClearEcho):
            if pending is not None and kind is v.ReplyKind.IF_CLEAR_BROADCAST:
                pending.result, pending.done = ev, True
                self._cleared(now)
            else:
                self._stray(ev)
        elif isinstance(ev, v.NetworkChange):
            self.stats.network_changes += 1
            self._network_changed = True

    def _on_error(self, ev: v.ErrorReply, pending: _Pending | None, now: float) -> None:
        kind = pending.request.kind if pending else None
        if pending is not None and kind is v.ReplyKind.CANCEL and ev.socket == pending.request.socket:
            if ev.code is v.ErrorCode.CANCELLED:
                handle = self._sockets.pop(ev.socket, None)
                if handle is not None:
                    handle._finish(ev.to_exception(handle.request.name), now)
                pending.result, pending.done = ev, True
            else:
                pending.error, pending.done = ev.to_exception(pending.request.name), True
            return
        if ev.socket != 0 and ev.socket in self._sockets:
            handle = self._sockets.pop(ev.socket)
            handle._finish(ev.to_exception(handle.request.name), now)
            return
        if pending is not None and kind in (v.ReplyKind.COMMAND, v.ReplyKind.INQUIRY, v.ReplyKind.IF_CLEAR,
                                            v.ReplyKind.CANCEL):
            pending.error, pending.done = ev.to_exception(pending.request.name), True
            return
        self._stray(ev)

    def _cleared(self, now: float) -> None:
        """IF_Clear empties the camera's sockets without replies: fail whatever we still track."""
        for sock, handle in self._sockets.items():
            handle._finish(CommandCancelledError(f"{handle.request.name}: cleared by IF_Clear", socket=sock,
                                                 code="IF_CLEAR", raw=b""), now)
        self._sockets.clear()
        self._driving = False

    def _completed(self, handle: CommandHandle, now: float) -> None:
        req = handle.request
        if req.motion is v.Motion.PAN_TILT_ABSOLUTE:
            self._last_pt = (req.pan_counts, req.tilt_counts)
        elif req.motion in (v.Motion.PAN_TILT_HOME, v.Motion.PAN_TILT_RESET):
            self._last_pt = (0, 0)
        elif req.motion is v.Motion.PAN_TILT_RELATIVE and self._last_pt is not None:
            self._last_pt = (self._last_pt[0] + req.pan_counts, self._last_pt[1] + req.tilt_counts)
        elif req.zoom_position is not None:
            self._last_zoom = req.zoom_position
        if self._last_pt is not None and self._last_zoom is not None:
            self._last_state = self._make_state(self._last_pt[0], self._last_pt[1], self._last_zoom, now,
                                                moving=self._moving_locked())

    # -- timeouts -----------------------------------------------------------------------------

    def completion_timeout_s(self, request: v.Request) -> float:
        """Deadline for a command's completion after its ACK: default + margin * predicted duration."""
        cfg, cal = self.config, self.calibration
        m = request.motion
        if m is v.Motion.PAN_TILT_RESET:
            return cfg.reset_timeout_s
        predicted = 0.0
        if m in (v.Motion.PAN_TILT_ABSOLUTE, v.Motion.PAN_TILT_RELATIVE, v.Motion.PAN_TILT_HOME):
            pan_span = (cal.pan_max_deg - cal.pan_min_deg) * cal.pan_counts_per_deg
            tilt_span = (cal.tilt_max_deg - cal.tilt_min_deg) * cal.tilt_counts_per_deg
            if m is v.Motion.PAN_TILT_RELATIVE:
                dp, dt = abs(request.pan_counts), abs(request.tilt_counts)
            elif self._last_pt is None:
                dp, dt = pan_span, tilt_span  # position unknown: the worst case
            else:
                tp, tt = (0, 0) if m is v.Motion.PAN_TILT_HOME else (request.pan_counts, request.tilt_counts)
                dp, dt = abs(tp - self._last_pt[0]), abs(tt - self._last_pt[1])
            ps = request.pan_speed or self.pan_max_speed
            ts = request.tilt_speed or self.tilt_max_speed
            pan_cps = cfg.speed_dps(ps, self.pan_max_speed, cfg.pan_max_dps) * cal.pan_counts_per_deg
            tilt_cps = cfg.speed_dps(ts, self.tilt_max_speed, cfg.tilt_max_dps) * cal.tilt_counts_per_deg
            predicted = max(dp / pan_cps, dt / tilt_cps)
        elif m is v.Motion.ZOOM:
            if request.zoom_position is not None and self._last_zoom is not None:
                frac = abs(request.zoom_position - self._last_zoom) / cal.optical_zoom_max
            else:
                frac = 2.0  # unknown start, or a digital range: the whole travel twice
            predicted = frac * cfg.zoom_full_travel_s
        return cfg.default_completion_timeout_s + cfg.completion_margin * predicted

    # -- requests -----------------------------------------------------------------------------

    def _exchange(self, request: v.Request, timeout_s: float) -> object:
        """Send one request and wait for its immediate reply (see the module docstring)."""
        with self._exchange_lock:
            self._ensure_open()
            if self._suspect_stale:
                time.sleep(self.config.stale_drain_s)  # late replies arrive now and are dropped as strays
                self._suspect_stale = False
            slot = _Pending(request)
            with self._cv:
                self._pending = slot
            self.stats.requests += 1
            port = self._port
            try:
                with self._write_lock:
                    if isinstance(port, HttpViscaPort):
                        port.write(request.packet)
                    else:
                        assert port is not None
                        write_all(port, request.packet)
            except DriverTimeoutError as exc:
                with self._cv:
                    self._pending = None
                raise ViscaTimeoutError(f"{request.name}: {exc}") from exc
            except DisconnectedError as exc:
                with self._cv:
                    self._pending = None
                self._error = ViscaDisconnectedError(f"{request.name}: {exc}")
                raise self._error from exc
            deadline = self._clock() + timeout_s
            with self._cv:
                while not slot.done:
                    remaining = deadline - self._clock()
                    if remaining <= 0:
                        break
                    self._cv.wait(min(remaining, 0.05))
                self._pending = None
            if not slot.done:
                self._suspect_stale = True
                self.stats.timeouts += 1
                raise ViscaTimeoutError(f"{request.name}: no reply within {timeout_s:.2f} s")
            if slot.error is not None:
                raise slot.error
            return slot.result

    def _handle_network_change(self) -> None:
        if self._network_changed:
            self._network_changed = False
            self._exchange(v.address_set(), self.config.ack_timeout_s)

    def submit(self, request: v.Request, *, retries: int = 0) -> CommandHandle:
        """Send a command and wait for its ACK; returns the handle that waits for its completion.

        ``retries`` re-sends only idempotent requests (never a relative move or a drive) after an
        ACK timeout (pitfall 8).
        """
        if request.kind is not v.ReplyKind.COMMAND:
            raise ViscaConfigError(f"{request.name} is not a socket command")
        self._handle_network_change()
        attempts = 1 + (retries if request.idempotent else 0)
        for attempt in range(attempts):
            try:
                result = self._exchange(request, self.config.ack_timeout_s)
                assert isinstance(result, CommandHandle)
                return result
            except ViscaTimeoutError:
                if attempt + 1 >= attempts:
                    raise
        raise AssertionError("unreachable")

    def command(self, request: v.Request, *, wait: bool = True, retries: int = 0) -> CommandHandle:
        handle = self.submit(request, retries=retries)
        if wait:
            handle.wait()
        return handle

    def inquire(self, request: v.Request, *, retries: int = 1) -> v.InquiryAnswer:
        if request.kind is not v.ReplyKind.INQUIRY:
            raise ViscaConfigError(f"{request.name} is not an inquiry")
        self._handle_network_change()
        for attempt in range(1 + retries):
            try:
                result = self._exchange(request, self.config.inquiry_timeout_s)
                assert isinstance(result, v.InquiryAnswer)
                return result
            except (ViscaTimeoutError, ViscaProtocolError):
                if attempt >= retries:
                    raise
        raise AssertionError("unreachable")

    def cancel(self, socket: int) -> None:
        """CommandCancel; the command in that socket fails with :class:`CommandCancelledError`.

        Raises :class:`NoSocketError` when the socket was empty.
        """
        self._exchange(v.command_cancel(socket, self.config.address), self.config.ack_timeout_s)

    def in_flight(self) -> dict[int, str]:
        """Sockets with a command this client is waiting on: socket -> request name."""
        with self._cv:
            return {s: h.request.name for s, h in self._sockets.items()}

    # -- start-up -----------------------------------------------------------------------------

    def start_up(self) -> None:
        """AddressSet, IF_Clear (broadcast and addressed), version, max speed, digital zoom off, state.

        The version inquiry ([?] on the RZ50) and auto pan-tilt speed off ([?]) are allowed to fail;
        what failed is listed in ``stats.startup_warnings``.
        """
        a = self.config.address
        reply = self._exchange(v.address_set(), self.config.ack_timeout_s)
        assert isinstance(reply, v.AddressSetReply)
        self.camera_count = reply.camera_count
        if reply.camera_count < 1:
            raise ViscaProtocolError(f"AddressSet found no camera ({reply.raw.hex(' ')})", raw=reply.raw)
        self._exchange(v.if_clear_broadcast(), self.config.ack_timeout_s)
        self._exchange(v.if_clear(a), self.config.ack_timeout_s)
        try:
            self.version = v.decode_version(self.inquire(v.version_inquiry(a)))
        except (SyntaxReplyError, ViscaTimeoutError, ViscaProtocolError) as exc:
            self.stats.startup_warnings.append(f"version inquiry: {exc}")
        try:
            ms = v.decode_max_speed(self.inquire(v.pan_tilt_max_speed_inquiry(a)))
            self.pan_max_speed, self.tilt_max_speed = ms.pan, ms.tilt
        except (SyntaxReplyError, ViscaTimeoutError, ViscaProtocolError) as exc:
            self.stats.startup_warnings.append(f"max speed inquiry: {exc}")
        if self.config.digital_zoom_off:
            self.command(v.digital_zoom(False, a))
        if self.config.set_auto_pan_tilt_speed_off:
            try:
                self.command(v.auto_pan_tilt_speed(False, a))
            except (SyntaxReplyError, NotExecutableError) as exc:
                self.stats.startup_warnings.append(f"auto pan-tilt speed off: {exc}")
        self.position()

    # -- inquiries ----------------------------------------------------------------------------

    def pan_tilt_counts(self) -> v.PanTiltPosition:
        pos = v.decode_pan_tilt_position(self.inquire(v.pan_tilt_position_inquiry(self.config.address)))
        with self._cv:
            self._last_pt = (pos.pan_counts, pos.tilt_counts)
        return pos

    def zoom_position(self) -> int:
        z = v.decode_zoom_position(self.inquire(v.zoom_position_inquiry(self.config.address)))
        with self._cv:
            self._last_zoom = z
        return z

    def max_speed(self) -> v.MaxSpeed:
        return v.decode_max_speed(self.inquire(v.pan_tilt_max_speed_inquiry(self.config.address)))

    def focus_mode(self) -> v.FocusMode:
        return v.decode_focus_mode(self.inquire(v.focus_mode_inquiry(self.config.address)))

    def power(self) -> v.PowerState:
        return v.decode_power(self.inquire(v.power_inquiry(self.config.address)))

    def digital_zoom_on(self) -> bool:
        return v.decode_on_off(self.inquire(v.digital_zoom_inquiry(self.config.address)), "digital zoom")

    def read_version(self) -> v.Version:
        self.version = v.decode_version(self.inquire(v.version_inquiry(self.config.address)))
        return self.version

    def _moving_locked(self) -> bool:
        return self._driving or any(
            h.request.motion is not v.Motion.NONE and h.request.motion is not v.Motion.FOCUS
            for h in self._sockets.values()
        )

    def _make_state(self, pan: int, tilt: int, zoom: int, stamp: float, moving: bool) -> PtzState:
        cal = self.calibration
        return PtzState(
            pan_rad=cal.pan_counts_to_rad(pan),
            tilt_rad=cal.tilt_counts_to_rad(tilt),
            zoom_position=zoom,
            hfov_rad=cal.hfov_rad(zoom),
            pan_counts=pan,
            tilt_counts=tilt,
            stamp_s=stamp,
            moving=moving,
        )

    def position(self) -> PtzState:
        """Read pan/tilt and zoom now; the result also becomes :attr:`last_state`."""
        pt = self.pan_tilt_counts()
        zoom = self.zoom_position()
        now = self._clock()
        with self._cv:
            state = self._make_state(pt.pan_counts, pt.tilt_counts, zoom, now, self._moving_locked())
            self._last_state = state
        return state

    @property
    def last_state(self) -> PtzState | None:
        """The newest known pan/tilt/zoom (from inquiries, or a completed move's target)."""
        with self._cv:
            state = self._last_state
            if state is not None and state.moving != self._moving_locked():
                state = dataclasses.replace(state, moving=self._moving_locked())
            return state

    def start_state_poller(self, interval_s: float = 0.2) -> None:
        """Poll the position in the background (rate-limited; pitfall 14) to keep last_state fresh."""
        if self._poller is not None and self._poller.is_alive():
            return
        if not interval_s > 0:
            raise ViscaConfigError("poll interval must be > 0")
        self._poller_stop.clear()

        def loop() -> None:
            while not self._poller_stop.wait(interval_s):
                try:
                    self.position()
                except ViscaError as exc:  # kept for the owner; the next poll tries again
                    self.poller_error = exc

        self.poller_error: ViscaError | None = None
        self._poller = threading.Thread(target=loop, name="visca-state-poller", daemon=True)
        self._poller.start()

    def stop_state_poller(self) -> None:
        self._poller_stop.set()
        if self._poller is not None and self._poller is not threading.current_thread():
            self._poller.join(timeout=2.0)
        self._poller = None

    def intrinsics(self, width_px: int, height_px: int, zoom_position: int | None = None) -> CameraIntrinsics:
        """fx, fy, cx, cy for an image size at a zoom position (default: the last known one)."""
        if zoom_position is None:
            zoom_position = self._last_zoom if self._last_zoom is not None else self.zoom_position()
        return self.calibration.intrinsics(zoom_position, width_px, height_px)

    # -- motion -------------------------------------------------------------------------------

    def _speed_value(self, fraction: float, maximum: int) -> int:
        if not (math.isfinite(fraction) and 0 < fraction <= 1):
            raise ViscaConfigError(f"speed fraction must be in (0, 1], got {fraction!r}")
        return max(1, min(maximum, math.ceil(fraction * maximum)))

    def move_to(self, pan_rad: float, tilt_rad: float, speed: float = 1.0, *, wait: bool = True) -> CommandHandle:
        """Absolute pan/tilt (radians, pan left-positive, tilt up-positive) at a fraction of max speed."""
        cal = self.calibration
        cal.check_pan_tilt(pan_rad, tilt_rad)
        req = v.pan_tilt_absolute(
            cal.pan_rad_to_counts(pan_rad), cal.tilt_rad_to_counts(tilt_rad),
            self._speed_value(speed, self.pan_max_speed), self._speed_value(speed, self.tilt_max_speed),
            address=self.config.address, pan_max=self.pan_max_speed, tilt_max=self.tilt_max_speed,
        )
        self._driving = False
        return self.command(req, wait=wait, retries=1)

    def move_by(self, dpan_rad: float, dtilt_rad: float, speed: float = 1.0, *, wait: bool = True) -> CommandHandle:
        """Relative move; never re-sent after a lost reply (it would move twice)."""
        cal = self.calibration
        if not (math.isfinite(dpan_rad) and math.isfinite(dtilt_rad)):
            raise ViscaConfigError("relative move must be finite")
        req = v.pan_tilt_relative(
            cal.pan_rad_to_counts(dpan_rad), cal.tilt_rad_to_counts(dtilt_rad),
            self._speed_value(speed, self.pan_max_speed), self._speed_value(speed, self.tilt_max_speed),
            address=self.config.address, pan_max=self.pan_max_speed, tilt_max=self.tilt_max_speed,
        )
        return self.command(req, wait=wait, retries=0)

    def drive(self, pan: float, tilt: float) -> None:
        """Continuous drive: ``pan``/``tilt`` in [-1, 1] as fractions of max speed (pan + = left, tilt + = up).

        The idle axis still gets a legal speed (1) with direction "stop".
        """
        for name, x in (("pan", pan), ("tilt", tilt)):
            if not (math.isfinite(x) and -1 <= x <= 1):
                raise ViscaConfigError(f"{name} drive must be in [-1, 1], got {x!r}")
        sign = self.calibration.pan_sign  # API left-positive; VISCA "left" is the API's + when pan_sign == -1
        pan_left = (pan > 0) == (sign < 0)
        pdir = v.PanDirection.STOP if pan == 0 else (v.PanDirection.LEFT if pan_left else v.PanDirection.RIGHT)
        tilt_up = (tilt > 0) == (self.calibration.tilt_sign > 0)
        tdir = v.TiltDirection.STOP if tilt == 0 else (v.TiltDirection.UP if tilt_up else v.TiltDirection.DOWN)
        ps = self._speed_value(abs(pan), self.pan_max_speed) if pan else 1
        ts = self._speed_value(abs(tilt), self.tilt_max_speed) if tilt else 1
        req = v.pan_tilt_drive(pdir, tdir, ps, ts, address=self.config.address,
                               pan_max=self.pan_max_speed, tilt_max=self.tilt_max_speed)
        self.command(req, wait=True, retries=0)
        self._driving = not (pdir is v.PanDirection.STOP and tdir is v.TiltDirection.STOP)

    def stop(self) -> None:
        """Stop pan/tilt (legal speeds on both axes); safe to re-send."""
        self.command(v.pan_tilt_stop(1, 1, address=self.config.address), retries=1)
        self._driving = False

    def home(self, *, wait: bool = True) -> CommandHandle:
        return self.command(v.pan_tilt_home(self.config.address), wait=wait, retries=1)

    def reset(self, *, wait: bool = True) -> CommandHandle:
        return self.command(v.pan_tilt_reset(self.config.address), wait=wait)

    def zoom_to(self, position: int, *, wait: bool = True) -> CommandHandle:
        return self.command(v.zoom_direct(position, self.config.address), wait=wait, retries=1)

    def zoom_to_magnification(self, magnification: float, *, wait: bool = True) -> CommandHandle:
        return self.zoom_to(self.calibration.zoom_position_for(magnification), wait=wait)

    def zoom_tele(self, speed: int | None = None) -> CommandHandle:
        return self.command(v.zoom_tele(self.config.address, speed))

    def zoom_wide(self, speed: int | None = None) -> CommandHandle:
        return self.command(v.zoom_wide(self.config.address, speed))

    def zoom_stop(self) -> CommandHandle:
        return self.command(v.zoom_stop(self.config.address), retries=1)

    def set_digital_zoom(self, on: bool) -> CommandHandle:
        return self.command(v.digital_zoom(on, self.config.address), retries=1)

    def focus_auto(self) -> CommandHandle:
        return self.command(v.focus_auto(self.config.address))

    def focus_manual(self) -> CommandHandle:
        return self.command(v.focus_manual(self.config.address))

    def focus_one_push(self) -> CommandHandle:
        return self.command(v.focus_one_push(self.config.address))
