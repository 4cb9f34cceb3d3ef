"""Shared fixtures: the real recorded data in ../shared/data, real-device discovery, the scripts of tools/."""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Callable, Generator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from tests.machine_lock import MachineLock

REPO_ROOT = Path(__file__).resolve().parents[1]


def shared_data_dir() -> Path:
    """``../shared/data`` beside the repository, or ``$VIPSM_SHARED_DATA``."""
    override = os.environ.get("VIPSM_SHARED_DATA")
    return Path(override) if override else REPO_ROOT.parent / "shared" / "data"


@pytest.fixture(scope="session")
def load_tool() -> Callable[[str], ModuleType]:
    """A script of ``tools/`` (no package) imported as a module: ``load_tool("laser_edges")``."""

    def load(name: str) -> ModuleType:
        spec = importlib.util.spec_from_file_location(name, REPO_ROOT / "tools" / f"{name}.py")
        assert spec is not None and spec.loader is not None, f"tools/{name}.py cannot be loaded"
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod

    return load


@pytest.fixture(scope="session")
def shared_data() -> Path:
    path = shared_data_dir()
    if not path.is_dir():
        pytest.skip(f"real recorded data not found at {path} (set VIPSM_SHARED_DATA to its folder)")
    return path


# Real devices: the URL from the environment, else the udev name from app/deploy/99-vipsm-robot.rules.
_HARDWARE = {
    "scanner": ("VIPSM_SCANNER_URL", "/dev/hokuyo"),
    "robot": ("VIPSM_ROBOT_URL", "/dev/pioneer"),
    "camera": ("VIPSM_CAMERA_URL", "/dev/ptzcam"),
}


def hardware_url(device: str) -> str:
    """URL of a real attached device, or skip the test (it must be marked ``hardware``)."""
    env, udev_name = _HARDWARE[device]
    url = os.environ.get(env)
    if url:
        return url
    if os.path.exists(udev_name):
        return udev_name
    pytest.skip(f"no real {device} attached (set {env} or plug one in as {udev_name})")


#: module fixtures that make one real-time run of the simulated robot (holding the machine alone)
REAL_TIME_RUNS = ("sim_run", "ros2_run")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Tests on real devices share the devices: on several workers (``-n 2 --dist loadgroup``, the README's
    command) they all run on one worker, one after another; so do the tests of one real-time run (the run
    is then made once, not once per worker)."""
    for item in items:
        if item.get_closest_marker("hardware") is not None:
            item.add_marker(pytest.mark.xdist_group("hardware"))
            continue
        for name in REAL_TIME_RUNS:
            if name in getattr(item, "fixturenames", ()):
                item.add_marker(pytest.mark.xdist_group(name))


@pytest.fixture(scope="session")
def machine_lock(tmp_path_factory: pytest.TempPathFactory) -> MachineLock:
    """The machine shared by the test workers of this run, or had by a real-time run alone
    (``tests/machine_lock.py``)."""
    base = tmp_path_factory.getbasetemp()
    return MachineLock(base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base)


@pytest.fixture(autouse=True)
def _machine_shared(machine_lock: MachineLock) -> Generator[None, None, None]:
    with machine_lock.shared():
        yield


@pytest.fixture(autouse=True)
def _no_files_left_in_the_working_folder() -> object:
    """A test that runs the CLI must send its logs and figures to a temporary folder, never into the
    folder pytest runs in (the repository, on a developer's machine)."""
    cwd = Path.cwd()
    before = {p.name for p in cwd.iterdir()}
    yield
    # tools' own caches (.hypothesis, .pytest_cache, __pycache__) appear on a first run: not a test's
    left = sorted(n for n in {p.name for p in cwd.iterdir()} - before if not n.startswith((".", "__")))
    assert not left, f"the test left {left} in {cwd}"


def _skipped_for_the_data(report: pytest.TestReport) -> bool:
    """A test skipped because the recorded data is absent (the ``shared_data`` fixture's reason, or a
    module's own ``../shared/data/...`` reason)."""
    longrepr = report.longrepr
    reason = longrepr[2] if isinstance(longrepr, tuple) and len(longrepr) == 3 else str(longrepr)
    return "shared/data" in reason or str(shared_data_dir()) in reason or "recorded data not found" in reason


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> Generator[None]:
    """Says once, at the end (after pytest's short summary, before its count line), how many tests
    skipped because the recorded data is absent (a fresh clone has no ``../shared/data``), where it
    was looked for and how to point to it."""
    try:
        return (yield)
    finally:
        skipped = [r for r in terminalreporter.stats.get("skipped", []) if _skipped_for_the_data(r)]
        if skipped:
            terminalreporter.write_sep("-", "real recorded data absent", yellow=True)
            terminalreporter.write_line(
                f"{len(skipped)} test(s) skipped: the real recorded data is not at {shared_data_dir()} "
                "(a fresh clone has none; put it in ../shared/data beside the repository or set "
                "VIPSM_SHARED_DATA to its folder to run them)"
            )
