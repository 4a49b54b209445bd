"""The paper-hyperparameter model (``cr_gpr_paper_hyp``): Table II's sigma_f,
ell, sigma_n mapped onto our scaling, trained by the pipeline's own function, loaded as the
exact posterior mean and rolled out; and the bounded hyperparameter search of the fitted models."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from crgpr.config import load_config, rod_params, sim_settings
from crgpr.learning.gradient_models import PAPER_MODELS, paper_hyperparameters, train_model
from crgpr.learning.learned import LearnedRod, model_files, rollout
from crgpr.learning.prefilter import fd_prefilter
from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import simulate
from crgpr.report.hyperparameters import lml_table

SMOKE = Path(__file__).parent / "smoke_config.yaml"


def test_paper_hyperparameter_mapping_is_original_units():
    h = paper_hyperparameters("q_x", np.array([2.0, 0.5, 4.0]), 0.1, ard=True)
    assert np.allclose(h["lengthscales"], [3.22 / 2.0, 2.47 / 0.5, 181 / 4.0])
    assert np.isclose(h["sigma_f"], 22.8) and np.isclose(h["sigma_n"], 0.34)
    h = paper_hyperparameters("dH_dp_x", np.array([0.01]), 2.0, ard=False)
    assert np.allclose(h["lengthscales"], [6180.0]) and np.isclose(h["sigma_f"], 134.7 / 2)


def test_paper_hyp_method_reads_its_own_model_folder():
    spec = load_config(SMOKE)["rollouts"]["methods"]["cr_gpr_paper_hyp"]
    assert all("/models/gp_paper_hyp/" in f for f in model_files("results", spec))


def test_paper_hyp_model_loads_and_rolls_out_on_smoke(tmp_path):
    cfg = load_config(SMOKE)
    P = rod_params(cfg)
    traj = simulate(85.0, P, sim_settings(cfg))
    df, _ = fd_prefilter(traj, int(cfg["prefilter"]["n_t_out"]))
    df.to_parquet(tmp_path / "fd85.parquet")
    (tmp_path / "paper").mkdir()
    (tmp_path / "fitted").mkdir()
    for name in PAPER_MODELS:
        train_model(cfg, name, tmp_path / "fd85.parquet", tmp_path / "paper" / name, "fd",
                    hyper="paper_table2")
        meta = json.loads((tmp_path / "paper" / f"{name}.json").read_text())
        hyp = paper_hyperparameters(name, np.asarray(meta["x_scale"]), float(meta["y_scale"][0]),
                                    name in ("q_x", "q_y", "dH_dtheta"))
        assert np.isclose(meta["sigma_f_std"], hyp["sigma_f"])
        assert np.allclose(meta["lengthscales_std"], hyp["lengthscales"])
        assert np.isclose(meta["sigma_n_std"], max(hyp["sigma_n"], 1e-6))
        assert meta["hyperparameters"] == "paper_table2"
        if name in ("q_x", "q_y", "dH_dtheta"):
            # the rollout integrates the exact mean; its truncation error is below 1 % of the target std
            assert meta["approximation"].startswith("exact posterior mean")
            assert meta["approx_error_vs_exact"]["rmse_over_target_std"] < 0.01
    model = LearnedRod.from_dir(tmp_path / "paper", "paper", P)
    assert model.components["dH_dtheta"].kind == "exact"
    tr = rollout(model, 125.0, SimSettings(dt=1e-4, t_end=0.01, record_every=10, scheme="variational"))
    assert tr.q.shape == (11, P.N + 1, 3) and np.all(np.isfinite(tr.q))
    # fitted models: inside the configured box; the LML table compares both on the same rows
    hb = cfg["gradient_models"]["hyper_bounds"]
    for name in ("q_y", "dH_dp_x"):
        train_model(cfg, name, tmp_path / "fd85.parquet", tmp_path / "fitted" / name, "fd")
        js = json.loads((tmp_path / "fitted" / f"{name}.json").read_text())
        lo, hi = (np.asarray(b) for b in js["ell_bounds_std"])
        ell = np.broadcast_to(js["lengthscales_std"], lo.shape)
        assert np.all(ell >= lo * (1 - 1e-9)) and np.all(ell <= hi * (1 + 1e-9))
        assert hb["sigma_f_min_std"] * (1 - 1e-9) <= js["sigma_f_std"] <= hb["sigma_f_max_std"] * (1 + 1e-9)
    tab = lml_table([tmp_path / "fitted" / "q_y.json", tmp_path / "fitted" / "dH_dp_x.json"])
    # our LML is the optimum of the search on exactly these rows
    np.testing.assert_allclose(tab["lml_ours"], tab["lml_ours_saved"], rtol=1e-8)
    assert np.all(np.isfinite(tab["lml_paper_table2"]))
