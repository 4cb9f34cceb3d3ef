"""The estimator step of two revisions, timed side by side on identical inputs: is a change faster?

    PYTHONPATH=. python tools/step_ab.py --base REV [--duration 10] [--scenes a,b] [--json]

A shared machine's speed drifts by up to 2x over minutes, so two ``bench`` runs minutes apart cannot tell
a 15 % change from the machine's mood. This tool runs the realistic suite's scenarios (first
``--duration`` seconds of each) through ``eval``'s runner with two estimators stepped one after the other in
every cycle on the same scan, odometry and frame: this working tree's (``new``) and the ``vipsm`` package of
git revision ``--base`` (``base``, exported to a temporary folder as the package ``vipsm_base``, with the
leg model file of that revision). Both estimators are warmed up first, so no compilation is timed. It
prints per scenario the median step of each and their ratio, and over all cycles the medians, the p99s and
the median of the per-cycle ratios (new / base; paired, so the machine's drift cancels). The two
estimators' outputs are not compared here (the suite's digests and ``eval`` do that).
"""

from __future__ import annotations

import argparse
import io
import json
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def export_base(rev: str, into: Path) -> Path:
    """The ``vipsm`` package of ``rev`` as ``into/vipsm_base``; a clear error for an unknown revision."""
    proc = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev, "vipsm"], capture_output=True,
                          timeout=120)
    if proc.returncode != 0:
        raise SystemExit(f"step_ab: cannot export vipsm at {rev!r}: {proc.stderr.decode(errors='replace').strip()}")
    with tarfile.open(fileobj=io.BytesIO(proc.stdout)) as tar:
        tar.extractall(into, filter="data")
    (into / "vipsm").rename(into / "vipsm_base")
    return into / "vipsm_base"


def run(base_dir: Path, duration_s: float, scenes: list[str]) -> dict[str, Any]:
    sys.path.insert(0, str(base_dir.parent))
    import vipsm_base.estimator as base_estimator  # noqa: E402 - exported above
    import vipsm_base.legs as base_legs  # noqa: E402

    import app.evaluation.runner as runner
    from hil_fakes.world.scenarios import suite_scenario
    from vipsm.estimator import warm_up

    own = runner.make_estimators

    def make(mount):  # the plain-PSM slot holds the base revision's VIPSM estimator
        new, _ = own(mount)
        cfg = runner._replace_fields(base_estimator.EstimatorConfig(), runner.mount_values(mount))
        with np.load(base_dir / "data" / "legs_model.npz") as z:
            model = base_legs.model_from_arrays({k: z[k] for k in z.files})
        return new, base_estimator.Estimator(cfg, plain_psm=False, leg_model=model)

    runner.make_estimators = make
    warm_up()
    base_estimator.warm_up()
    per_scene, all_new, all_base = {}, [], []
    for name in scenes:
        log = runner.run_scenario(suite_scenario(name, overrides={"duration_s": duration_s}))
        new = 1000.0 * np.asarray(log.methods["vipsm"].step_s[1:])
        base = 1000.0 * np.asarray(log.methods["plain_psm"].step_s[1:])
        per_scene[name] = {"base_ms_median": round(float(np.median(base)), 2),
                           "new_ms_median": round(float(np.median(new)), 2),
                           "ratio": round(float(np.median(new) / np.median(base)), 3)}
        all_new.append(new)
        all_base.append(base)
    new, base = np.concatenate(all_new), np.concatenate(all_base)
    out: dict[str, Any] = {"scenes": per_scene, "cycles": int(new.size)}
    for key, ms in (("base", base), ("new", new)):
        out[f"{key}_ms_median"] = round(float(np.median(ms)), 2)
        out[f"{key}_ms_p99"] = round(float(np.percentile(ms, 99)), 2)
    out["paired_ratio_median"] = round(float(np.median(new / base)), 3)
    return out


def main(argv: list[str] | None = None) -> int:
    from hil_fakes.world.scenarios import REALISTIC_SUITE

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", required=True, help="git revision to compare against (its vipsm package)")
    ap.add_argument("--duration", type=float, default=10.0, help="seconds of each scenario (default 10, as bench)")
    ap.add_argument("--scenes", default=",".join(REALISTIC_SUITE), help="comma list (default: the realistic suite)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    scenes = [s for s in args.scenes.split(",") if s]
    unknown = sorted(set(scenes) - set(REALISTIC_SUITE))
    if unknown or not scenes or not args.duration > 0.0:
        ap.error(f"need --duration > 0 and scenes of the realistic suite ({', '.join(REALISTIC_SUITE)}); "
                 f"unknown: {', '.join(unknown) or '-'}")
    from hil_fakes.world.scenarios import ScenarioError, suite_scenario

    try:  # built once here: a duration the scenarios refuse is refused before the export and the warm-up
        for name in scenes:
            suite_scenario(name, overrides={"duration_s": args.duration})
    except ScenarioError as exc:
        ap.error(str(exc))
    with tempfile.TemporaryDirectory(prefix="step_ab_") as tmp:
        out = run(export_base(args.base, Path(tmp)), args.duration, scenes)
    out["base"] = args.base
    if args.json:
        print(json.dumps(out))
        return 0
    for name, s in out["scenes"].items():
        print(f"{name:22s} base {s['base_ms_median']:6.2f} ms  new {s['new_ms_median']:6.2f} ms  "
              f"ratio {s['ratio']:.2f}")
    print(f"all {out['cycles']} cycles: median {out['base_ms_median']} -> {out['new_ms_median']} ms, p99 "
          f"{out['base_ms_p99']} -> {out['new_ms_p99']} ms, paired ratio {out['paired_ratio_median']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
