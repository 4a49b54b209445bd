"""The paper-hyperparameter model (issue 11, part 3, ``cr_gpr_paper_hyp``): Table II's sigma_f,
ell, sigma_n mapped onto our scaling load, evaluate by their exact mean, and roll out."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from crgpr.config import load_config, rod_params, sim_settings
from crgpr.gp import fit_gp
from crgpr.gp.exact import ExactMean
from crgpr.learning.features import theta_center
from crgpr.learning.gradient_models import PAPER_MODELS, paper_hyperparameters, training_data
from crgpr.learning.learned import LearnedRod, rollout
from crgpr.learning.prefilter import fd_prefilter, prefiltered_arrays
from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import simulate

SMOKE = Path(__file__).parent / "smoke_config.yaml"


def test_paper_hyperparameter_mapping_is_original_units():
    h = paper_hyperparameters("q_x", np.array([2.0, 0.5, 4.0]), 0.1, ard=True)
    assert np.allclose(h["lengthscales"], [3.22 / 2.0, 2.47 / 0.5, 181 / 4.0])
    assert np.isclose(h["sigma_f"], 22.8) and np.isclose(h["sigma_n"], 0.34)
    h = paper_hyperparameters("dH_dp_x", np.array([0.01]), 2.0, ard=False)
    assert np.allclose(h["lengthscales"], [6180.0]) and np.isclose(h["sigma_f"], 134.7 / 2)


def test_paper_hyp_model_loads_and_rolls_out_on_smoke(tmp_path):
    cfg = load_config(SMOKE)
    P = rod_params(cfg)
    traj = simulate(85.0, P, sim_settings(cfg))
    df, _ = fd_prefilter(traj, int(cfg["prefilter"]["n_t_out"]))
    arr = prefiltered_arrays(df)
    center = theta_center(arr["theta"])
    comps = {}
    for name in PAPER_MODELS:
        X, y = training_data(arr, P, name, center)
        spec = cfg["gradient_models"]["models"][name]
        probe = fit_gp(X, y, kernel=spec["kernel"], basis=spec["basis"], ard=spec["ard"],
                       fixed={"sigma_f": 1.0, "lengthscales": 1.0, "sigma_n": 0.1}, factorise=False)
        hyp = paper_hyperparameters(name, probe.x_scale, float(probe.y_scale[0]), bool(spec["ard"]))
        gp = fit_gp(X, y, kernel=spec["kernel"], basis=spec["basis"], ard=spec["ard"], fixed=hyp,
                    factorise=False)
        gp.save(tmp_path / name)
        comps[name] = ExactMean(tmp_path / name)
        assert np.isclose(comps[name].gp.sigma_f, hyp["sigma_f"])
    model = LearnedRod(comps, "paper", P, center)
    tr = rollout(model, 125.0, SimSettings(dt=1e-4, t_end=0.01, record_every=10, scheme="variational"))
    assert tr.q.shape == (11, P.N + 1, 3) and np.all(np.isfinite(tr.q))
