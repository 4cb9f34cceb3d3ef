"""``vipsm-robot export LOG.mcap --rosbag2 OUT_DIR``: a field log as a ROS 2 bag
(:mod:`app.export_rosbag2`).

The summary (``--json``: one object) names the bag, the messages written per topic, those not
exported, ``scan_info`` (``recorded``: ``/scan`` messages whose limits and timing came from the log's
``/vipsm/scanner``; ``assumed``: from an old log without it, see :mod:`app.export_rosbag2`) and
``warnings`` (each assumption once, also on stderr; a warning alone does not change the exit code).

Exit codes as ``replay``: 0 the whole log exported; 3 the bag is written but something was skipped
(a malformed message, a message whose schema does not fit its topic, a damaged chunk: counted in
``bad_messages`` and ``bad_chunks``, with reasons, and named on stderr); 2 nothing exported (not a
log, no message to export, the bag cannot be written), and then no ``OUT_DIR`` is left behind."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .cli import emit
from .errors import AppError


def cmd_export(args: argparse.Namespace) -> int:
    from .export_rosbag2 import export_rosbag2

    log = Path(args.log)
    if not log.exists():
        raise AppError(f"no such log: {log}")
    result = export_rosbag2(log, args.rosbag2)
    emit({"log_path": str(log), "rosbag2": result.out_dir, "messages": dict(sorted(result.counts.items())),
          "not_exported": dict(sorted(result.not_exported.items())),
          "scan_info": {"recorded": result.scan_info["recorded"], "assumed": result.scan_info["assumed"]},
          "warnings": result.warnings, **result.read.summary()}, args.json)
    for warning in result.warnings:
        print(f"vipsm-robot: warning: {warning}", file=sys.stderr)
    if result.read.damaged:
        print(result.read.warning(log), file=sys.stderr)
        return 3
    return 0


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("export", help="convert a field log for other tools: a ROS 2 bag (ros2 bag play)")
    p.add_argument("log", metavar="LOG.mcap")
    p.add_argument("--rosbag2", metavar="OUT_DIR", required=True,
                   help="write a ROS 2 bag (sqlite3, CDR; REP 105 frames) into this new folder")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_export)
