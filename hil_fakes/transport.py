"""Byte transports and the device loop shared by the fake devices.

A fake device is a :class:`DeviceModel`: it is fed the bytes the host wrote and is polled on its
own clock; whatever it emits goes through a :class:`FaultInjector` to an :class:`Endpoint`.

Endpoints:

* :class:`PtyEndpoint` serves on a pseudo-terminal (``os.openpty``): a real tty, so baud settings,
  exclusive opens and hang-ups behave as on hardware. An optional stable symlink (like the udev
  names ``/dev/hokuyo``) points at the current slave; ``unplug()`` closes the pty (the client sees
  the device vanish) and opens a fresh one behind the same symlink, as a USB replug would.
* :class:`TcpEndpoint` serves one client at a time on a loopback TCP port; a new connection
  replaces the old one.

Nothing here knows a protocol, and nothing here imports the drivers: the fakes are independent
models of the devices.
"""

from __future__ import annotations

import errno
import os
import select
import socket
import termios
import threading
import time
import tty
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

Clock = Callable[[], float]

_TERMIOS_BPS = {
    getattr(termios, f"B{r}"): r
    for r in (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 921600)
    if hasattr(termios, f"B{r}")
}

# Longest the device loop blocks on input before polling the model again.
_MAX_IDLE_S = 0.005


class Endpoint(ABC):
    """One byte stream to one host at a time."""

    #: bytes the model emitted while no client was there to read them
    dropped_no_client: int = 0

    @property
    @abstractmethod
    def address(self) -> str:
        """What a client opens: a device path or ``socket://host:port``."""

    @abstractmethod
    def read(self, timeout_s: float) -> bytes:
        """Bytes from the host, b'' when none came within ``timeout_s`` or no client is there."""

    @abstractmethod
    def write(self, data: bytes) -> None:
        """Send to the host; bytes are dropped (and counted) when no client is connected."""

    @property
    @abstractmethod
    def connected(self) -> bool:
        """Whether a client holds the device open right now."""

    @abstractmethod
    def unplug(self) -> None:
        """Drop the client as a cable pull would; the device can be opened again afterwards."""

    @abstractmethod
    def close(self) -> None:
        """Stop serving for good."""


class PtyEndpoint(Endpoint):
    """A pseudo-terminal; ``address`` is the stable symlink if one was asked for, else the slave."""

    def __init__(self, link_path: str | None = None) -> None:
        self._link_path = link_path
        self._lock = threading.Lock()
        self._master = -1
        self._slave_name = ""
        self.dropped_no_client = 0
        self._open_pty()

    def _open_pty(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)
        self._slave_name = os.ttyname(slave)
        os.close(slave)
        os.set_blocking(master, False)
        self._master = master
        if self._link_path:
            tmp = f"{self._link_path}.{os.getpid()}.tmp"
            if os.path.lexists(tmp):
                os.unlink(tmp)
            os.symlink(self._slave_name, tmp)
            os.replace(tmp, self._link_path)

    @property
    def address(self) -> str:
        return self._link_path or self._slave_name

    @property
    def slave_name(self) -> str:
        return self._slave_name

    def line_speed_bps(self) -> int | None:
        """The bit rate the host set on its end of the pty (Linux reports the slave's termios through
        the master), so a fake can model a wrong baud rate; None when closed or not a standard rate."""
        fd = self._master
        if fd < 0:
            return None
        try:
            speed = termios.tcgetattr(fd)[5]
        except (termios.error, OSError):
            return None
        return _TERMIOS_BPS.get(speed)

    @property
    def connected(self) -> bool:
        with self._lock:
            if self._master < 0:
                return False
            p = select.poll()
            p.register(self._master, select.POLLIN | select.POLLHUP)
            events = p.poll(0)
        return not any(ev & select.POLLHUP for _, ev in events)

    def read(self, timeout_s: float) -> bytes:
        master = self._master
        if master < 0:
            time.sleep(timeout_s)
            return b""
        try:
            ready, _, _ = select.select([master], [], [], timeout_s)
        except (OSError, ValueError):
            return b""
        if not ready:
            return b""
        try:
            return os.read(master, 65536)
        except BlockingIOError:
            return b""
        except OSError as exc:
            if exc.errno in (errno.EIO, errno.EBADF):
                # No client holds the slave open: the pty reports hang-up until one does.
                time.sleep(timeout_s)
                return b""
            raise

    def write(self, data: bytes) -> None:
        if not data:
            return
        if not self.connected:
            self.dropped_no_client += len(data)
            return
        view = memoryview(data)
        deadline = time.monotonic() + 0.5
        while view:
            master = self._master
            if master < 0:
                self.dropped_no_client += len(view)
                return
            try:
                n = os.write(master, view)
                view = view[n:]
            except BlockingIOError:
                # The client is not reading fast enough; wait a little, then give up on the rest,
                # as a device's USB buffer would overflow.
                if time.monotonic() > deadline:
                    self.dropped_no_client += len(view)
                    return
                select.select([], [master], [], 0.01)
            except OSError:
                self.dropped_no_client += len(view)
                return

    def unplug(self) -> None:
        with self._lock:
            old = self._master
            self._master = -1
            if old >= 0:
                os.close(old)
            self._open_pty()

    def close(self) -> None:
        with self._lock:
            if self._master >= 0:
                os.close(self._master)
                self._master = -1
        if self._link_path and os.path.islink(self._link_path):
            os.unlink(self._link_path)


class TcpEndpoint(Endpoint):
    """A loopback TCP server holding one client at a time (port 0 picks a free port)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0) -> None:
        self._listener = socket.create_server((host, port), reuse_port=False)
        self._listener.setblocking(False)
        self._host, self._port = self._listener.getsockname()[:2]
        self._client: socket.socket | None = None
        self._lock = threading.Lock()
        self.dropped_no_client = 0
        #: number of client connections accepted so far
        self.accepted = 0

    @property
    def address(self) -> str:
        return f"socket://{self._host}:{self._port}"

    @property
    def port(self) -> int:
        return int(self._port)

    @property
    def connected(self) -> bool:
        return self._client is not None

    def _accept_pending(self) -> None:
        try:
            conn, _ = self._listener.accept()
        except (BlockingIOError, OSError):
            return
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        conn.settimeout(1.0)
        with self._lock:
            old, self._client = self._client, conn
            self.accepted += 1
        if old is not None:
            old.close()

    def read(self, timeout_s: float) -> bytes:
        watch: list[socket.socket] = [self._listener]
        client = self._client
        if client is not None:
            watch.append(client)
        try:
            ready, _, _ = select.select(watch, [], [], timeout_s)
        except (OSError, ValueError):
            return b""
        if self._listener in ready:
            self._accept_pending()
        if client is not None and client in ready:
            try:
                data = client.recv(65536)
            except (OSError, TimeoutError):
                data = b""
            if not data:
                self._drop_client(client)
            return data
        return b""

    def _drop_client(self, client: socket.socket) -> None:
        with self._lock:
            if self._client is client:
                self._client = None
        try:
            client.close()
        except OSError:
            pass

    def write(self, data: bytes) -> None:
        client = self._client
        if client is None:
            self.dropped_no_client += len(data)
            return
        try:
            client.sendall(data)
        except (OSError, TimeoutError):
            self.dropped_no_client += len(data)
            self._drop_client(client)

    def unplug(self) -> None:
        client = self._client
        if client is not None:
            try:
                client.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            self._drop_client(client)

    def close(self) -> None:
        self.unplug()
        self._listener.close()


@dataclass
class FaultStats:
    corrupted: int = 0
    dropped_bytes: int = 0
    junk_bytes: int = 0
    split_writes: int = 0
    stalls: int = 0
    disconnects: int = 0


class FaultInjector:
    """Stream faults applied to what a device emits; all methods are thread-safe.

    * ``corrupt(n)``: the next ``n`` emitted chunks each get one byte bit-flipped (so a checksum
      or a framing byte breaks); ``position`` picks the byte (default: the middle of the chunk).
    * ``drop(n)``: the next ``n`` emitted bytes vanish.
    * ``split(chunk, delay_s, writes)``: the next ``writes`` chunks go out ``chunk`` bytes at a time.
    * ``junk(data)``: garbage bytes go out at once.
    * ``stall(seconds)``: the device goes silent (its output is discarded, its input ignored).
    * ``disconnect()``: the endpoint is unplugged.
    """

    def __init__(self, endpoint: Endpoint, clock: Clock = time.monotonic) -> None:
        self._endpoint = endpoint
        self._clock = clock
        self._lock = threading.Lock()
        self._corrupt_left = 0
        self._corrupt_position: int | None = None
        self._drop_left = 0
        self._split_left = 0
        self._split_chunk = 1
        self._split_delay_s = 0.0
        self._stall_until = -1.0
        self.stats = FaultStats()

    def corrupt(self, count: int = 1, position: int | None = None) -> None:
        with self._lock:
            self._corrupt_left += count
            self._corrupt_position = position

    def drop(self, count_bytes: int) -> None:
        with self._lock:
            self._drop_left += count_bytes

    def split(self, chunk_bytes: int = 1, delay_s: float = 0.0, writes: int = 1) -> None:
        with self._lock:
            self._split_left = writes
            self._split_chunk = max(1, chunk_bytes)
            self._split_delay_s = delay_s

    def junk(self, data: bytes) -> None:
        with self._lock:
            self.stats.junk_bytes += len(data)
        self._endpoint.write(data)

    def stall(self, seconds: float) -> None:
        with self._lock:
            self._stall_until = self._clock() + seconds
            self.stats.stalls += 1

    def disconnect(self) -> None:
        with self._lock:
            self.stats.disconnects += 1
        self._endpoint.unplug()

    @property
    def stalled(self) -> bool:
        return self._clock() < self._stall_until

    def send(self, data: bytes) -> None:
        if not data or self.stalled:
            return
        with self._lock:
            if self._drop_left:
                n = min(self._drop_left, len(data))
                self._drop_left -= n
                self.stats.dropped_bytes += n
                data = data[n:]
                if not data:
                    return
            if self._corrupt_left:
                self._corrupt_left -= 1
                pos = self._corrupt_position
                pos = len(data) // 2 if pos is None else min(max(pos, 0), len(data) - 1)
                buf = bytearray(data)
                buf[pos] ^= 0x01
                data = bytes(buf)
                self.stats.corrupted += 1
            split = self._split_left > 0
            if split:
                self._split_left -= 1
                self.stats.split_writes += 1
                chunk, delay = self._split_chunk, self._split_delay_s
        if not split:
            self._endpoint.write(data)
            return
        for i in range(0, len(data), chunk):
            self._endpoint.write(data[i : i + chunk])
            if delay > 0:
                time.sleep(delay)


class DeviceModel(ABC):
    """A device's behaviour: fed host bytes, polled on its own clock, emits through ``emit``."""

    def __init__(self) -> None:
        self._emit: Callable[[bytes], None] = lambda data: None

    def attach(self, emit: Callable[[bytes], None]) -> None:
        self._emit = emit

    def emit(self, data: bytes) -> None:
        self._emit(data)

    @abstractmethod
    def on_bytes(self, data: bytes, now_s: float) -> None:
        """Bytes the host wrote."""

    def poll(self, now_s: float) -> float | None:
        """Advance to ``now_s``; return when the model next needs polling (None: on input only)."""
        return None

    def on_client_change(self, connected: bool, now_s: float) -> None:
        """A client opened (True) or let go of (False) the device; the default ignores it."""
        return None


class DeviceServer:
    """Runs one :class:`DeviceModel` on one :class:`Endpoint` in a background thread.

    An exception inside the model stops the server and is kept in ``error`` (and re-raised by
    :meth:`stop`), so a broken fake is never mistaken for a silent device.
    """

    def __init__(self, model: DeviceModel, endpoint: Endpoint, clock: Clock = time.monotonic) -> None:
        self.model = model
        self.endpoint = endpoint
        self.clock = clock
        self.faults = FaultInjector(endpoint, clock)
        self.bytes_in = 0
        self.bytes_out = 0
        self.error: BaseException | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        model.attach(self._send)

    @property
    def address(self) -> str:
        return self.endpoint.address

    def _send(self, data: bytes) -> None:
        self.bytes_out += len(data)
        self.faults.send(data)

    def start(self) -> DeviceServer:
        self._thread = threading.Thread(target=self._run, name=f"fake-{type(self.model).__name__}", daemon=True)
        self._thread.start()
        return self

    def _run(self) -> None:
        was_connected = False
        try:
            while not self._stop.is_set():
                now = self.clock()
                connected = self.endpoint.connected
                if connected != was_connected:
                    self.model.on_client_change(connected, now)
                    was_connected = connected
                next_due = self.model.poll(now)
                wait = _MAX_IDLE_S if next_due is None else min(_MAX_IDLE_S, max(0.0, next_due - self.clock()))
                data = self.endpoint.read(wait)
                if data and not self.faults.stalled:
                    self.bytes_in += len(data)
                    self.model.on_bytes(data, self.clock())
        except BaseException as exc:  # noqa: BLE001 - kept and re-raised by stop()
            self.error = exc

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.endpoint.close()
        if self.error is not None:
            raise RuntimeError(f"fake device {type(self.model).__name__} failed") from self.error

    def __enter__(self) -> DeviceServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def wait_forever(servers: list[DeviceServer], poll_s: float = 0.2) -> None:
    """Block until Ctrl-C (or a server fails), for the ``vipsm-robot fake ...`` commands."""
    try:
        while all(s.error is None for s in servers):
            time.sleep(poll_s)
    except KeyboardInterrupt:
        pass
    finally:
        for s in servers:
            s.stop()
