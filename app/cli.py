"""The ``vipsm-robot`` command line.

Each area of the product owns one command module (``app/cmd_*.py``) that registers its own
subcommands, so the areas stay independent:

* ``register(sub)``: top-level subcommands, each with ``set_defaults(func=...)`` where ``func(args)``
  returns the exit code;
* ``register_fake(fake_sub)``: its device under ``vipsm-robot fake <device>``;
* ``probe(args) -> dict``: what ``vipsm-robot probe --<device> URL`` prints for that device;
* ``bench(args) -> dict``: the figures ``vipsm-robot bench`` prints for that area.

``probe`` prints one JSON object keyed by device: ``{"scanner": {...}, "robot": {...},
"camera": {...}}`` with the devices that were asked for.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from collections.abc import Sequence
from types import ModuleType

from drivers.errors import DriverError

from .errors import AppError

COMMAND_MODULES: tuple[str, ...] = (
    "app.cmd_scanner",
    "app.cmd_robot",
    "app.cmd_camera",
    "app.cmd_estimator",
    "app.cmd_eval",
    "app.cmd_daemon",
    "app.cmd_export",
    "app.cmd_ros2",
)

# probe flag -> command module that answers it
PROBE_DEVICES: tuple[tuple[str, str], ...] = (
    ("scanner", "app.cmd_scanner"),
    ("robot", "app.cmd_robot"),
    ("camera", "app.cmd_camera"),
)


def load_modules() -> dict[str, ModuleType]:
    modules: dict[str, ModuleType] = {}
    for name in COMMAND_MODULES:
        try:
            modules[name] = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            # A command module not written yet is reported by `tests/app/test_cli.py`; any other
            # missing import is a real error and propagates.
            if exc.name != name:
                raise
    return modules


def print_json(obj: object) -> None:
    json.dump(obj, sys.stdout, indent=None, separators=(",", ":"), allow_nan=False)
    sys.stdout.write("\n")
    sys.stdout.flush()


def print_human(obj: object, indent: int = 0) -> None:
    pad = "  " * indent
    if isinstance(obj, dict):
        for key, value in obj.items():
            if isinstance(value, dict | list):
                print(f"{pad}{key}:")
                print_human(value, indent + 1)
            else:
                print(f"{pad}{key}: {value}")
    elif isinstance(obj, list):
        for item in obj:
            if isinstance(item, dict | list):
                print(f"{pad}-")
                print_human(item, indent + 1)
            else:
                print(f"{pad}- {item}")
    else:
        print(f"{pad}{obj}")


def emit(obj: object, as_json: bool) -> None:
    (print_json if as_json else print_human)(obj)


def _cmd_probe(args: argparse.Namespace, modules: dict[str, ModuleType]) -> int:
    if args.list:
        result: dict[str, object] = {"devices": []}
        for _, modname in PROBE_DEVICES:
            mod = modules.get(modname)
            if mod is not None and hasattr(mod, "list_devices"):
                result["devices"].extend(mod.list_devices(args))  # type: ignore[union-attr]
        emit(result, args.json)
        return 0
    result = {}
    for device, modname in PROBE_DEVICES:
        if getattr(args, device) is None:
            continue
        mod = modules.get(modname)
        if mod is None:
            raise AppError(f"probing the {device} is not built yet")
        result[device] = mod.probe(args)
    if not result:
        raise AppError("probe needs --scanner, --robot, --camera or --list")
    emit(result, args.json)
    return 0


def _cmd_bench(args: argparse.Namespace, modules: dict[str, ModuleType]) -> int:
    wanted = set(args.only.split(",")) if args.only else None
    known = sorted(name.removeprefix("app.cmd_") for name, mod in modules.items() if hasattr(mod, "bench"))
    if wanted is not None and not wanted <= set(known):
        raise AppError(f"unknown bench area(s) {', '.join(sorted(wanted - set(known)))}; known: {', '.join(known)}")
    result: dict[str, object] = {}
    for name, mod in modules.items():
        area = name.removeprefix("app.cmd_")
        if hasattr(mod, "bench") and (wanted is None or area in wanted):
            result[area] = mod.bench(args)
    emit(result, args.json)
    return 0


def build_parser(modules: dict[str, ModuleType]) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="vipsm-robot",
        description="Moving-obstacle detection with visually informed polar scan matching: drivers, fakes, daemon.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    probe = sub.add_parser("probe", help="open devices, print what they are and one sample of each")
    probe.add_argument("--scanner", metavar="URL", help="UTM-30LX: /dev/ttyACM0, a pty, socket://host:10940")
    probe.add_argument("--robot", metavar="URL", help="Pioneer: /dev/ttyUSB0, socket://127.0.0.1:8101")
    probe.add_argument("--camera", metavar="URL", help="SNC-RZ50 VISCA port: a tty, or socket://host:port")
    probe.add_argument("--camera-http", metavar="URL", help="SNC-RZ50 HTTP base URL, e.g. http://user:pw@cam")
    probe.add_argument("--list", action="store_true", help="list attached devices")
    probe.add_argument("--json", action="store_true", help="print one JSON object")
    probe.add_argument("--timeout-s", type=float, default=5.0, help="give up after this long per device")
    probe.set_defaults(func=lambda a: _cmd_probe(a, modules))

    bench = sub.add_parser("bench", help="run the benchmarks and print figures")
    bench.add_argument("--only", metavar="AREAS", help="comma list of areas (scanner,robot,camera,estimator,...)")
    bench.add_argument("--json", action="store_true", help="print one JSON object")
    bench.set_defaults(func=lambda a: _cmd_bench(a, modules))

    fake = sub.add_parser("fake", help="serve a byte-level fake device until interrupted")
    fake_sub = fake.add_subparsers(dest="device", required=True, metavar="DEVICE")

    for mod in modules.values():
        if hasattr(mod, "register"):
            mod.register(sub)
        if hasattr(mod, "register_fake"):
            mod.register_fake(fake_sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    modules = load_modules()
    parser = build_parser(modules)
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (AppError, DriverError) as exc:
        from .config import redact_text

        print(f"vipsm-robot {args.command}: error: {redact_text(str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
