"""``vipsm-robot export LOG.mcap --rosbag2 OUT_DIR``: a field log as a ROS 2 bag
(:mod:`app.export_rosbag2`)."""

from __future__ import annotations

import argparse
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
          "truncated": result.read.truncated, "truncation": result.read.reason,
          "bad_messages": result.read.bad_messages}, args.json)
    return 0


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("export", help="convert a field log for other tools: a ROS 2 bag (ros2 bag play)")
    p.add_argument("log", metavar="LOG.mcap")
    p.add_argument("--rosbag2", metavar="OUT_DIR", required=True,
                   help="write a ROS 2 bag (sqlite3, CDR; REP 105 frames) into this new folder")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_export)
