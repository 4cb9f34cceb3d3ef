"""``vipsm-robot eval-psm``: the polar scan matcher on the real recorded scans in ``../shared/data``
(the evaluation is :mod:`app.evaluation.psm_real`; the estimator's benchmarks
:mod:`app.evaluation.bench_estimator`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from .cli import emit
from .evaluation.psm_real import (
    CSAIL_CORRECTED,
    CSAIL_RAW,
    DIOSI_FILE,
    INTEL_CORRECTED,
    INTEL_RAW,
    DataFormatError,
    eval_csail,
    eval_diosi,
    eval_intel,
)


def cmd_eval_psm(args: argparse.Namespace) -> int:
    data = Path(args.data)
    if not data.is_dir():
        raise DataFormatError(f"--data {data}: not a directory (expected the shared data folder)")
    result: dict[str, Any] = {}
    diosi = data / DIOSI_FILE
    intel_raw, intel_cor = data / INTEL_RAW, data / INTEL_CORRECTED
    if diosi.exists():
        result["diosi_utm30lx"] = eval_diosi(diosi, args.per_pair)
    if intel_raw.exists() or intel_cor.exists():
        result["intel"] = eval_intel(intel_raw, intel_cor, args.per_pair)
    if (data / CSAIL_RAW).exists() or (data / CSAIL_CORRECTED).exists():
        result["csail"] = eval_csail(data / CSAIL_RAW, data / CSAIL_CORRECTED, args.per_pair)
    if not result:
        raise DataFormatError(f"--data {data}: neither {DIOSI_FILE} nor {INTEL_RAW} found")
    emit(result, args.json)
    return 0


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "eval-psm",
        help="run the polar scan matcher on the real recorded scans (Diosi UTM-30LX, Intel Research Lab, MIT CSAIL)",
    )
    p.add_argument("--data", required=True, metavar="DIR", help="the shared data folder, e.g. ../shared/data")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--per-pair", action="store_true", help="also print every pair's estimate (dx_m, dy_m, dtheta_rad)")
    p.set_defaults(func=cmd_eval_psm)



def bench(args: argparse.Namespace) -> dict[str, Any]:
    from .evaluation.bench_estimator import bench as estimator_bench

    return estimator_bench(args)
