"""``bench``'s PSM figures on the real recorded scans (the keys ``bench --json`` carries)."""

from __future__ import annotations

from pathlib import Path

from app.evaluation.psm_real import bench_real


def test_real_scan_speed_figures_are_reported(shared_data: Path) -> None:
    out = bench_real(shared_data, repetitions=1)
    for name in ("utm_v03", "utm_default", "intel", "intel_preset", "csail_preset"):
        for key in ("ms_median", "ms_p90", "ms_prepared_median", "ms_prepared_p90"):
            value = out[f"psm_real_{name}_{key}"]
            assert isinstance(value, float) and value > 0.0
        assert out[f"psm_real_{name}_ms_median"] <= out[f"psm_real_{name}_ms_p90"]
    assert out["psm_real_utm_pairs"] == 24 and out["psm_real_intel_pairs"] == 909
    assert out["psm_real_csail_pairs"] == 405


def test_missing_real_data_is_said_not_hidden(tmp_path: Path) -> None:
    out = bench_real(tmp_path)
    assert "not found" in out["psm_real_utm_skipped"] and "not found" in out["psm_real_intel_skipped"]
    assert "not found" in out["psm_real_csail_skipped"]
