"""Black-box GP baseline (paper Sec. V): features, fit, Verlet rollout, divergence record."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from crgpr.baselines import blackbox
from crgpr.commands.blackbox import blackbox_rollout, blackbox_train
from crgpr.config import load_config, rod_params, sim_settings
from crgpr.io import read_metadata, read_parquet, write_parquet
from crgpr.learning.prefilter import PrefilterSettings, fd_prefilter, prefilter
from crgpr.physics.params import SimSettings
from crgpr.physics.ports import ports_from_config
from crgpr.physics.rod import straight_rod
from crgpr.physics.signals import SignalInputs
from crgpr.physics.simulate import TRAJECTORY_COLUMNS, simulate

SMOKE = Path(__file__).parent / "smoke_config.yaml"


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """Black-box GPs trained on the FD-prefiltered smoke training trajectory via the rule."""
    cfg = load_config(SMOKE)
    params, settings = rod_params(cfg), sim_settings(cfg)
    traj = simulate(cfg["angles"]["train_deg"], params, settings)
    df, _ = prefilter(traj, "fd", PrefilterSettings.from_config(cfg))
    d = tmp_path_factory.mktemp("bb")
    pre = d / "pre.parquet"
    write_parquet(df, pre)
    blackbox_train(cfg, str(pre), str(d / "models"), str(d / "summary.json"))
    return cfg, d


def test_features_are_crgpr_features_plus_momenta():
    cfg = load_config(SMOKE)
    params = rod_params(cfg)
    q = straight_rod(1.0, params)
    p = np.zeros_like(q)
    p[:, 2] = np.arange(params.N + 1)
    f = blackbox.node_features(q, p, params.ds, None)
    assert f.shape == (params.N, len(blackbox.FEATURES))
    np.testing.assert_allclose(f[:, 0], 1.0)  # theta_i
    np.testing.assert_allclose(f[:, 3], 0.0, atol=1e-9)  # straight: no curvature change
    np.testing.assert_allclose(f[:, 4], np.cos(1.0))  # dx/ds
    np.testing.assert_allclose(f[:, 8], np.arange(1, params.N + 1))  # p_theta of nodes 1..N


def test_blackbox_trains_and_rolls_out_on_the_smoke_config(trained, tmp_path):
    cfg, d = trained
    summary = json.loads((d / "summary.json").read_text())
    assert [m["model"] for m in summary["models"]] == list(blackbox.TARGETS)
    assert all(m["n"] == cfg["baselines"]["blackbox_gp"]["n_train"] for m in summary["models"])
    # the velocity GPs must learn dq/dt = p / mass from data alone: check on the training data
    gps = blackbox.load_models(d / "models")
    params = rod_params(cfg)
    X = gps[0].X
    np.testing.assert_allclose(gps[0].predict(X), X[:, 6] / params.rhoA, rtol=0.05, atol=0.02)
    angles = list(cfg["angles"]["test_deg"])  # every test angle in one call, one file each
    outs = [str(tmp_path / f"{a}.parquet") for a in angles]
    blackbox_rollout(cfg, str(d / "models"), str(d / "summary.json"), angles, outs)
    n_t = sim_settings(cfg).n_records
    for angle, out in zip(angles, outs, strict=True):
        df = read_parquet(out, required=TRAJECTORY_COLUMNS)
        assert len(df) == n_t * (params.N + 1)
        assert np.all(np.isfinite(df[["x", "y", "theta", "p_x", "p_y", "p_theta"]].to_numpy()))
        meta = read_metadata(out)
        assert meta["method"] == "blackbox_gp" and "diverged" in meta and meta["theta0_deg"] == angle
        np.testing.assert_allclose(df[df["t"] == 0]["theta"], np.radians(angle), atol=1e-9)
        base = df[df["node"] == 0]
        assert np.allclose(base[["x", "y", "p_x", "p_y", "p_theta"]], 0.0)


def test_divergence_is_recorded_and_the_state_frozen(trained, monkeypatch):
    """A model that blows up stops at a plausible state, reports time and node, and does not crash."""
    cfg, d = trained
    gps = blackbox.load_models(d / "models")
    params = rod_params(cfg)

    class Runaway:
        """The learned tip velocity runs away: 50 m/s along x (evaluator k = 0 is dx/dt)."""

        def __init__(self, k: int):
            self.k = k

        def __call__(self, X):
            out = np.zeros(X.shape[0])
            if self.k == 0:
                out[-1] = 50.0
            return out

    ks = iter(range(len(gps)))
    monkeypatch.setattr(blackbox.KernelMean, "exact", staticmethod(lambda gp: Runaway(next(ks))))
    settings = SimSettings(dt=1e-4, t_end=0.2, record_every=5, scheme="variational")
    t, q, p, info = blackbox.rollout(gps, 60.0, params, settings)
    assert info["diverged"] and info["node_diverged"] == params.N
    assert 0 < info["t_diverged"] < 0.2
    r = int(round(info["t_diverged"] / (settings.dt * settings.record_every)))
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(p))
    np.testing.assert_array_equal(q[-1], q[r - 1])  # frozen at the last plausible record
    reach = np.hypot(q[: r, :, 0], q[: r, :, 1]).max()
    assert reach <= 2 * params.L0


def test_baseline_table_means_paper_columns_and_ordering(tmp_path):
    """The comparison table averages over the test angles and reports the ordering honestly."""
    from crgpr.report import comparison as baselines

    angles = [60, 125]
    vals = {"blackbox_gp": 3.0, "pinn_physics": 1.7, "pinn_data_1": 1.6, "pinn_data_8": 0.2, "cr_gpr": 0.4}
    rows = [{"method": m, "theta0_deg": float(a), "rmse_theta": v * (1 + 0.5 * i), "r2_theta": 0.5,
             "tip_rmse_over_L": v / 2, "group_nrmse": v / 10}
            for m, v in vals.items() for i, a in enumerate(angles)]
    rows.append({"method": "cr_gpr_fd", "theta0_deg": 60.0, "rmse_theta": 9.0, "r2_theta": 0.0,
                 "tip_rmse_over_L": 1.0, "group_nrmse": 1.0})  # other methods are ignored
    import pandas as pd

    df = baselines.baseline_table(pd.DataFrame(rows), angles)
    assert list(df["method"]) == [m for m in baselines.ORDER if m in vals]  # present ones, in order
    r = df.set_index("method")
    assert r.loc["pinn_data_8", "rmse_theta"] == pytest.approx(0.2 * 1.25)
    assert r.loc["blackbox_gp", "paper_rmse_theta"] == 4.559
    assert r.loc["blackbox_gp", "ratio_to_cr_gpr"] == pytest.approx(3.0 / 0.4)
    notes = " ".join(baselines.ordering_notes(df))
    assert "DISAGREES" in notes and "beaten by: pinn_data_8" in notes
    out = tmp_path / "b.png"
    baselines.plot_baselines(df, out)
    assert out.stat().st_size > 10_000
    with pytest.raises(ValueError, match="expected"):
        baselines.baseline_table(pd.DataFrame(rows), [60, 125, 160])


def test_blackbox_given_the_inputs_has_them_as_features_in_training_and_rollout():
    """Trained on an actuated record (a tip couple switched on at 0.05 s), every node's features
    end with the input channels at that frame's time (``INPUT_FEATURES``), zero before the step
    and the couple after it; the model rolls out under the inputs without diverging, and the
    inputs reach it (the rollout under zero inputs differs)."""
    cfg = load_config(SMOKE)
    params, ports = rod_params(cfg), ports_from_config(cfg)
    st = SimSettings(dt=1e-4, t_end=0.1, record_every=5, scheme="variational")
    u = SignalInputs({"tip_moment": {"kind": "step", "value": 0.01, "t_s": 0.05}}, "step")
    traj = simulate(85.0, params, st, inputs=u, ports=ports)
    df, _ = fd_prefilter(traj, 40)
    F, Y, center = blackbox.training_set(df, params, True, u)
    assert F.shape == (40 * params.N, len(blackbox.FEATURES) + len(blackbox.INPUT_FEATURES))
    t = np.repeat(np.unique(df["t"]), params.N)
    k = blackbox.INPUT_FEATURES.index("u_tip_moment")
    np.testing.assert_array_equal(F[:, len(blackbox.FEATURES) + k], np.where(t >= 0.05, 0.01, 0.0))
    assert np.all(np.delete(F[:, len(blackbox.FEATURES):], k, axis=1) == 0.0)
    gps = blackbox.fit_blackbox(F, Y, dict(cfg["baselines"]["blackbox_gp"], n_train=100, n_hyper=40), 3)
    _, q, _, info = blackbox.rollout(gps, 85.0, params, st, center, inputs=u)
    assert not info["diverged"] and np.all(np.isfinite(q))
    zero = SignalInputs({"tip_moment": {"kind": "constant", "value": 0.0}}, "zero")
    _, q0, _, _ = blackbox.rollout(gps, 85.0, params, st, center, inputs=zero)
    assert np.abs(q - q0).max() > 0
