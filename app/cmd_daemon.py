"""``vipsm-robot run | sim | replay | dump-config``: the daemon and its simulated and replayed runs."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shlex
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from .cli import emit
from .config import Config, dump_toml, load_config
from .errors import AppError
from .runtime import Progress, install_signal_handlers, loop_summary

#: ``run --duration``'s exit code when a configured device never opened during the run
EXIT_DEVICE_NEVER_OPENED = 4


def _add_config_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", metavar="FILE.toml", help="configuration file (defaults: vipsm-robot dump-config)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a config key")


def _add_live_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--live", metavar="[HOST:]PORT", default=None,
                   help="serve the log's channels live to Foxglove/Lichtblick (WebSocket; host 127.0.0.1 unless "
                        "given; a non-loopback host needs live.allow_remote = true); sets live.listen")


def _add_ros2_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--ros2", action="store_true",
                   help="publish live ROS 2 topics over DDS (Cyclone DDS; domain, namespace and DDS config in "
                        "ros2.*); sets ros2.enabled")


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("dump-config", help="print the default configuration as TOML")
    _add_config_args(p)
    p.set_defaults(func=cmd_dump_config)

    p = sub.add_parser("run", help="run the daemon: devices from the config, 0.1 s control loop")
    _add_config_args(p)
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help=f"stop after S seconds; exit {EXIT_DEVICE_NEVER_OPENED} if a configured device never opened")
    p.add_argument("--log", metavar="FILE", help="field log path (overrides log.path)")
    _add_live_arg(p)
    _add_ros2_arg(p)
    p.add_argument("--json", action="store_true", help="print the run summary as one JSON object")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser(
        "sim", help="the simulated robot: world and byte-level fakes in a child process, the daemon against them"
    )
    _add_config_args(p)
    from .evaluation.scenarios import add_scenario_arguments

    add_scenario_arguments(p, allow_all=False)
    p.add_argument("--log", metavar="FILE", default=None, help="field log path (default: sim-<time>.mcap)")
    _add_live_arg(p)
    _add_ros2_arg(p)
    p.add_argument("--json", action="store_true", help="print the run summary as one JSON object")
    p.add_argument("--no-progress", action="store_true", help="no progress line")
    p.add_argument("--verbose", action="store_true",
                   help="print every figure of the summary (devices, latencies, fakes), the headline last")
    p.add_argument(
        "--mission",
        choices=("cruise", "hold"),
        default="cruise",
        help="cruise: straight ahead at the scenario's robot speed (the paper); hold: stand still (soak runs)",
    )
    p.set_defaults(func=cmd_sim)

    p = sub.add_parser("replay", help="run the estimator on a field log or a ROS bag as fast as possible")
    p.add_argument("log", metavar="LOG.mcap|BAG", help="a field log, a ROS 1 .bag file or a ROS 2 bag folder")
    p.add_argument("--plain-psm", action="store_true", help="replay with the plain-PSM baseline")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plots", metavar="DIR",
                   help="write the figures (Fig. 8 map, Fig. 9 paths, errors over time; both methods) as PNG into DIR")
    p.add_argument("--svg", action="store_true", help="with --plots: also write each figure as SVG")
    _add_config_args(p)
    from .replay import add_bag_arguments

    add_bag_arguments(p)
    p.set_defaults(func=cmd_replay)


def _config(args: argparse.Namespace) -> Config:
    config = load_config(args.config, args.set)
    if getattr(args, "live", None) is not None:
        config = dataclasses.replace(config, live=dataclasses.replace(config.live, listen=args.live))
    if getattr(args, "ros2", False):
        config = dataclasses.replace(config, ros2=dataclasses.replace(config.ros2, enabled=True))
    return config


def cmd_dump_config(args: argparse.Namespace) -> int:
    sys.stdout.write(dump_toml(_config(args)))
    return 0


# ---------------------------------------------------------------------------------------------


def cmd_run(args: argparse.Namespace) -> int:
    from .devices import build_loop
    from .evaluation.runner import tune_allocator

    config = _config(args)
    tune_allocator()  # per-cycle image and scan arrays stay in the process: no page-fault churn
    stop = threading.Event()
    install_signal_handlers(stop)
    loop = build_loop(config, log_path=args.log)
    try:
        loop.run(stop, duration_s=args.duration)
    finally:
        loop.shutdown()
    summary = loop_summary(loop)
    never = loop.devices_never_opened()
    summary["devices_never_opened"] = sorted(never)
    emit(summary, args.json)
    if args.duration is not None and never:
        for name, detail in never.items():
            print(f"vipsm-robot run: error: the {name} never opened during the run ({detail})", file=sys.stderr)
        return EXIT_DEVICE_NEVER_OPENED
    return 0


def _sim_status_port(config: Config, args: argparse.Namespace) -> Config:
    """``sim``'s status server listens on any free port (0, printed in the summary) unless the port
    is given (``--set status.port=N`` or the config file), so two runs at once do not clash."""
    if any(text.split("=", 1)[0].strip() == "status.port" for text in args.set):
        return config
    if args.config:
        import tomllib

        with open(args.config, "rb") as f:  # already read and checked by load_config
            if "port" in tomllib.load(f).get("status", {}):
                return config
    return dataclasses.replace(config, status=dataclasses.replace(config.status, port=0))


def cmd_sim(args: argparse.Namespace) -> int:
    from .evaluation.runner import tune_allocator
    from .sim import run_sim, summary_lines

    config = _sim_status_port(_config(args), args)
    tune_allocator()
    summary = run_sim(config, args)
    if args.json:
        emit(summary, True)
        return 0
    if args.verbose:
        emit({k: v for k, v in summary.items() if k != "headline"}, False)
    print("\n".join(summary_lines(summary)))
    return 0


# ---------------------------------------------------------------------------------------------


def _replay_plots(path: Path, results: list[Any], estimator_config: Any, args: argparse.Namespace) -> list[str]:
    """The figures of a replay: the method replayed, and the other one run over the same log for
    comparison (VIPSM above plain PSM)."""
    from vipsm.estimator import EstimatorConfig

    from .plots import write_figures
    from .replay import recorded_estimator_config, replay_trace, run_replay

    config = estimator_config or recorded_estimator_config(path) or EstimatorConfig()
    other, _ = run_replay(path, config, plain_psm=not args.plain_psm)
    vipsm, plain = (other, results) if args.plain_psm else (results, other)
    traces = [replay_trace(vipsm, config, "vipsm"), replay_trace(plain, config, "plain_psm")]
    return [str(p) for p in write_figures(traces, Path(args.plots), path.stem, svg=args.svg)]


def cmd_replay(args: argparse.Namespace) -> int:
    from .bagread import is_bag
    from .daemon import estimate_to_dict
    from .fieldlog import encode_json
    from .replay import cmd_replay_bag, recorded_log_version, run_replay

    if is_bag(args.log):
        return cmd_replay_bag(args, _config(args))
    # the estimator configuration recorded in the log, unless one is given here
    estimator_config = _config(args).estimator if (args.config or args.set) else None
    path = Path(args.log)
    if not path.exists():
        raise AppError(f"no such log: {path}")
    progress = Progress(None, enabled=True)
    t0 = time.perf_counter()
    results, read = run_replay(
        path, estimator_config, plain_psm=args.plain_psm, progress=lambda i: progress(f"replay: cycle {i + 1}", 0.0)
    )
    elapsed = time.perf_counter() - t0
    progress.finish()
    if not results:
        why = f"; {read.bad_messages} malformed, the first: {read.bad[0]}" if read.bad else ""
        why += f"; {read.corruption_count} damaged, the first: {read.corruption[0]}" if read.corruption else ""
        raise AppError(f"{path}: no estimator cycle to replay (truncated: {read.truncated} {read.reason}{why})")
    # compared in the log's JSON form (NaN is recorded as null)
    identical = sum(1 for cyc, est in results if json.loads(encode_json(estimate_to_dict(est))) == cyc.recorded)
    summary: dict[str, Any] = {
        "log_path": str(path),
        "cycles": len(results),
        "plain_psm": bool(args.plain_psm),
        "identical_to_recorded": identical,
        "ms_per_cycle": round(1e3 * elapsed / len(results), 3),
        "log_version": recorded_log_version(path),
        **read.summary(),  # truncated, truncation, bad_messages (+ reasons), bad_chunks, corruption
    }
    truths = [(cyc.truth, est) for cyc, est in results if cyc.truth is not None]
    if truths:
        from .sim import SimScorer

        scorer = SimScorer(origin=tuple(truths[0][0]["origin"]))  # type: ignore[arg-type]
        for truth, est in truths:
            scorer.score(est, truth)
        summary.update(scorer.metrics())
    if args.plots:
        summary["plots"] = _replay_plots(path, results, estimator_config, args)
    emit(summary, args.json)
    if read.damaged:
        print(read.warning(path), file=sys.stderr)
        return 3
    return 0


# ---------------------------------------------------------------------------------------------

#: ``bench --only daemon``: the simulated robot at 40 Hz, a cycle on every scan, the field log on
BENCH_SIM_S = 30.0
BENCH_SIM_ARGV = ("sim", "--scenario", "1", "--mission", "hold", "--set", 'loop.trigger="scan"',
                  "--set", "loop.period_s=0.025", "--no-progress")
BENCH_KEYS = ("cycles", "deadline_misses", "scans", "estimates", "daemon_cpu_percent", "compute_median_ms",
              "compute_p99_ms", "scan_to_obstacles_ms_median", "scan_to_obstacles_ms_p99",
              "scan_received_to_obstacles_ms_median", "scan_received_to_obstacles_ms_p99")


def bench(args: argparse.Namespace) -> dict[str, Any]:
    """The daemon's loop at 40 Hz against the simulated devices (``vipsm-robot sim``, BENCH_SIM_S
    seconds): latency from a scan's last beam to its obstacles published, deadline misses, CPU."""
    from .evaluation.runner import tune_allocator
    from .sim import run_sim

    load_1min = os.getloadavg()[0]  # the machine's load before this run adds its own
    parser = argparse.ArgumentParser(prog="vipsm-robot")
    register(parser.add_subparsers())
    with tempfile.TemporaryDirectory(prefix="vipsm-bench-") as tmp:
        argv = [*BENCH_SIM_ARGV, "--duration", str(BENCH_SIM_S), "--log", os.path.join(tmp, "bench.mcap")]
        sim_args = parser.parse_args(argv)
        tune_allocator()
        summary = run_sim(_sim_status_port(_config(sim_args), sim_args), sim_args)
    return {
        "command": shlex.join(["vipsm-robot", *argv[:-2]]),  # without the temporary --log
        "duration_s": BENCH_SIM_S,
        **{key: summary[key] for key in BENCH_KEYS},
        "load_average_1min": round(load_1min, 2),
    }
