"""Every compiled kernel the estimator uses is loaded by ``vipsm.estimator.warm_up`` before the loop's
first cycle: a kernel left out compiles inside a cycle on the first run after an install (hundreds of
milliseconds), which a busy loop reads as overload and the scenario as missed cycles."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# in a fresh process: warm up, note every kernel's loaded signatures, run a short scenario with
# people, furniture and the camera through the whole estimator, and list what had to be compiled since
_SCRIPT = """
import contextlib, importlib, io, json, pkgutil
from numba.core.registry import CPUDispatcher
import vipsm

def loaded():
    out = {}
    for info in pkgutil.iter_modules(vipsm.__path__):
        mod = importlib.import_module("vipsm." + info.name)
        for name, obj in vars(mod).items():
            if isinstance(obj, CPUDispatcher) and obj.__module__ == mod.__name__:
                out[mod.__name__ + "." + name] = sorted(map(str, obj.signatures))
    return out

from vipsm.estimator import warm_up
warm_up()
before = loaded()
from app.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    main(["eval", "--scenario", "cross_60", "--duration", "6", "--json"])
after = loaded()
late = {k: sorted(set(v) - set(before.get(k, []))) for k, v in after.items()}
print(json.dumps({k: v for k, v in late.items() if v}))
"""


def test_warm_up_loads_every_kernel_a_scenario_uses() -> None:
    proc = subprocess.run([sys.executable, "-c", _SCRIPT], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    compiled_late = json.loads(proc.stdout.strip().splitlines()[-1])
    assert compiled_late == {}, f"kernels compiled inside a cycle, not in warm_up: {compiled_late}"
