"""The architecture's import rules (../shared/ARCHITECTURE.md, 'Packages and who may import whom')."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
STDLIB = set(sys.stdlib_module_names)

# Standard-library modules that mean I/O, threads or a clock: the estimator must stay pure.
VIPSM_STDLIB = {
    "__future__", "abc", "bisect", "collections", "copy", "dataclasses", "enum", "functools",
    "heapq", "itertools", "math", "numbers", "operator", "statistics", "typing", "warnings",
}

RULES: dict[str, tuple[set[str], set[str] | None]] = {
    # package: (allowed third-party / project top-level modules, allowed stdlib (None: all))
    "drivers": ({"drivers", "serial", "usb", "numpy"}, None),
    "vipsm": ({"vipsm", "numpy", "cv2"}, VIPSM_STDLIB),
    "hil_fakes": ({"hil_fakes", "numpy", "cv2"}, None),
    "app": ({"app", "drivers", "vipsm", "hil_fakes", "numpy", "cv2", "serial", "usb", "pymodbus", "mcap"}, None),
}


def imported_top_levels(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.extend((node.lineno, alias.name.split(".")[0]) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: stays inside its own package
                continue
            found.append((node.lineno, (node.module or "").split(".")[0]))
    return found


def violations(package: str) -> list[str]:
    allowed, stdlib_allowed = RULES[package]
    bad = []
    for path in sorted((ROOT / package).rglob("*.py")):
        for lineno, mod in imported_top_levels(path):
            if mod in allowed:
                continue
            if mod in STDLIB and (stdlib_allowed is None or mod in stdlib_allowed):
                continue
            bad.append(f"{path.relative_to(ROOT)}:{lineno} imports {mod}")
    return bad


@pytest.mark.parametrize("package", sorted(RULES))
def test_package_imports_only_what_the_architecture_allows(package: str) -> None:
    assert (ROOT / package).is_dir()
    assert violations(package) == []


def test_the_checker_catches_a_forbidden_import(tmp_path: Path) -> None:
    bad = tmp_path / "x.py"
    bad.write_text("import socket\nfrom drivers.errors import DriverError\nfrom . import sibling\n")
    mods = [m for _, m in imported_top_levels(bad)]
    assert mods == ["socket", "drivers"]
    assert "socket" not in VIPSM_STDLIB and "drivers" not in RULES["vipsm"][0]
