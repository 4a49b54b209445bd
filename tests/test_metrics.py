"""Accuracy metrics (crgpr.report.metrics) against hand-computed values (paper Sec. V definitions)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from paper_rod import paper_rod

from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import simulate, trajectory_frame
from crgpr.report.metrics import ACCURACY_COLUMNS, accuracy, accuracy_table, table1, table4


@pytest.fixture(scope="module")
def gt():
    return trajectory_frame(simulate(60.0, paper_rod(N=6),
                                     SimSettings(dt=1e-4, t_end=0.05, record_every=10, scheme="variational")))


def test_identical_rollout_is_perfect(gt):
    m = accuracy(gt, gt.copy(), 0.5)
    assert m["rmse_theta"] == 0.0 and m["tip_rmse_over_L"] == 0.0 and m["group_nrmse"] == 0.0
    assert m["r2_theta"] == pytest.approx(1.0)


def test_known_offsets(gt):
    pred = gt.copy()
    free = pred["node"] > 0
    pred.loc[free, "theta"] += 0.1
    pred.loc[free, "x"] += 0.03
    m = accuracy(gt, pred, 0.5)
    assert m["rmse_theta"] == pytest.approx(0.1, rel=1e-9)
    assert m["tip_rmse_over_L"] == pytest.approx(0.03 / 0.5, rel=1e-9)
    g = gt[gt["node"] > 0]
    expected = (0.03 / np.ptp(g["x"]) + 0.1 / np.ptp(g["theta"])) / 6
    assert m["group_nrmse"] == pytest.approx(expected, rel=1e-9)
    th = g["theta"].to_numpy()
    assert m["r2_theta"] == pytest.approx(1 - len(th) * 0.01 / np.sum((th - th.mean()) ** 2), rel=1e-9)
    # the clamped base node does not count
    pred.loc[pred["node"] == 0, "theta"] += 5.0
    assert accuracy(gt, pred, 0.5)["rmse_theta"] == pytest.approx(0.1, rel=1e-9)


def test_bad_rollouts_rejected(gt):
    short = gt[gt["t"] < gt["t"].max() / 2]
    with pytest.raises(ValueError, match="covers t"):
        accuracy(gt, short, 0.5, pred_name="short.parquet")
    nan = gt.copy()
    nan.loc[5, "x"] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        accuracy(gt, nan, 0.5)


def test_tables_generic_in_method(gt, tmp_path):
    gt_path = tmp_path / "gt.parquet"
    gt.to_parquet(gt_path)
    pairs = [("my_method", 60, gt_path, gt_path), ("missing", 60, gt_path, tmp_path / "x.parquet")]
    acc = accuracy_table(pairs, 0.5)
    assert list(acc.columns) == list(ACCURACY_COLUMNS) and list(acc["method"]) == ["my_method"]
    acc = pd.concat([acc, acc.assign(method="other", rmse_theta=0.5)])
    t1 = table1(acc, "other", [60, 125])
    assert set(t1["source"]) == {"paper", "other"}
    ours = t1[(t1["source"] == "other") & (t1["metric"] == "rmse_theta")]
    assert float(ours["60"].iloc[0]) == 0.5 and np.isnan(float(ours["125"].iloc[0]))
    t4 = table4(acc, ["my_method", "other"])
    assert t4["paper_rmse_theta"].tolist() == [0.2218, 0.2107]
