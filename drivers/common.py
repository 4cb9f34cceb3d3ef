"""Plumbing shared by the three device clients: ports, the newest-wins sample buffer, backoff.

Nothing here knows a protocol. Codecs live in each driver package and never import this module's
I/O parts; clients use it to own their port and hand out samples.
"""

from __future__ import annotations

import collections
import select
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

import serial

from .errors import ConfigError, DisconnectedError, DriverTimeoutError

T = TypeVar("T")


class LatestBuffer(Generic[T]):
    """A bounded buffer where the newest sample wins.

    ``put`` never blocks: when the buffer is full the oldest sample is dropped and counted in
    ``dropped``. ``get`` waits at most ``timeout_s``. ``latest`` returns the newest sample without
    waiting and empties the buffer (older samples it skips are counted as dropped), which is what a
    control loop that wants only the newest scan needs.
    """

    def __init__(self, capacity: int = 4) -> None:
        if capacity < 1:
            raise ConfigError(f"buffer capacity must be >= 1, got {capacity}")
        self._items: collections.deque[T] = collections.deque()
        self._capacity = capacity
        self._cond = threading.Condition()
        self._dropped = 0
        self._put_count = 0
        self._error: BaseException | None = None

    @property
    def dropped(self) -> int:
        """Samples discarded unread because newer ones arrived (or ``latest`` skipped them)."""
        with self._cond:
            return self._dropped

    @property
    def put_count(self) -> int:
        """Samples ever put (delivered or dropped)."""
        with self._cond:
            return self._put_count

    def put(self, item: T) -> None:
        with self._cond:
            if len(self._items) >= self._capacity:
                self._items.popleft()
                self._dropped += 1
            self._items.append(item)
            self._put_count += 1
            self._cond.notify_all()

    def set_error(self, error: BaseException | None) -> None:
        """Surface a background thread's error to the consumer (raised by the next ``get``)."""
        with self._cond:
            self._error = error
            self._cond.notify_all()

    def get(self, timeout_s: float) -> T:
        """Oldest unread sample; raises :class:`DriverTimeoutError` when none came in time.

        If the producer set an error and nothing is buffered, that error is raised instead.
        """
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while not self._items:
                if self._error is not None:
                    raise self._error
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise DriverTimeoutError(f"no sample within {timeout_s:.3f} s")
                self._cond.wait(remaining)
            return self._items.popleft()

    def wait_nonempty(self, timeout_s: float) -> bool:
        """Whether a sample is (or becomes, within ``timeout_s``) available, without taking it."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while not self._items and self._error is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._cond.wait(remaining)
            return bool(self._items)

    def latest(self) -> T | None:
        """Newest sample or None, without waiting; the buffer is emptied."""
        with self._cond:
            if not self._items:
                return None
            item = self._items.pop()
            self._dropped += len(self._items)
            self._items.clear()
            return item

    def clear(self) -> None:
        with self._cond:
            self._items.clear()


@dataclass
class Backoff:
    """Exponential reconnect backoff: ``initial_s``, doubling up to ``max_s``; ``reset`` on success."""

    initial_s: float = 0.1
    max_s: float = 2.0
    factor: float = 2.0
    _next_s: float = 0.0

    def __post_init__(self) -> None:
        if self.initial_s <= 0 or self.max_s < self.initial_s or self.factor < 1.0:
            raise ConfigError("backoff needs 0 < initial_s <= max_s and factor >= 1")
        self._next_s = self.initial_s

    def next_delay(self) -> float:
        delay = self._next_s
        self._next_s = min(self._next_s * self.factor, self.max_s)
        return delay

    def reset(self) -> None:
        self._next_s = self.initial_s


def open_port(
    url: str,
    *,
    baudrate: int = 115200,
    timeout_s: float = 0.05,
    write_timeout_s: float = 1.0,
    exclusive: bool = True,
) -> serial.SerialBase:
    """Open a device by pyserial URL: a tty path (``/dev/ttyACM0``, a pty) or ``socket://host:port``.

    Every read and write on the returned port has a finite timeout. A tty is opened exclusively
    (``flock``), so two clients cannot share one device. Raises :class:`DisconnectedError` when the
    device is absent or busy.
    """
    if timeout_s <= 0 or write_timeout_s <= 0:
        raise ConfigError("port timeouts must be finite and positive")
    kwargs: dict[str, object] = {
        "baudrate": baudrate,
        "timeout": timeout_s,
        "write_timeout": write_timeout_s,
    }
    is_url = "://" in url
    if not is_url:
        kwargs["exclusive"] = exclusive
    try:
        port = serial.serial_for_url(url, **kwargs)
    except (serial.SerialException, OSError, ValueError) as exc:
        raise DisconnectedError(f"cannot open {url}: {exc}") from exc
    return port


def read_some(port: serial.SerialBase, max_bytes: int = 65536) -> bytes:
    """Read what is available (waiting at most the port's timeout); b'' on timeout.

    Raises :class:`DisconnectedError` when the port is gone (EIO on an unplugged tty, a closed
    socket), so readers never spin on a dead link.
    """
    try:
        sock = getattr(port, "_socket", None)
        if sock is not None and port.is_open:
            # pyserial's socket:// reports in_waiting as 0 or 1 (readable or not), which would make
            # this read one byte per call; read what the socket holds instead.
            ready, _, _ = select.select([sock], [], [], port.timeout)
            if not ready:
                return b""
            data = sock.recv(max_bytes)
            if not data:
                raise DisconnectedError("read failed: socket closed by the peer")
            return bytes(data)
        waiting = port.in_waiting
        data = port.read(max(1, min(max_bytes, waiting)))
    except (serial.SerialException, OSError, TypeError, AttributeError, ValueError) as exc:
        raise DisconnectedError(f"read failed: {exc}") from exc
    return bytes(data)


def write_all(port: serial.SerialBase, data: bytes) -> None:
    """Write every byte or raise (:class:`DriverTimeoutError` on a write timeout)."""
    try:
        port.write(data)
        port.flush()
    except serial.SerialTimeoutException as exc:
        raise DriverTimeoutError(f"write of {len(data)} bytes timed out") from exc
    except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
        raise DisconnectedError(f"write failed: {exc}") from exc


def close_quietly(port: serial.SerialBase | None) -> None:
    if port is None:
        return
    try:
        port.close()
    except (serial.SerialException, OSError):
        pass


def run_guarded(target: Callable[[], None], on_error: Callable[[BaseException], None]) -> Callable[[], None]:
    """Wrap a thread body so an unexpected exception is handed to ``on_error``, never lost."""

    def body() -> None:
        try:
            target()
        except BaseException as exc:  # noqa: BLE001 - surfaced to the owner, not swallowed
            on_error(exc)

    return body
