"""The live view's front: the only socket viewers reach. It accepts on ``live.listen``, checks each
WebSocket upgrade, and relays it to the Foxglove SDK's server, which listens on a private loopback
port and so only ever sees the front's connections (read promptly, closed cleanly).

Why a front: the SDK server (0.30) has no client cap, no handshake timeout, a per-client queue of
messages (not bytes) that a client that stops reading fills, and a shutdown that waits for such
clients; it accepts only the subprotocol ``foxglove.sdk.v1``. The front gives, in one asyncio thread:

* at most ``max_clients`` connections (a handshake under way counts); more get HTTP 503 at once;
* the upgrade request complete within ``handshake_timeout_s``, else closed;
* a bounded send queue per client: Message Data (the data plane) is dropped for a client whose
  queue holds ``send_queue_bytes`` or more; a client whose queue passes twice that, or stays full
  for ``stall_timeout_s``, is disconnected. Both are counted;
* ``foxglove.websocket.v1`` (the same protocol under its older name) served as ``foxglove.sdk.v1``;
* latched topics: the last message of such a topic sent to each new subscriber;
* accept failures (out of file descriptors) reported and retried; the SDK server restarted when
  it stops answering;
* ``stop`` aborts every connection and returns within its timeout whatever the clients do.
"""

from __future__ import annotations

import asyncio
import json
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from . import wsframes as wf
from .errors import AppError

#: the largest frame a viewer may send (subscribe lists, parameters); the SDK's own frames (camera
#: images) may be larger
MAX_CLIENT_FRAME_BYTES = 1 << 20
MAX_SERVER_FRAME_BYTES = 64 << 20
READ_BYTES = 256 * 1024


@dataclass(frozen=True)
class FrontLimits:
    max_clients: int = 8
    handshake_timeout_s: float = 5.0
    send_queue_bytes: int = 1 << 20
    stall_timeout_s: float = 10.0


@dataclass
class FrontStats:
    #: "ok", "degraded" (accepting fails, e.g. out of file descriptors; retried every second),
    #: "failed" (the SDK server could not be restarted; retried at the next connection); after
    #: ``stop`` the last state while running
    state: str = "ok"
    clients: int = 0
    served: int = 0
    refused_full: int = 0
    handshake_failures: int = 0
    slow_disconnects: int = 0
    dropped_messages: int = 0
    accept_errors: int = 0
    backend_errors: int = 0
    backend_restarts: int = 0
    last_failure: str | None = None


@dataclass(eq=False)
class _Conn:
    peer: str
    writer: asyncio.StreamWriter
    backend: asyncio.StreamWriter | None = None
    backend_reader: asyncio.StreamReader | None = None
    #: the SDK's frames as they arrive (one reader for the connection's whole byte stream)
    frames: wf.FrameReader = field(default_factory=lambda: wf.FrameReader(MAX_SERVER_FRAME_BYTES))
    #: the SDK's channel ids -> topics (from its advertise messages)
    topics: dict[int, str] = field(default_factory=dict)
    full_since: float | None = None
    closed: bool = False
    #: the SDK server's restarts counted when this connection reached for it
    generation: int = 0

    def queued(self) -> int:
        return 0 if self.writer.transport.is_closing() else self.writer.transport.get_write_buffer_size()


class Backend:
    """What the front needs of the SDK server: its loopback port, and a restart when it is gone."""

    def port(self) -> int:
        raise NotImplementedError

    def restart(self) -> None:
        raise NotImplementedError


class LiveFront:
    """See the module docstring. ``report(kind, level, message)``: kind ``client`` (one client's
    trouble; many) or ``state`` (the front's own state; few)."""

    def __init__(self, host: str, port: int, backend: Backend, limits: FrontLimits,
                 report: Callable[[str, str, str], None], latched: Callable[[str], tuple[int, bytes] | None],
                 tick: Callable[[], None] = lambda: None) -> None:
        self.host, self.requested_port = host, port
        self.backend, self.limits = backend, limits
        self.report, self.latched, self.tick = report, latched, tick
        self.stats = FrontStats()
        self._conns: set[_Conn] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: asyncio.base_events.Server | None = None
        self._thread: threading.Thread | None = None
        self._bound_port = port
        self._restart_lock = asyncio.Lock()
        self._stopping = False
        #: SDK handshakes in a row that got no answer
        self._no_answer = 0

    @property
    def port(self) -> int:
        return self._bound_port

    def queued_bytes(self) -> int:
        """Bytes waiting in every client's send queue now."""
        return sum(c.queued() for c in list(self._conns))

    # -- start / stop ----------------------------------------------------------------------------

    def start(self, timeout_s: float = 5.0) -> LiveFront:
        ready = threading.Event()
        failure: list[BaseException] = []

        def run() -> None:
            loop = asyncio.new_event_loop()
            self._loop = loop
            loop.set_exception_handler(self._loop_error)
            try:
                self._server = loop.run_until_complete(self._listen())
            except OSError as exc:
                failure.append(exc)
                ready.set()
                loop.close()
                return
            ready.set()
            loop.create_task(self._housekeeping())
            try:
                loop.run_forever()
            finally:
                _finish(loop)

        self._thread = threading.Thread(target=run, name="live-view", daemon=True)
        self._thread.start()
        if not ready.wait(timeout_s):
            raise AppError(f"live view on {self.host}:{self.requested_port}: not listening after {timeout_s:g} s")
        if failure:
            exc = failure[0]
            raise AppError(f"live view on {self.host}:{self.requested_port} failed: {exc}") from exc
        return self

    async def _listen(self) -> asyncio.base_events.Server:
        server = await asyncio.start_server(self._serve, self.host, self.requested_port, limit=READ_BYTES,
                                            backlog=128)
        self._bound_port = server.sockets[0].getsockname()[1]
        return server

    def stop(self, timeout_s: float = 1.0) -> None:
        """Every connection aborted (nothing waits for a client), the thread ended within ``timeout_s``."""
        loop, thread = self._loop, self._thread
        if loop is None or thread is None or loop.is_closed():
            return
        try:
            loop.call_soon_threadsafe(self._shutdown_now)
        except RuntimeError:  # the loop closed meanwhile
            return
        thread.join(timeout_s)
        self._thread = None

    def _shutdown_now(self) -> None:
        assert self._loop is not None
        self._stopping = True
        if self._server is not None:
            self._server.close()
        for conn in list(self._conns):
            self._abort(conn)
        self._loop.stop()

    # -- errors the event loop catches (accept failing for want of file descriptors) -------------

    def _loop_error(self, loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
        exc = context.get("exception")
        message = str(context.get("message", "error"))
        if self._stopping:  # tasks cancelled by stop: nothing went wrong
            return
        if "accept" in message:  # asyncio stops accepting for 1 s, then retries by itself
            self.stats.accept_errors += 1
            self.stats.last_failure = f"accept failed: {exc}"
            if self.stats.state == "ok":
                self.stats.state = "degraded"
                self.report("state", "error", f"live view: cannot accept connections ({exc}); retrying every "
                                              "second (raise the file-descriptor limit, LimitNOFILE=)")
            return
        self.stats.last_failure = f"{message}: {exc}" if exc else message
        self.report("client", "warning", f"live view: {self.stats.last_failure}")

    def _accepted(self) -> None:
        if self.stats.state == "degraded":
            self.stats.state = "ok"
            self.report("state", "info", f"live view: accepting connections again (after "
                                         f"{self.stats.accept_errors} failed accepts)")

    # -- one connection ----------------------------------------------------------------------------

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self._accepted()
        peer = _peer(writer)
        if len(self._conns) >= self.limits.max_clients:
            self.stats.refused_full += 1
            self.report("client", "warning", f"live view: {peer} refused: {self.limits.max_clients} clients "
                                             "already (live.max_clients)")
            writer.write(wf.http_error(503, f"live view full: {self.limits.max_clients} clients (live.max_clients)"))
            _close(writer.transport)
            return
        conn = _Conn(peer, writer)
        self._conns.add(conn)
        self.stats.clients = len(self._conns)
        try:
            if await self._handshake(conn, reader):
                await self._relay(conn, reader)
        except (OSError, asyncio.IncompleteReadError, wf.FrameError) as exc:
            self.report("client", "info", f"live view: {peer} closed ({_why(exc)})")
        finally:
            self._abort(conn)
            self._conns.discard(conn)
            self.stats.clients = len(self._conns)

    async def _handshake(self, conn: _Conn, reader: asyncio.StreamReader) -> bool:
        deadline = time.monotonic() + self.limits.handshake_timeout_s
        try:
            head, rest = await asyncio.wait_for(_read_head(reader), self.limits.handshake_timeout_s)
            req = wf.parse_request_head(head)
            ask, answer = wf.choose_subprotocol(req.values("Sec-WebSocket-Protocol"))
        except (TimeoutError, wf.HandshakeError, asyncio.IncompleteReadError) as exc:
            self.stats.handshake_failures += 1
            if isinstance(exc, wf.HandshakeError):
                conn.writer.write(wf.http_error(exc.status, exc.reason))
            self.report("client", "info", f"live view: {conn.peer} refused ({_why(exc)})")
            return False
        b_reader = await self._connect_backend(conn, max(0.1, deadline - time.monotonic()))
        if b_reader is None:
            return False
        assert conn.backend is not None
        conn.backend.write(wf.backend_request(req, ask) + rest)
        try:
            resp, extra = await asyncio.wait_for(_read_head(b_reader), max(0.5, deadline - time.monotonic()))
        except (TimeoutError, asyncio.IncompleteReadError, wf.HandshakeError) as exc:
            self._no_answer += 1  # a busy machine may be slow once; three in a row: the server is stuck
            if self._no_answer >= 3:
                await self._backend_failed(conn, f"no handshake answer ({_why(exc)})", conn.generation)
            else:
                self.stats.backend_errors += 1
                conn.writer.write(wf.http_error(503, "live view busy, try again"))
            return False
        self._no_answer = 0
        conn.writer.write(wf.rename_response_subprotocol(resp, answer))
        if wf.response_status(resp) != 101:
            self.stats.handshake_failures += 1
            return False
        self.stats.served += 1
        conn.backend_reader = b_reader
        self._from_backend(conn, extra)
        return True

    async def _connect_backend(self, conn: _Conn, timeout_s: float) -> asyncio.StreamReader | None:
        async with self._restart_lock:  # not while the SDK server is being restarted
            conn.generation = self.stats.backend_restarts
        try:
            b_reader, conn.backend = await asyncio.wait_for(
                asyncio.open_connection("127.0.0.1", self.backend.port(), limit=READ_BYTES), timeout_s)
        except ConnectionRefusedError:
            await self._backend_failed(conn, "connection refused", conn.generation)
            return None
        except (OSError, TimeoutError) as exc:  # EMFILE here: out of file descriptors
            self.stats.backend_errors += 1
            self.stats.last_failure = f"SDK server unreachable: {_why(exc)}"
            conn.writer.write(wf.http_error(503, "live view busy, try again"))
            self.report("client", "warning", f"live view: {conn.peer} not served: SDK server unreachable "
                                             f"({_why(exc)})")
            return None
        return b_reader

    async def _backend_failed(self, conn: _Conn, why: str, generation: int) -> None:
        """The SDK server refused or did not answer: started anew (its listener may be gone), once
        for all the connections that found the same server failing (``generation``)."""
        self.stats.backend_errors += 1
        self.stats.last_failure = f"SDK server: {why}"
        conn.writer.write(wf.http_error(503, "live view restarting, try again"))
        async with self._restart_lock:
            if self.stats.backend_restarts != generation:
                return  # restarted meanwhile
            self.report("state", "error", f"live view: the SDK server failed ({why}); restarting it")
            assert self._loop is not None
            try:
                await asyncio.wait_for(self._loop.run_in_executor(None, self.backend.restart), 5.0)
                self.stats.backend_restarts += 1
                self._no_answer = 0
                if self.stats.state == "failed":
                    self.stats.state = "ok"
            except Exception as exc:  # noqa: BLE001 - any failure of the SDK is reported, the front stays
                self.stats.state = "failed"  # the next viewer that connects tries again
                self.stats.last_failure = f"SDK server restart failed: {_why(exc)}"
                self.report("state", "error", f"live view: {self.stats.last_failure}")

    async def _relay(self, conn: _Conn, reader: asyncio.StreamReader) -> None:
        down = asyncio.ensure_future(self._pump_down(conn))
        up = asyncio.ensure_future(self._pump_up(conn, reader))
        done, pending = await asyncio.wait({down, up}, return_when=asyncio.FIRST_COMPLETED)
        for task in pending:
            task.cancel()
        for task in done:
            if (exc := task.exception()) is not None:
                raise exc

    async def _pump_down(self, conn: _Conn) -> None:
        """SDK -> viewer: never waits for the viewer (its queue is bounded by dropping, then closing)."""
        assert conn.backend_reader is not None
        while not conn.closed and (data := await conn.backend_reader.read(READ_BYTES)):
            self._from_backend(conn, data)

    def _from_backend(self, conn: _Conn, data: bytes) -> None:
        for frame in conn.frames.feed(data):
            if frame.opcode == wf.OP_TEXT and frame.fin:
                _note_channels(conn, frame.payload)
            self._send(conn, frame.raw, droppable=frame.is_message_data())
            if conn.closed:
                return

    def _send(self, conn: _Conn, raw: bytes, droppable: bool) -> None:
        if conn.writer.transport.is_closing():  # the viewer left: writing on would log a line per write
            self._abort(conn)
            return
        queued = conn.queued()
        limit = self.limits.send_queue_bytes
        if droppable and queued >= limit:
            self.stats.dropped_messages += 1
            self._check_stall(conn, queued)
            return
        conn.writer.write(raw)
        queued += len(raw)
        if queued > 2 * limit:
            self._slow(conn, f"{queued} bytes unsent")
        else:
            self._check_stall(conn, queued)

    def _check_stall(self, conn: _Conn, queued: int) -> None:
        now = time.monotonic()
        if queued < self.limits.send_queue_bytes:
            conn.full_since = None
        elif conn.full_since is None:
            conn.full_since = now
        elif now - conn.full_since > self.limits.stall_timeout_s:
            self._slow(conn, f"not reading for {self.limits.stall_timeout_s:g} s")

    def _slow(self, conn: _Conn, why: str) -> None:
        self.stats.slow_disconnects += 1
        self.report("client", "warning", f"live view: {conn.peer} disconnected: too slow ({why})")
        self._abort(conn)

    async def _pump_up(self, conn: _Conn, reader: asyncio.StreamReader) -> None:
        """Viewer -> SDK; a subscription to a latched topic gets that topic's last message at once."""
        frames = wf.FrameReader(MAX_CLIENT_FRAME_BYTES)
        assert conn.backend is not None
        while not conn.closed and (data := await reader.read(READ_BYTES)):
            for frame in frames.feed(data):
                conn.backend.write(frame.raw)
                if frame.opcode == wf.OP_TEXT and frame.fin:
                    for raw in self._latched_for(conn, frame.payload):
                        self._send(conn, raw, droppable=False)
            await asyncio.wait_for(conn.backend.drain(), self.limits.stall_timeout_s)

    def _latched_for(self, conn: _Conn, payload: bytes) -> list[bytes]:
        try:
            msg = json.loads(payload)
            subs = msg["subscriptions"] if msg.get("op") == "subscribe" else []
            pairs = [(int(s["id"]), int(s["channelId"])) for s in subs]
        except (ValueError, TypeError, KeyError, AttributeError):
            return []  # the SDK answers a malformed message itself
        out = []
        for sub_id, channel_id in pairs:
            latched = self.latched(conn.topics.get(channel_id, ""))
            if latched is not None and 0 <= sub_id < 1 << 32:
                out.append(wf.message_data_frame(sub_id, *latched))
        return out

    def _abort(self, conn: _Conn) -> None:
        if conn.closed:
            return
        conn.closed = True
        _close(conn.writer.transport)
        if conn.backend is not None:  # a close frame first, so the SDK sees a normal goodbye
            if not conn.backend.transport.is_closing():
                conn.backend.write(wf.client_close_frame(os.urandom(4)))
                conn.backend.close()

    async def _housekeeping(self) -> None:
        """Twice a second: clients stalled with no traffic flowing are found; the report is flushed."""
        while True:
            await asyncio.sleep(0.5)
            for conn in list(self._conns):
                if not conn.closed and conn.backend is not None:
                    self._check_stall(conn, conn.queued())
            self.tick()


def _note_channels(conn: _Conn, payload: bytes) -> None:
    try:
        msg = json.loads(payload)
        if msg.get("op") == "advertise":
            conn.topics.update({int(c["id"]): str(c["topic"]) for c in msg["channels"]})
        elif msg.get("op") == "unadvertise":
            for cid in msg["channelIds"]:
                conn.topics.pop(int(cid), None)
    except (ValueError, TypeError, KeyError, AttributeError):
        pass  # not a message the front needs


def _finish(loop: asyncio.AbstractEventLoop) -> None:
    """The loop's tasks cancelled and given a moment (bounded) to end; the loop closed."""
    tasks = asyncio.all_tasks(loop)
    for task in tasks:
        task.cancel()
    if tasks:
        loop.run_until_complete(asyncio.wait(tasks, timeout=0.5))
    loop.close()


async def _read_head(reader: asyncio.StreamReader) -> tuple[bytes, bytes]:
    """An HTTP head and the bytes read past it."""
    buf = bytearray()
    while (end := wf.head_end(buf)) < 0:
        data = await reader.read(4096)
        if not data:
            raise asyncio.IncompleteReadError(bytes(buf), None)
        buf += data
    return bytes(buf[:end]), bytes(buf[end:])


def _close(transport: asyncio.BaseTransport) -> None:
    """Closed now: what is unsent is discarded (a close would wait for a client that does not read)."""
    if isinstance(transport, asyncio.WriteTransport) and transport.get_write_buffer_size():
        transport.abort()
    else:
        transport.close()


def _peer(writer: asyncio.StreamWriter) -> str:
    peer = writer.get_extra_info("peername")
    return f"{peer[0]}:{peer[1]}" if isinstance(peer, tuple) and len(peer) >= 2 else "a client"


def _why(exc: BaseException) -> str:
    if isinstance(exc, TimeoutError):
        return "timed out"
    if isinstance(exc, asyncio.IncompleteReadError):
        return "closed early"
    return str(exc) or type(exc).__name__
