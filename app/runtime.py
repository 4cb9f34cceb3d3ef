"""What ``run`` and ``sim`` share at run time: the progress line, signal handling, the process's
resource usage and the loop's summary (a module of its own, so the two commands import it and not
each other)."""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from typing import Any


class Progress:
    """A one-line progress display, only on a terminal."""

    def __init__(self, total_s: float | None, enabled: bool) -> None:
        self.total_s = total_s
        self.enabled = enabled and sys.stderr.isatty()
        self._last = 0.0

    def __call__(self, text: str, done_s: float) -> None:
        if not self.enabled or time.monotonic() - self._last < 0.25:
            return
        self._last = time.monotonic()
        frac = f" {100 * done_s / self.total_s:5.1f}%" if self.total_s else ""
        sys.stderr.write(f"\r{text}{frac}   ")
        sys.stderr.flush()

    def finish(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")


def install_signal_handlers(stop: threading.Event) -> None:
    def handler(signum: int, frame: Any) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)


def process_usage() -> dict[str, float]:
    import resource

    ru = resource.getrusage(resource.RUSAGE_SELF)
    rss_mb = 0.0
    try:
        with open(f"/proc/{os.getpid()}/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    rss_mb = int(line.split()[1]) / 1024.0
    except OSError:
        rss_mb = ru.ru_maxrss / 1024.0
    return {"cpu_s": ru.ru_utime + ru.ru_stime, "rss_mb": rss_mb, "max_rss_mb": ru.ru_maxrss / 1024.0}


def loop_summary(loop: Any) -> dict[str, Any]:
    s = loop.stats
    out: dict[str, Any] = dict(loop.health.summary())
    out.update(
        {
            "scans": s.scans_in,
            "odometry_samples": s.odometry_in,
            "frames": s.frames_in,
            "frames_used": s.frames_used,
            "estimates": s.estimates,
            "plain_psm_cycles": s.plain_psm_cycles,
            "odometry_fallback_cycles": s.fallback_cycles,
            "device_stop_cycles": s.device_stop_cycles,
            "safety_stop_cycles": s.safety_stop_cycles,
            "log_path": loop.log.path if loop.log is not None else None,
            "log_files": list(loop.log.stats.files) if loop.log is not None else [],
            "log_messages": loop.log.stats.written if loop.log is not None else 0,
            "log_dropped": loop.log.stats.dropped if loop.log is not None else 0,
            "log_bad_messages": loop.log.stats.bad_messages if loop.log is not None else 0,
            "log_error": loop.log.stats.error if loop.log is not None else None,
            "log_state": loop.log.stats.state if loop.log is not None else "off",
            "log_lost_to_disk": loop.log.stats.lost_to_disk if loop.log is not None else 0,
            "log_disk_errors": loop.log.stats.disk_errors if loop.log is not None else 0,
            "log_last_disk_error": loop.log.stats.last_disk_error if loop.log is not None else None,
            "live_url": loop.live_view.url if loop.live_view is not None else None,
            "ros2": loop.ros2.summary() if getattr(loop, "ros2", None) is not None else None,
            "live_view": loop.live_view.summary() if loop.live_view is not None else None,
            "status_server": None if loop.status is None else {
                "host": loop.status.host, "port": loop.status.port, "restarts": loop.status.restarts,
                "last_failure": loop.status.last_failure,
                "refused_writes": loop.status.refused_writes, **loop.status.connection_counts()},
            "events": list(s.state_changes)[-50:],
        }
    )
    out.update(loop.safety_summary())  # protective field and overload figures (app/daemon.py)
    out["devices"] = loop.final_counters or {
        name: dev.counters() for name in ("scanner", "base", "camera") if (dev := getattr(loop, name)) is not None
    }
    return out
