"""Trajectory UQ (crgpr.uq.ensemble): coverage statistics, band table and figure on synthetic ensembles,
and the sampling stage on a small synthetic GP saved in crgpr.gp._gpr's format."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from crgpr.config import load_config
from crgpr.gp import fit_gp
from crgpr.io import read_parquet, write_parquet
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.simulate import simulate, trajectory_frame
from crgpr.uq.ensemble import (
    COVERAGE_COLUMNS,
    UQ_COLUMNS,
    UQSettings,
    band_figure,
    coverage_row,
    coverage_table,
    expected_coverage_calibrated,
    load_gp_spec,
    sample_models,
)

SMOKE = "tests/smoke_config.yaml"


def _ensemble(gt: pd.DataFrame, S: int, scale: float, bias: float, seed: int) -> pd.DataFrame:
    """Synthetic ensemble: ground truth + bias + smooth random perturbations of size scale."""
    rng = np.random.default_rng(seed)
    frames = []
    t = gt["t"].to_numpy()
    s = gt["s"].to_numpy()
    for k in range(S):
        d = gt.copy()
        for c in ("x", "y", "theta"):
            a, w = rng.standard_normal(2)
            d[c] = d[c] + bias + scale * (a * np.sin(3 * t + w) * s / s.max())
        d.insert(0, "sample", k)
        frames.append(d)
    return pd.concat(frames, ignore_index=True)


@pytest.fixture(scope="module")
def gt() -> pd.DataFrame:
    params = RodParams(N=6)
    return trajectory_frame(simulate(125.0, params, SimSettings(dt=1e-4, t_end=0.1, record_every=20)))


def test_expected_coverage_of_calibrated_band() -> None:
    """S = 10: about 0.79 (not 0.95); grows towards 0.95 with S."""
    e10 = expected_coverage_calibrated(10, 2.5, 97.5)
    assert 0.76 < e10 < 0.82
    assert e10 < expected_coverage_calibrated(40, 2.5, 97.5) < expected_coverage_calibrated(400, 2.5, 97.5)
    assert abs(expected_coverage_calibrated(400, 2.5, 97.5) - 0.95) < 0.01


def test_coverage_of_calibrated_and_biased_ensembles(gt: pd.DataFrame) -> None:
    """Truth drawn like the samples: coverage near the calibrated reference; a biased ensemble
    with a narrow band: coverage near zero; base node and t = 0 are excluded."""
    S = 30
    cov = []
    for rep in range(12):  # the truth as an extra member of the same family
        ens = _ensemble(gt, S + 1, 0.05, 0.0, seed=rep)
        truth = ens[ens["sample"] == S].drop(columns="sample")
        cov.append(coverage_row(ens[ens["sample"] < S], truth, 2.5, 97.5)["theta_coverage"])
    ref = expected_coverage_calibrated(S, 2.5, 97.5)
    assert abs(np.mean(cov) - ref) < 0.1, (np.mean(cov), ref)
    biased = _ensemble(gt, 10, 1e-3, 0.2, seed=1)
    row = coverage_row(biased, gt, 2.5, 97.5)
    assert row["theta_coverage"] < 0.05 and row["tip_coverage"] < 0.05
    assert row["theta_rmse_median"] == pytest.approx(0.2, rel=0.05)
    assert set(COVERAGE_COLUMNS) == set(row)


def test_coverage_table_and_figure(gt: pd.DataFrame, tmp_path) -> None:
    cfg = load_config(SMOKE)
    settings = UQSettings.from_config(cfg)
    ens = _ensemble(gt, 10, 0.05, 0.0, seed=3)
    write_parquet(ens[list(UQ_COLUMNS)], tmp_path / "125.parquet", {"n_diverged": 0})
    write_parquet(gt, tmp_path / "gt125.parquet")
    df = coverage_table({125: str(tmp_path / "125.parquet")}, {125: str(tmp_path / "gt125.parquet")},
                        settings, tmp_path / "cov.parquet", tmp_path / "cov.csv")
    assert list(df.columns) == list(COVERAGE_COLUMNS)
    csv = pd.read_csv(tmp_path / "cov.csv")
    assert list(csv["angle"].astype(str)) == ["125", "mean"]
    assert 0.0 < csv["theta_coverage"].iloc[0] <= 1.0
    band_figure(ens, gt, settings, tmp_path / "fig.png")
    assert (tmp_path / "fig.png").stat().st_size > 10_000
    # a missing column is named
    write_parquet(ens.drop(columns="theta"), tmp_path / "bad.parquet")
    with pytest.raises(ValueError, match="theta"):
        coverage_table({125: str(tmp_path / "bad.parquet")}, {125: str(tmp_path / "gt125.parquet")},
                       settings, tmp_path / "c2.parquet", tmp_path / "c2.csv")


def test_sample_models_from_saved_gp(tmp_path) -> None:
    """The sampling stage reads crgpr.gp._gpr's saved format, writes loadable samples, and its
    sparse posterior agrees with the exact one (diagnostics)."""
    cfg = load_config(SMOKE)
    settings = UQSettings.from_config(cfg)
    rng = np.random.default_rng(0)
    X = rng.uniform(-1.0, 1.0, (150, 3))
    y = 3.0 + np.sin(2.0 * X[:, 0]) * X[:, 1] + 0.01 * rng.standard_normal(150)
    gp = fit_gp(X, y, kernel="ard_se", basis="pure_quadratic", n_restarts=0, seed=0)
    gp.save(tmp_path / "m" / "q_x")
    spec, Z, grid = load_gp_spec(tmp_path / "m" / "q_x", "q_x")
    assert Z is None and grid is None
    np.testing.assert_allclose(spec.Xs, gp.standardise_x(X))
    res = sample_models({"q_x": str(tmp_path / "m" / "q_x")}, settings, cfg, tmp_path / "s",
                        tmp_path / "s" / "diag.json")
    comp = res["q_x"]
    assert comp.n_samples == settings.n_samples
    diag = json.loads((tmp_path / "s" / "diag.json").read_text())["models"]["q_x"]
    assert diag["inducing"] <= settings.inducing
    assert diag["mean_err_max_over_sd"] < 0.1  # M = 100 >= effective rank here
    f = comp(np.broadcast_to(X[:5], (comp.n_samples, 5, 3)))
    mean, var = gp.predict(X[:5], return_var=True)
    assert np.all(np.abs(f.mean(0) - mean) < 6.0 * np.sqrt(var / comp.n_samples) + 1e-6)
    assert read_parquet  # imported for the table test


def test_samples_centred_on_rollout_dtc_mean(tmp_path) -> None:
    """With the rollout's DTC arrays in the model file, the samples scatter around exactly that
    mean model (the CR-GPR prediction the band is drawn around)."""
    import dataclasses

    from crgpr.gp import KernelMean, dtc_fit

    cfg = load_config(SMOKE)
    settings = dataclasses.replace(UQSettings.from_config(cfg), n_samples=400, n_features=64)
    rng = np.random.default_rng(1)
    X = rng.uniform(-1.0, 1.0, (300, 3))
    y = np.sin(2.0 * X[:, 0]) * X[:, 1] + 0.3 * X[:, 2] ** 2 + 0.02 * rng.standard_normal(300)
    gp = fit_gp(X, y, kernel="ard_se", basis="pure_quadratic", n_restarts=0, seed=0)
    V = ((y - gp.y_mean[0]) / gp.y_scale[0])[:, None]
    arrays = dtc_fit(gp, X, V, 40, seed=0)
    gp.save(tmp_path / "q_y", extra_arrays=arrays)
    comp = sample_models({"q_y": str(tmp_path / "q_y")}, settings, cfg, tmp_path / "s",
                         tmp_path / "d.json")["q_y"]
    like = KernelMean.dtc(gp, arrays["dtc_Z"], arrays["dtc_w"], arrays["dtc_beta"])
    xt = np.vstack([X[:4], [[1.5, -1.5, 1.5]]])
    f = comp(np.broadcast_to(xt, (400, *xt.shape)))
    m_roll = like(xt)
    assert np.all(np.abs(f.mean(0) - m_roll) < 5.0 * f.std(0) / np.sqrt(400) + 1e-9)
    assert np.all(f.std(0) > 0)


def test_true_targets_match_the_rod_forces() -> None:
    """The analytic targets used by the calibration check reproduce the rod's nodal forces
    through the same assembly as the learned model (features.forces_from_q)."""
    from crgpr.learning.features import forces_from_q
    from crgpr.physics.rod import internal_forces, node_weights
    from crgpr.uq.ensemble import true_targets

    params = RodParams(N=8)
    traj = simulate(125.0, params, SimSettings(dt=1e-4, t_end=0.05, record_every=100))
    tt = true_targets(traj.q, traj.p, params)
    wds = node_weights(params.N) * params.ds
    F = internal_forces(traj.q[-1], params, float(traj.q[0, 0, 2]))[0]
    np.testing.assert_allclose(forces_from_q(tt["q_x"][-1], params)[1:], F[1:, 0] / wds[1:], rtol=1e-9,
                               atol=1e-9 * np.abs(F).max())
    np.testing.assert_allclose(forces_from_q(tt["q_y"][-1], params)[1:], F[1:, 1] / wds[1:], rtol=1e-9,
                               atol=1e-9 * np.abs(F).max())
    np.testing.assert_allclose(tt["dH_dp_x"], traj.p[:, 1:, 0] / params.rhoA)
