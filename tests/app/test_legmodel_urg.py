"""The leg detector's check on the URG-04LX-class demo recording (app.legmodel_urg)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app import legmodel_urg
from app.legmodel import default_leg_model
from vipsm.legs import FEATURE_NAMES


def test_report_counts_and_takes_per_band() -> None:
    model = default_leg_model()
    x = np.zeros((3, len(FEATURE_NAMES)))
    x[:, FEATURE_NAMES.index("range_m")] = [1.0, 1.2, 4.0]
    x[:, FEATURE_NAMES.index("n_points")] = [10, 12, 3]
    out = legmodel_urg.report(x, model)
    assert out["segments"] == 3
    assert out["bands"]["0-1.5m"]["segments"] == 2 and out["bands"]["3.6-6m"]["segments"] == 1
    assert out["bands"]["1.5-2.5m"] == {"segments": 0}
    taken = float(np.mean(model.predict(x[:2]) >= model.threshold_p))
    assert out["bands"]["0-1.5m"]["taken"] == pytest.approx(taken)
    assert out["bands"]["0-1.5m"]["n_points"] == [10.5, 11.0, 11.5]


def test_bad_options_are_refused(tmp_path, capsys) -> None:
    assert legmodel_urg.main(["--every", "0"]) == 2
    assert "--every" in capsys.readouterr().err
    assert legmodel_urg.main(["--data-dir", str(tmp_path)]) == 2
    assert "demo_stationary_simple_environment.bag" in capsys.readouterr().err


def test_demo_legs_beyond_3_6_m_are_three_returns_of_one_range(shared_data, capsys) -> None:
    """The URG-04LX-class scanner's far legs: 3 returns of one range (no line residual, no curvature but the
    range's), which the recordings' laser gives as 4-5 curved returns (docs/estimator.md stage 1)."""
    data = shared_data / "real_people_laser"
    if not (data / legmodel_urg.DEMO_BAG).exists():
        pytest.skip(f"no {legmodel_urg.DEMO_BAG} in {data}")
    assert legmodel_urg.main(["--data-dir", str(data), "--every", "4", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    far = out["bands"]["3.6-6m"]
    assert far["segments"] >= 20
    assert far["n_points"][1] == 3 and far["linearity_m"][1] < 1e-3
    assert far["mean_curvature"][1] < 0.5  # 1 / range: the returns lie on an arc around the laser
    near = out["bands"]["0-1.5m"]
    assert near["n_points"][1] >= 10 and near["taken"] >= 0.5
