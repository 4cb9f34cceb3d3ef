"""``vipsm-robot ros2-listen`` (the daemon's ROS 2 topics seen without ROS) and ``bench --only ros2``
(the daemon's loop with and without ``--ros2``)."""

from __future__ import annotations

import argparse
import json
import os
import shlex
import signal
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import Any

from .cli import emit
from .errors import AppError

#: the Cyclone DDS config of the bench: loopback only, no multicast (the machine's network stays out)
LOOPBACK_XML = """<?xml version="1.0" encoding="UTF-8" ?>
<CycloneDDS xmlns="https://cdds.io/config">
  <Domain Id="any">
    <General>
      <Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>
      <AllowMulticast>false</AllowMulticast>
    </General>
    <Discovery>
      <Peers><Peer address="127.0.0.1"/></Peers>
      <ParticipantIndex>auto</ParticipantIndex>
    </Discovery>
  </Domain>
</CycloneDDS>
"""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("ros2-listen", help="subscribe to the daemon's ROS 2 topics (no ROS needed) and print "
                                           "what arrived: samples, rate, type, age")
    p.add_argument("--duration", type=float, default=5.0, metavar="S", help="listen this long (default 5 s)")
    p.add_argument("--namespace", default="", help="the daemon's ros2.namespace (default: none)")
    p.add_argument("--domain-id", type=int, default=-1, metavar="N",
                   help="DDS domain (default: ROS_DOMAIN_ID, else 0)")
    p.add_argument("--cyclonedds-config", default="", metavar="FILE.xml",
                   help="Cyclone DDS config (default: CYCLONEDDS_URI, else Cyclone's defaults)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_listen)


def cmd_listen(args: argparse.Namespace) -> int:
    from cyclonedds.core import DDSException

    from .ros2.listen import listen
    from .ros2.publisher import MAX_DOMAIN_ID, cyclone_config_uri, resolve_domain_id
    from .ros2.qos import normalise_namespace
    from .runtime import install_signal_handlers

    if not 0 < args.duration <= 86400:
        raise AppError(f"--duration must be in (0, 86400] s, got {args.duration}")
    if not -1 <= args.domain_id <= MAX_DOMAIN_ID:
        raise AppError(f"--domain-id must be 0-{MAX_DOMAIN_ID} (or -1: ROS_DOMAIN_ID), got {args.domain_id}")
    namespace = normalise_namespace(args.namespace)
    domain_id = resolve_domain_id(args.domain_id)
    uri = cyclone_config_uri(args.cyclonedds_config)
    stop = threading.Event()
    install_signal_handlers(stop)
    try:
        result = listen(namespace, domain_id, uri, args.duration, stop,
                        on_ready=lambda: print("vipsm-robot: info: ros2-listen: listening", file=sys.stderr,
                                               flush=True))
    except DDSException as exc:
        raise AppError(f"ros2-listen: DDS failed: {exc}") from exc
    emit(result, args.json)
    return 0


# ---------------------------------------------------------------------------------------------


def _bench_run(ros2: bool, tmp: Path, domain_id: int, xml: Path) -> dict[str, Any]:
    """The daemon bench's sim (``bench --only daemon``), with ``--ros2`` and a listener in another
    process when ``ros2``."""
    from .cmd_daemon import BENCH_KEYS, BENCH_SIM_ARGV, BENCH_SIM_S, _config
    from .cmd_daemon import register as register_daemon
    from .evaluation.runner import tune_allocator
    from .sim import run_sim

    parser = argparse.ArgumentParser(prog="vipsm-robot")
    register_daemon(parser.add_subparsers())
    extra = (["--ros2", "--set", f"ros2.domain_id={domain_id}", "--set", 'ros2.cyclonedds_config="{xml}"']
             if ros2 else [])
    argv = [*BENCH_SIM_ARGV, *extra, "--duration", str(BENCH_SIM_S)]
    sim_args = parser.parse_args([*(a.replace("{xml}", str(xml)) for a in argv),
                                  "--log", str(tmp / f"bench-{int(ros2)}.mcap")])
    listener = None
    if ros2:
        listener = subprocess.Popen(
            [sys.executable, "-m", "app", "ros2-listen", "--json", "--duration", str(BENCH_SIM_S + 120),
             "--domain-id", str(domain_id), "--cyclonedds-config", str(xml)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env={**os.environ})
        assert listener.stderr is not None
        listener.stderr.readline()  # "listening": its readers exist
    try:
        tune_allocator()
        summary = run_sim(_config(sim_args), sim_args)
    finally:
        heard = None if listener is None else _stopped_listener(listener)
    # the command as run, the bench's loopback config written as LOOPBACK.xml (LOOPBACK_XML)
    command = shlex.join(["vipsm-robot", *(a.replace("{xml}", "LOOPBACK.xml") for a in argv)])
    out: dict[str, Any] = {"command": command, **{k: summary[k] for k in BENCH_KEYS}}
    if ros2:
        r = summary["ros2"]
        out["ros2"] = {k: r[k] for k in ("state", "dropped", "errors")} | {"published": sum(r["published"].values())}
        out["listener"] = heard
    return out


#: how long the bench's listener may take to print its figures and exit after SIGTERM
LISTENER_EXIT_S = 30.0


def _stopped_listener(listener: subprocess.Popen) -> dict[str, Any]:
    """SIGTERM to the listener, then its figures; ``{"error": ...}`` when it fails, prints nothing, or has not
    exited within ``LISTENER_EXIT_S`` (then it is killed: the bench reports the rest rather than hang or
    end in a traceback)."""
    listener.send_signal(signal.SIGTERM)
    try:
        out, err = listener.communicate(timeout=LISTENER_EXIT_S)
    except subprocess.TimeoutExpired:
        listener.kill()
        listener.communicate(timeout=10)
        return {"error": f"the listener did not exit within {LISTENER_EXIT_S:g} s of SIGTERM (killed)"}
    if listener.returncode != 0:
        return {"error": f"the listener exited with {listener.returncode}: {err[-500:]}"}
    try:
        return json.loads(out)
    except json.JSONDecodeError:
        return {"error": f"the listener printed no JSON: {out[-200:]!r}"}


def bench(args: argparse.Namespace) -> dict[str, Any]:
    """The daemon's 40 Hz loop against the simulated devices without, then with ``--ros2`` (every
    topic read by a listener in another process over loopback): deadline misses, latency, CPU."""
    load_1min = os.getloadavg()[0]
    domain_id = 150 + os.getpid() % 80  # a domain of its own: other DDS users on the machine stay apart
    with tempfile.TemporaryDirectory(prefix="vipsm-bench-ros2-") as tmp:
        xml = Path(tmp) / "cyclonedds.xml"
        xml.write_text(LOOPBACK_XML, encoding="utf-8")
        without = _bench_run(False, Path(tmp), domain_id, xml)
        with_ros2 = _bench_run(True, Path(tmp), domain_id, xml)
    return {"without_ros2": without, "with_ros2": with_ros2, "load_average_1min": round(load_1min, 2)}
