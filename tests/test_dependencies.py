"""The package's declared dependencies cover what its code needs at run time on a fresh machine."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _declared() -> set[str]:
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    return {re.split(r"[<>=!~\[ ;]", d, maxsplit=1)[0].lower() for d in deps}


def test_numba_kernels_using_linalg_have_scipy_declared() -> None:
    """numba compiles ``np.linalg`` inside an ``@njit`` kernel against scipy's LAPACK bindings
    (``scipy.linalg.cython_lapack``): without scipy the kernel fails to compile at run time, which
    a machine with scipy installed for other reasons never shows."""
    users = [p.name for p in (ROOT / "vipsm").glob("*.py")
             if "njit" in (text := p.read_text()) and "np.linalg" in text]
    if users:
        assert "scipy" in _declared(), f"{users} use np.linalg in numba kernels: declare scipy"
