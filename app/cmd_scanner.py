"""`vipsm-robot` commands for the Hokuyo UTM-30LX: probe, probe --list, fake scanner, bench.

* ``vipsm-robot probe --scanner URL --json``: VV/PP/II values and a summary of one GD scan
* ``vipsm-robot probe --list --json``: attached URG-family scanners (USB vendor 0x15d1) and their tty
* ``vipsm-robot fake scanner --pty [--link PATH] | --tcp 127.0.0.1:PORT``: serve the fake until Ctrl-C;
  ready (READY=1 to systemd, then its addresses on stdout) only once every endpoint listens
* ``vipsm-robot bench --only scanner --json``: MD frame decode time and driver CPU share at 40 Hz

:func:`to_vipsm_scan` turns a driver :class:`LaserScan` into the estimator's :class:`vipsm.types.Scan`.
"""

from __future__ import annotations

import argparse
import math
import os
import select
import signal
import statistics
import subprocess
import sys
import time
from typing import Any

from drivers.hokuyo_scip import ClientConfig, LaserScan, Utm30lxClient, discover
from drivers.hokuyo_scip.codec import ScanFrame, ScipDecoder
from vipsm.types import Scan

from .errors import AppError


def to_vipsm_scan(scan: LaserScan) -> Scan:
    """The estimator's view of a scan (ranges NaN where invalid, bearings from PP, stamp of step 0)."""
    return Scan(
        ranges_m=scan.ranges_m,
        bearings_rad=scan.bearings_rad,
        stamp_s=scan.stamp_s,
        seq=scan.seq,
        beam_dt_s=scan.beam_dt_s,
        intensities=scan.intensities,
    )


def scan_summary(scan: LaserScan) -> dict[str, Any]:
    valid = scan.ranges_m[scan.valid]
    return {
        "count": int(scan.ranges_m.size),
        "valid_count": int(valid.size),
        "min_range_m": float(valid.min()) if valid.size else None,
        "max_range_m": float(valid.max()) if valid.size else None,
        "first_bearing_rad": float(scan.bearings_rad[0]),
        "last_bearing_rad": float(scan.bearings_rad[-1]),
        "device_stamp_ms": scan.device_stamp_raw_ms,
        "host_stamp_s": scan.host_stamp_s,
        "stamp_s": scan.stamp_s,
        "stamp_from_time_sync": scan.stamp_from_time_sync,
        "beam_dt_s": scan.beam_dt_s,
    }


def probe(args: argparse.Namespace) -> dict[str, Any]:
    """Open the scanner, read VV/PP/II, take one GD scan, switch the laser off again."""
    timeout_s = float(getattr(args, "timeout_s", 5.0) or 5.0)
    config = ClientConfig(reply_timeout_s=max(0.2, min(timeout_s, 2.0)), time_sync_rounds=5)
    with Utm30lxClient(args.scanner, config) as client:
        info = client.info
        scan = client.get_scan(timeout_s=timeout_s)
        offset = client.clock_offset
        out: dict[str, Any] = {
            "url": args.scanner,
            "vv": dict(info.values.get("VV", {})),
            "pp": dict(info.values.get("PP", {})),
            "ii": dict(info.values.get("II", {})),
            "scan": scan_summary(scan),
            "clock_offset_s": None if offset is None else offset.offset_s,
        }
        if info.checksum_fallback_keys:
            out["warnings"] = [f"II {k}: checksum matched only before '<-'" for k in info.checksum_fallback_keys]
    return out


def list_devices(args: argparse.Namespace) -> list[dict[str, Any]]:
    result = discover()
    if result.usb_error:
        print(f"vipsm-robot probe: scanner discovery: {result.usb_error}", file=sys.stderr)
    return [d.as_dict() for d in result.devices]


# ------------------------------------------------------------------------------------ fake


def _parse_host_port(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise AppError(f"--tcp wants HOST:PORT, got {text!r}")
    return host, int(port)


FAKE_DESCRIPTION = """\
Serve a byte-level fake Hokuyo UTM-30LX (SCIP 2.0) until Ctrl-C or SIGTERM.

Readiness: only when every endpoint asked for is listening (the pty open, the TCP port bound and
listening) and the fake answers, it
  1. tells systemd, if NOTIFY_SOCKET is set: READY=1 and STATUS=serving ADDRESS ... (so a
     Type=notify unit, or `systemd-run --service-type=notify`, starts its clients only then), and
  2. prints one line per endpoint on stdout, flushed: first the pty's path (--link if given), then
     socket://HOST:PORT for --tcp, with the port actually bound (--tcp 127.0.0.1:0 picks a free one).
A client that waits for these lines (or for READY=1) never connects before the fake listens. Nothing
is printed or notified when an endpoint cannot be set up (e.g. the port is taken): exit 2 with one
line on stderr. On Ctrl-C or SIGTERM (once its options are read, also before it is ready) it tells systemd
STOPPING=1, closes its endpoints, removes --link and exits 0.
"""


def _cmd_fake(args: argparse.Namespace) -> int:
    from .sdnotify import SystemdNotifier

    if not args.pty and not args.tcp:
        raise AppError("fake scanner needs --pty and/or --tcp HOST:PORT")
    notifier = SystemdNotifier()
    # SIGTERM ends the fake as cleanly as Ctrl-C (the pty link is removed), from the start on
    previous = signal.signal(signal.SIGTERM, _interrupt)
    servers: list[Any] = []
    try:
        _start_fake_servers(args, servers)
        addresses = [s.address for s in servers]
        notifier.notify("READY=1\nSTATUS=serving " + " ".join(addresses))  # every endpoint listens
        for address in addresses:
            print(address, flush=True)
        while all(s.error is None for s in servers):
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)
        notifier.stopping()
        failure = _stop_all(servers)
        notifier.close()
    if failure is not None:
        raise AppError(f"the fake scanner failed: {failure}")
    return 0


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def _start_fake_servers(args: argparse.Namespace, servers: list[Any]) -> None:
    """Every endpoint asked for, listening, its device thread running (appended to ``servers`` as each
    starts, so that the caller stops those already up when a later one fails)."""
    from hil_fakes.transport import DeviceServer, PtyEndpoint, TcpEndpoint
    from hil_fakes.utm30lx import Utm30lxConfig, Utm30lxModel

    config = Utm30lxConfig(initial_time_ms=args.initial_time_ms, laser_on_at_start=not args.laser_off)
    source = None
    if args.scenario:
        from hil_fakes.world import ScenarioError, World, paper_scenario

        try:
            # world time = the fake's clock (time.monotonic), starting now
            source = World(paper_scenario(args.scenario), start_s=time.monotonic()).range_source()
        except ScenarioError as exc:
            raise AppError(f"--scenario {args.scenario}: {exc}") from exc
    if args.pty:
        servers.append(DeviceServer(Utm30lxModel(config, source), PtyEndpoint(args.link)).start())
    if args.tcp:
        host, port = _parse_host_port(args.tcp)
        try:
            endpoint = TcpEndpoint(host, port)
        except OSError as exc:
            raise AppError(f"cannot listen on {args.tcp}: {exc.strerror or exc}") from exc
        servers.append(DeviceServer(Utm30lxModel(config, source), endpoint).start())


def _stop_all(servers: list[Any]) -> str | None:
    """Stops every server (endpoints closed, the link removed); the first model failure, if any."""
    failure = None
    for s in servers:
        try:
            s.stop()
        except RuntimeError as exc:
            failure = failure or f"{exc}: {exc.__cause__!r}"
    return failure


def register_fake(fake_sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = fake_sub.add_parser("scanner", help="fake Hokuyo UTM-30LX (SCIP 2.0) on a pty and/or loopback TCP",
                            description=FAKE_DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--pty", action="store_true", help="serve on a pseudo-terminal (its path is printed)")
    p.add_argument("--link", metavar="PATH", help="stable symlink to the pty (kept across a simulated replug)")
    p.add_argument("--tcp", metavar="HOST:PORT", help="serve on TCP, e.g. 127.0.0.1:10940; port 0 picks a free "
                   "port (the one bound is printed)")
    p.add_argument("--initial-time-ms", type=int, default=4821456, help="the sensor clock at start (24-bit ms)")
    p.add_argument("--laser-off", action="store_true", help="start with the laser off (BM then answers 00)")
    p.add_argument(
        "--scenario",
        choices=("1", "2"),
        help="ranges from the simulated world of the paper's scenario (robot standing still; the cylinder moves) "
        "instead of the fixed room",
    )
    p.set_defaults(func=_cmd_fake)


# ------------------------------------------------------------------------------------ bench


def _percentile(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, max(0, math.ceil(q * len(s)) - 1))]


def _md_frame_bytes(intensity: bool) -> bytes:
    """A full-window frame built by the fake's own encoder (not the codec under test)."""
    from hil_fakes.utm30lx import Utm30lxModel

    model = Utm30lxModel()
    out: list[bytes] = []
    model.attach(out.append)
    model.on_bytes(b"ME0000108001000\n" if intensity else b"MD0000108001000\n", 0.0)
    model.poll(0.03)
    frames = [b for b in out if b"\n99" in b]
    if not frames:
        raise AppError("the fake produced no frame for the benchmark")
    return frames[0]


def bench_decode(intensity: bool = False, repeats: int = 2000) -> dict[str, float]:
    frame = _md_frame_bytes(intensity)
    decoder = ScipDecoder()
    times_us: list[float] = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        events = decoder.feed(frame)
        times_us.append((time.perf_counter() - t0) * 1e6)
        if len(events) != 1 or not isinstance(events[0], ScanFrame):
            raise AppError(f"benchmark frame did not decode: {events!r}")
    return {
        "frame_bytes": len(frame),
        "median_us": statistics.median(times_us),
        "p99_us": _percentile(times_us, 0.99),
    }


def _start_fake_subprocess() -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "app", "fake", "scanner", "--pty"],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], 20.0)
    line = proc.stdout.readline().strip() if ready else ""
    if not line:
        proc.kill()
        proc.wait(5)
        raise AppError("the fake scanner subprocess did not print its device path within 20 s")
    return proc, line


def bench_stream_cpu(duration_s: float = 4.0) -> dict[str, float]:
    """Driver CPU share of one core while streaming MD at 40 Hz from the fake in a subprocess.

    The fake runs in its own process, so this process's ``time.process_time`` (all its threads:
    the reader thread decoding and the consumer taking every scan) is the driver's cost alone.
    """
    proc, path = _start_fake_subprocess()
    try:
        with Utm30lxClient(path, ClientConfig(time_sync_rounds=5)) as client:
            client.start_stream()
            client.next_scan(2.0)  # warm-up: the first frame
            frames = 0
            wall0, cpu0 = time.monotonic(), time.process_time()
            while time.monotonic() - wall0 < duration_s:
                client.next_scan(2.0)
                frames += 1
            wall, cpu = time.monotonic() - wall0, time.process_time() - cpu0
            stats = client.stats
            client.stop_stream()
    finally:
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
    return {
        "duration_s": wall,
        "frames": frames,
        "rate_hz": frames / wall,
        "cpu_percent_of_one_core": 100.0 * cpu / wall,
        "corrupted_frames": stats.corrupted_frames,
        "buffer_drops": stats.buffer_drops,
    }


def bench(args: argparse.Namespace) -> dict[str, Any]:
    return {
        "md_frame_decode": bench_decode(intensity=False),
        "me_frame_decode": bench_decode(intensity=True),
        "stream_md_40hz_pty": bench_stream_cpu(),
        "method": (
            "decode: ScipDecoder.feed on one full-window frame built by the fake, 2000 runs, perf_counter; "
            "stream: fake in a subprocess on a pty, client in this process taking every scan for 4 s; "
            "CPU = time.process_time() of this process / wall time"
        ),
    }
