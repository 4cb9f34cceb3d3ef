"""The test workers' machine lock (``tests/machine_lock.py``): checked without waiting, through
non-blocking attempts on the same files (``flock`` locks of two open files conflict in one process
as in two)."""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

from tests.machine_lock import MachineLock


def _can_lock(path: Path, mode: int) -> bool:
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, mode | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        return False
    finally:
        os.close(fd)


def test_shared_holders_exclude_an_exclusive_run_and_an_exclusive_run_excludes_everyone(tmp_path: Path) -> None:
    lock = MachineLock(tmp_path)
    share, gate = tmp_path / "machine.share", tmp_path / "machine.gate"
    with lock.shared():
        assert _can_lock(share, fcntl.LOCK_SH)  # another test may run beside it
        assert not _can_lock(share, fcntl.LOCK_EX)  # a real-time run may not
        assert _can_lock(gate, fcntl.LOCK_EX)  # the gate is only held while a lock is being taken
    assert _can_lock(share, fcntl.LOCK_EX)
    with MachineLock(tmp_path).exclusive():
        assert not _can_lock(share, fcntl.LOCK_SH) and not _can_lock(gate, fcntl.LOCK_EX)
    assert _can_lock(share, fcntl.LOCK_EX) and _can_lock(gate, fcntl.LOCK_EX)


def test_an_exclusive_run_inside_a_shared_test_gives_its_share_up_for_the_while(tmp_path: Path) -> None:
    lock = MachineLock(tmp_path)
    share = tmp_path / "machine.share"
    with lock.shared():
        with lock.exclusive():  # would wait for itself if it kept its shared lock
            assert not _can_lock(share, fcntl.LOCK_SH)
        assert _can_lock(share, fcntl.LOCK_SH) and not _can_lock(share, fcntl.LOCK_EX)  # shared again


def test_the_session_lock_is_held_shared_during_a_test(machine_lock: MachineLock) -> None:
    assert machine_lock._shared_fd is not None
    assert not _can_lock(machine_lock._share_path, fcntl.LOCK_EX)
