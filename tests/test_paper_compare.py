"""crgpr.report.paper: tolerance bands, references and the claim language, on synthetic numbers."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest

from crgpr.report.paper import (
    FAILS,
    HOLDS,
    MATCH,
    MISSING,
    OUTSIDE,
    UNKNOWN,
    Sources,
    compare_quantities,
    evaluate_claim,
    in_band,
    load_values,
    resolve,
)

ROOT = Path(__file__).resolve().parents[1]
VALUES = ROOT / "workflow" / "paper_values.yaml"
ANGLES = (60, 125, 160, 180, 225, 325)


def accuracy(**mean_rmse: float) -> pd.DataFrame:
    rows = []
    for method, v in mean_rmse.items():
        for i, a in enumerate(ANGLES):
            rows.append({"method": method, "theta0_deg": float(a), "rmse_theta": v * (0.5 + i / 5),
                         "r2_theta": 0.9, "tip_rmse_over_L": v / 2, "group_nrmse": v / 4})
    return pd.DataFrame(rows)


def test_paper_values_file_is_complete():
    vals = load_values(VALUES)
    ids = {q["id"] for q in vals["quantities"]}
    # Table I per angle and mean, both metrics; Table IV both pipelines; the baseline numbers
    for a in (*ANGLES, "mean"):
        assert f"table1_rmse_{a}" in ids and f"table1_r2_{a}" in ids
    assert {"base_blackbox", "base_pinn1", "base_pinn8", "base_crgpr"} <= ids
    assert {f"time_stage{i}" for i in range(1, 5)} <= ids
    paper = {q["id"]: q["paper"] for q in vals["quantities"]}
    assert paper["table1_rmse_mean"] == 0.222 and paper["base_blackbox"] == 4.559
    for q in vals["quantities"]:
        assert q["source"] and q["label"] and len(q["tolerance"]) == 1


@pytest.mark.parametrize(("paper", "ours", "tol", "expected"), [
    (0.2, 0.29, {"factor": 1.5}, True), (0.2, 0.31, {"factor": 1.5}, False),
    (0.9, 0.81, {"abs": 0.1}, True), (0.9, 0.79, {"abs": 0.1}, False),
    (1.0, 1.1, {"rel": 0.1}, True), (1.0, 1.2, {"rel": 0.1}, False),
    (3.0, 2.0, {"at_most": 1.0}, True), (3.0, 4.0, {"at_most": 1.0}, False),
])
def test_bands(paper, ours, tol, expected):
    assert in_band(paper, ours, tol) is expected


def test_resolve_mean_and_angle():
    src = Sources(accuracy=accuracy(cr_gpr=0.2))
    assert resolve("accuracy:cr_gpr:125:rmse_theta", src) == pytest.approx(0.2 * 0.7)
    assert resolve("accuracy:cr_gpr:mean:rmse_theta", src) == pytest.approx(0.2 * 1.0)
    assert math.isnan(resolve("accuracy:pinn_data_8:mean:rmse_theta", src))
    assert math.isnan(resolve("timing:stage1", src))


def test_verdicts_match_outside_missing():
    vals = load_values(VALUES)
    q = compare_quantities(vals, Sources(accuracy=accuracy(cr_gpr=0.2, cr_gpr_fd=2.0)))
    v = dict(zip(q["id"], q["verdict"], strict=True))
    assert v["table1_rmse_mean"] == MATCH
    assert v["table4_fd_rmse"] == OUTSIDE  # 2.0 vs 0.2107 is ~10x
    assert v["base_pinn8"] == MISSING


def test_claims():
    src = Sources(accuracy=accuracy(cr_gpr=0.2, blackbox_gp=5.0, pinn_data_1=2.0, pinn_data_8=0.3))
    assert evaluate_claim("ratio(accuracy:blackbox_gp:mean:rmse_theta, accuracy:cr_gpr:mean:rmse_theta) > 20",
                          src) == HOLDS
    assert evaluate_claim("lt(accuracy:pinn_data_8:mean:rmse_theta, accuracy:cr_gpr:mean:rmse_theta)",
                          src) == FAILS
    assert evaluate_claim("best(cr_gpr, [blackbox_gp, pinn_data_1, pinn_data_8], "
                          "[rmse_theta, tip_rmse_over_L, group_nrmse])", src) == HOLDS
    assert evaluate_claim("best(pinn_data_8, [cr_gpr], [rmse_theta])", src) == FAILS
    assert evaluate_claim("lt(sum(timing:stage1, timing:stage2), 11)", src) == UNKNOWN
    with pytest.raises(ValueError):
        evaluate_claim("__import__('os')", src)
