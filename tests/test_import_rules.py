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
    "vipsm": ({"vipsm", "numpy", "cv2", "numba"}, VIPSM_STDLIB),
    "hil_fakes": ({"hil_fakes", "numpy", "cv2"}, None),
    "app": ({"app", "drivers", "vipsm", "hil_fakes", "numpy", "cv2", "serial", "usb", "pymodbus", "mcap", "foxglove",
             "google", "rosbags", "matplotlib", "cyclonedds", "zstandard", "lz4"}, None),
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


#: modules only the evaluation may import (a reference run beside the product, never in its loop): kiss-icp, and
#: scipy's k-d tree for the drive's loop-closure check (scipy is installed with the product for numba's LAPACK,
#: but the product's code does not use it)
EVALUATION_ONLY = {"app/evaluation": {"kiss_icp", "scipy"}}


def violations(package: str) -> list[str]:
    allowed, stdlib_allowed = RULES[package]
    bad = []
    for path in sorted((ROOT / package).rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        extra = set().union(*(mods for folder, mods in EVALUATION_ONLY.items() if rel.startswith(folder + "/")))
        for lineno, mod in imported_top_levels(path):
            if mod in allowed or mod in extra:
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


# ------------------------------------------------------------------ no import circles
PACKAGES = ("drivers", "vipsm", "hil_fakes", "app")


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(root: Path, packages: tuple[str, ...] = PACKAGES) -> dict[str, set[str]]:
    """Module -> the project modules it imports, every import counted: top-level, function-local and
    under ``if TYPE_CHECKING:`` alike (a circle that only typing hides is still a circle in the design)."""
    files = {module_name(p, root): p for pkg in packages for p in sorted((root / pkg).rglob("*.py"))}
    graph: dict[str, set[str]] = {m: set() for m in files}

    def resolve(base: str, name: str | None) -> str | None:
        for cand in (f"{base}.{name}" if name else base, base):
            if cand in files:
                return cand
        return None

    for mod, path in files.items():
        is_pkg = path.name == "__init__.py"
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            targets: list[str | None] = []
            if isinstance(node, ast.Import):
                targets = [a.name if a.name in files else None for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    pkg = mod if is_pkg else mod.rpartition(".")[0]
                    for _ in range(node.level - 1):
                        pkg = pkg.rpartition(".")[0]
                    base = f"{pkg}.{node.module}" if node.module else pkg
                else:
                    base = node.module or ""
                targets = [resolve(base, a.name) for a in node.names]
            graph[mod].update(t for t in targets if t and t != mod)
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_circles_anywhere() -> None:
    assert circles(import_graph(ROOT)) == []


def test_the_circle_checker_finds_a_typing_only_circle(tmp_path: Path) -> None:
    pkg = tmp_path / "drivers"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from .b import B\n")
    (pkg / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from drivers.a import A\n")
    (pkg / "c.py").write_text("def f():\n    from . import a\n")
    graph = import_graph(tmp_path, ("drivers",))
    assert graph["drivers.c"] == {"drivers.a"}
    assert circles(graph) == [["drivers.a", "drivers.b"]]
