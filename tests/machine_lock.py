"""The machine, shared by the test workers, or had by one test alone.

A few tests run the whole simulated robot in real time: the world (a process that ray-casts the laser
at 40 Hz and renders the camera, about one core) beside the daemon. With the README's two workers on
CI's two cores, the other worker's tests starve that world, its scanner falls behind real time, and
what such a test measures is the machine's load. Every test therefore holds the machine *shared*, and
a real-time run holds it *exclusively* (:meth:`MachineLock.exclusive`): the other worker finishes its
current test and waits until the run is over.

Two ``flock`` files make it writer-preferring: an exclusive holder first takes the gate, so no new test
starts while it waits for the running ones to end. Without xdist (one process) both are free at once.
"""

from __future__ import annotations

import fcntl
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


class MachineLock:
    def __init__(self, directory: Path) -> None:
        directory.mkdir(parents=True, exist_ok=True)
        self._gate_path = directory / "machine.gate"
        self._share_path = directory / "machine.share"
        self._shared_fd: int | None = None

    def _open(self, path: Path) -> int:
        return os.open(path, os.O_RDWR | os.O_CREAT, 0o600)

    @contextmanager
    def shared(self) -> Iterator[None]:
        """Held for one test: waits while a real-time run has the machine or waits for it."""
        gate, share = self._open(self._gate_path), self._open(self._share_path)
        try:
            fcntl.flock(gate, fcntl.LOCK_EX)
            try:
                fcntl.flock(share, fcntl.LOCK_SH)
            finally:
                fcntl.flock(gate, fcntl.LOCK_UN)
            self._shared_fd = share
            yield
        finally:
            self._shared_fd = None
            os.close(share)  # releases its lock
            os.close(gate)

    @contextmanager
    def exclusive(self) -> Iterator[None]:
        """Held for a real-time run: no other test runs meanwhile. Called inside a test that holds the
        machine shared, it gives that up for the while (else it would wait for itself)."""
        own = self._shared_fd
        if own is not None:
            fcntl.flock(own, fcntl.LOCK_UN)
        gate, share = self._open(self._gate_path), self._open(self._share_path)
        try:
            fcntl.flock(gate, fcntl.LOCK_EX)
            fcntl.flock(share, fcntl.LOCK_EX)
            yield
        finally:
            os.close(share)
            os.close(gate)
            if own is not None:
                fcntl.flock(own, fcntl.LOCK_SH)
