"""The live view: the field log's channels served to Foxglove or Lichtblick (``ws://HOST:PORT``):
scans, pose, transforms, obstacles, the camera and the loop's health while the robot runs.

The Foxglove SDK's WebSocket server encodes and serves the channels on a private loopback port;
viewers reach only the front (:mod:`app.livefront`), which caps clients, times out handshakes,
bounds each client's send queue, serves the protocol's older name ``foxglove.websocket.v1``, latches
topics (``/vipsm/config``) and stops within its timeout whatever the clients do. Lines about clients
are rate-limited (:class:`LineBudget`); the counters are in the run summary (``live_view``).
Loopback only unless ``live.allow_remote`` is set (the camera image and the robot's position would
be readable by anyone on the network)."""

from __future__ import annotations

import dataclasses
import logging
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from .errors import AppError
from .listen_address import DEFAULT_HOST, check_exposure, is_loopback, parse_listen
from .livefront import Backend, FrontLimits, FrontStats, LiveFront

__all__ = ["DEFAULT_HOST", "LiveLimits", "LiveView", "check_exposure", "is_loopback", "layout_path", "parse_listen"]

LAYOUT_FILE = "foxglove-layout.json"


def layout_path() -> str:
    """The Foxglove layout shipped with the package (3D scene, camera, loop health, obstacle speed)."""
    from importlib.resources import files

    return str(files("app") / "deploy" / LAYOUT_FILE)


class LineBudget:
    """At most ``lines[kind]`` stderr lines per ``interval_s`` for each kind of report (``client``:
    one client's trouble, which any local user can cause by the thousand; ``state``: the live view's
    own state, rare); the rest are counted and summarised in one line when the interval ends."""

    def __init__(self, emit: Callable[[str, str], None], lines: dict[str, int] | None = None,
                 interval_s: float = 60.0, clock: Callable[[], float] = time.monotonic) -> None:
        self.emit, self.interval_s, self.clock = emit, interval_s, clock
        self.lines = lines or {"client": 5, "state": 10}
        self._lock = threading.Lock()
        self._since = clock()
        self._used: dict[str, int] = {}
        self._held: dict[str, int] = {}
        #: lines not shown since the start (each was counted in a summary line)
        self.suppressed = 0

    def __call__(self, kind: str, level: str, message: str) -> None:
        self.flush()
        with self._lock:
            used = self._used.get(kind, 0)
            self._used[kind] = used + 1
            if used >= self.lines.get(kind, 1):
                self._held[kind] = self._held.get(kind, 0) + 1
                self.suppressed += 1
                return
        self.emit(level, message)

    def flush(self, final: bool = False) -> None:
        """The summary of what was held back, once the interval is over (or now, when ``final``)."""
        with self._lock:
            now = self.clock()
            if now - self._since < self.interval_s and not final:
                return
            held, self._held, self._used, self._since = self._held, {}, {}, now
        if held:
            counts = ", ".join(f"{n} {kind}" for kind, n in sorted(held.items()))
            self.emit("warning", f"live view: {sum(held.values())} more lines not shown in the last "
                                 f"{self.interval_s:g} s ({counts}; counts in the run summary)")


class _SdkLogRoute(logging.Handler):
    """The SDK's own log records (it logs one per client error) into the line budget."""

    def __init__(self, budget: LineBudget) -> None:
        super().__init__(logging.WARNING)
        self.budget = budget

    def emit(self, record: logging.LogRecord) -> None:
        level = "error" if record.levelno >= logging.ERROR else "warning"
        self.budget("client", level, f"live view: SDK: {record.getMessage()}")


class _SdkServer(Backend):
    """The Foxglove SDK's WebSocket server on a private loopback port (only the front connects)."""

    def __init__(self, context: Any) -> None:
        self.context = context
        self._server: Any = None
        self._lock = threading.Lock()

    def start(self) -> None:
        import foxglove

        server = foxglove.start_server(name="vipsm-robot", host="127.0.0.1", port=0, context=self.context,
                                       message_backlog_size=256)
        with self._lock:
            self._server = server

    def port(self) -> int:
        with self._lock:
            if self._server is None:
                raise ConnectionRefusedError("the SDK server is stopped")
            return int(self._server.port)

    def restart(self) -> None:
        with self._lock:
            old, self._server = self._server, None
        if old is not None:
            _stop_within(old, 1.0)
        self.start()

    def stop(self, timeout_s: float) -> bool:
        with self._lock:
            old, self._server = self._server, None
        return old is None or _stop_within(old, timeout_s)


def _stop_within(server: Any, timeout_s: float) -> bool:
    """The SDK server's stop, waited for at most ``timeout_s`` (a daemon thread finishes it)."""
    t = threading.Thread(target=server.stop, name="live-view-sdk-stop", daemon=True)
    t.start()
    t.join(timeout_s)
    return not t.is_alive()


@dataclass(frozen=True)
class LiveLimits(FrontLimits):
    """``live.max_clients``, ``live.handshake_timeout_s``, ``live.send_queue_bytes``, ``live.stall_timeout_s``."""

    @classmethod
    def from_config(cls, live: Any) -> LiveLimits:
        return cls(live.max_clients, live.handshake_timeout_s, live.send_queue_bytes, live.stall_timeout_s)


class LiveView:
    """The field log's SDK context served to viewers through :class:`app.livefront.LiveFront`.

    ``on_event(level, message)`` receives its stderr lines (rate-limited); by default they are
    printed. ``latch(topic, ...)`` makes a topic's last message reach every new subscriber."""

    def __init__(self, context: Any, host: str, port: int, limits: FrontLimits | None = None,
                 on_event: Callable[[str, str], None] | None = None) -> None:
        self.context = context
        self.host = host
        self.requested_port = port
        self.limits = limits or FrontLimits()
        self.on_event = on_event
        self.budget = LineBudget(self._emit)
        self._latched: dict[str, tuple[int, bytes]] = {}
        self._backend = _SdkServer(context)
        self._front: LiveFront | None = None
        self._route: _SdkLogRoute | None = None

    @property
    def port(self) -> int:
        """The port bound (the real one when 0 was asked for), also after ``stop``."""
        return self._front.port if self._front is not None else self.requested_port

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    def _emit(self, level: str, message: str) -> None:
        if self.on_event is not None:
            self.on_event(level, message)
        else:
            print(f"vipsm-robot: {level}: {message}", file=sys.stderr, flush=True)

    def start(self) -> LiveView:
        try:
            self._backend.start()
        except (RuntimeError, OSError) as exc:
            raise AppError(f"live view: the Foxglove SDK server did not start: {exc}") from exc
        self._route = _SdkLogRoute(self.budget)
        sdk_log = logging.getLogger("foxglove")
        sdk_log.addHandler(self._route)
        sdk_log.propagate = False
        front = LiveFront(self.host, self.requested_port, self._backend, self.limits, self.budget,
                          self._latched.get, tick=self.budget.flush)
        try:
            self._front = front.start()
        except AppError as exc:
            self.stop()
            raise AppError(f"{exc} (another program, or another vipsm-robot, uses the port? choose another with "
                           "--live or live.listen; port 0 picks a free one)") from exc
        return self

    def latch(self, topic: str, t_wall_s: float, payload: Any) -> None:
        """``topic``'s last message, sent to each client when it subscribes (a dict is sent as the
        field log's JSON; bytes as they are)."""
        from .fieldlog import encode_json

        data = payload if isinstance(payload, bytes) else encode_json(payload)
        self._latched[topic] = (max(0, int(t_wall_s * 1e9)), data)

    @property
    def state(self) -> str:
        """``ok``, ``degraded`` (accepting fails, e.g. no file descriptors), ``failed``, or ``off``."""
        return self._front.stats.state if self._front is not None else "off"

    def summary(self) -> dict[str, Any]:
        """The counters for the run summary (JSON field ``live_view``)."""
        stats = self._front.stats if self._front is not None else FrontStats(state="off")
        return {"url": self.url, **dataclasses.asdict(stats), "lines_not_shown": self.budget.suppressed}

    def stop(self, timeout_s: float = 1.5) -> None:
        """Within ``timeout_s`` whatever the clients do: connections aborted, the SDK server stopped."""
        deadline = time.monotonic() + timeout_s
        if self._front is not None:
            self._front.stop(timeout_s / 2)
        if not self._backend.stop(max(0.1, deadline - time.monotonic())):
            self._emit("warning", "live view: the SDK server did not stop in time (it ends with the process)")
        if self._route is not None:
            logging.getLogger("foxglove").removeHandler(self._route)
            self._route = None
        self.budget.flush(final=True)
