"""Step 3 (crgpr.learning.features, .gradient_models): targets, training on the smoke config, files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from crgpr.config import load_config, rod_params, sim_settings
from crgpr.gp import GP, KernelMean, dtc_fit, fit_gp, load_evaluator
from crgpr.learning import features as ft
from crgpr.learning.gradient_models import (
    PAPER_MODELS,
    train_model,
)
from crgpr.learning.prefilter import fd_prefilter, prefiltered_arrays
from crgpr.physics.rod import node_weights, strains, variational_derivative
from crgpr.physics.simulate import simulate
from crgpr.report.hyperparameters import table2

SMOKE = Path(__file__).parent / "smoke_config.yaml"


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    cfg = load_config(SMOKE)
    traj = simulate(85.0, rod_params(cfg), sim_settings(cfg))
    d = tmp_path_factory.mktemp("gm")
    df, _ = fd_prefilter(traj, int(cfg["prefilter"]["n_t_out"]))
    df.to_parquet(d / "fd85.parquet")
    return cfg, traj, d


def _exact_arrays(traj):
    """Prefilter-like arrays with exact time derivatives from the rod's own equations."""
    P = traj.params
    hz = np.array([variational_derivative(q, p, P) for q, p in zip(traj.q, traj.p, strict=True)])
    arr = {k: traj.z[..., i] for i, k in enumerate(("x", "y", "theta", "p_x", "p_y", "p_theta"))}
    v = hz[..., 3:]
    for i, c in enumerate(("x", "y", "theta")):
        arr[f"d{c}_dt"] = v[..., i]
    gu = np.array([0.0, -P.rhoA * P.g, 0.0])
    dp = -hz[..., :3] - P.zeta * v + gu
    for i, c in enumerate(("p_x", "p_y", "p_theta")):
        arr[f"d{c}_dt"] = dp[..., i]
    return arr, hz


def test_targets_recover_the_discrete_variational_derivative(smoke):
    """H_z = (J - R)^-1 (dz/dt - G u); q = tip-to-base sums; m from the moment balance."""
    _, traj, _ = smoke
    P = traj.params
    arr, hz = _exact_arrays(traj)
    np.testing.assert_allclose(ft.hz_targets(arr, P)[:, 1:], hz[:, 1:], rtol=1e-10, atol=1e-12)
    st = strains(traj.q, P)
    np.testing.assert_allclose(ft.q_from_hz(hz[..., 0], P), st["q_x"], atol=1e-12)
    np.testing.assert_allclose(ft.q_from_hz(hz[..., 1], P), st["q_y"], atol=1e-12)
    sg = ft.segments(traj.q[..., 0], traj.q[..., 1], traj.q[..., 2], P.ds)
    c = sg["nu1"] * st["n2"] - sg["nu2"] * st["n1"]
    np.testing.assert_allclose(ft.moments_from_htheta(hz[..., 2], c, P), st["m"], atol=1e-12)
    # and back: the rollout's force assembly gives -H_q at the free nodes
    np.testing.assert_allclose(ft.forces_from_q(st["q_x"], P)[:, 1:], -hz[:, 1:, 0], atol=1e-9)
    f_th = ft.theta_forces_objective(st["n1"], st["n2"], st["m"], sg["nu1"], sg["nu2"], P)
    np.testing.assert_allclose(f_th[:, 1:], -hz[:, 1:, 2], atol=1e-9)


def test_compiled_segment_table_and_force_assembly_match_their_array_definitions(smoke):
    """The rollout's compiled segment quantities and force assembly (``segment_table``,
    ``objective_forces``) are the array formulas of the features module: slopes, mid-segment angle,
    strains, kappa's ghost neighbours; forces_from_q of the resultants in the lab frame and the
    moment balance of theta_forces_objective. Also batched (leading axes)."""
    _, traj, _ = smoke
    P = traj.params
    q = traj.q[::7]
    x, y, th = q[..., 0], q[..., 1], q[..., 2]
    sg = ft.segments(x, y, th, P.ds)
    ex, ey = np.diff(x, axis=-1) / P.ds, np.diff(y, axis=-1) / P.ds
    tb = 0.5 * (th[..., 1:] + th[..., :-1])
    k = np.diff(th, axis=-1) / P.ds
    ref = {"ex": ex, "ey": ey, "theta_bar": tb, "cos": np.cos(tb), "sin": np.sin(tb), "kappa": k,
           "nu1": np.cos(tb) * ex + np.sin(tb) * ey, "nu2": -np.sin(tb) * ex + np.cos(tb) * ey,
           "kappa_jm1": np.concatenate([k[:, :1], k[:, :-1]], axis=-1),
           "kappa_jp1": np.concatenate([k[:, 1:], 0 * k[:, :1]], axis=-1)}
    for name, want in ref.items():
        np.testing.assert_allclose(sg[name], want, rtol=1e-13, atol=1e-13, err_msg=name)
    Xn, Xm = ft.objective_inputs(ft.segment_table(q, P.ds))
    np.testing.assert_array_equal(Xn, np.stack([sg["nu1"], sg["nu2"], sg["kappa"]], axis=-1))
    np.testing.assert_array_equal(Xm, np.stack([sg[n] for n in ("kappa", "kappa_jm1", "kappa_jp1", "nu1",
                                                                 "nu2")], axis=-1))
    rng = np.random.default_rng(3)
    n1, n2, m = (rng.normal(size=k.shape) for _ in range(3))
    cs, sn = sg["cos"], sg["sin"]
    want = np.stack([ft.forces_from_q(n1 * cs - n2 * sn, P), ft.forces_from_q(n1 * sn + n2 * cs, P),
                     ft.theta_forces_objective(n1, n2, m, sg["nu1"], sg["nu2"], P)], axis=-1)
    table = ft.segment_table(q, P.ds)
    wds = node_weights(P.N) * P.ds
    np.testing.assert_allclose(ft.objective_forces(n1, n2, m, table, wds, P.ds), want, rtol=1e-12, atol=1e-12)
    # a leading batch axis
    two = ft.objective_forces(*(np.stack([a, a]) for a in (n1, n2, m, table)), wds, P.ds)
    np.testing.assert_array_equal(two[1], ft.objective_forces(n1, n2, m, table, wds, P.ds))


def test_theta_wrap_keeps_differences():
    th = np.array([[5.0, 5.2, 5.1, 4.9]])
    x = np.cumsum(np.cos(th), axis=-1)
    y = np.cumsum(np.sin(th), axis=-1)
    f = ft.paper_theta_features(x, y, th, 1.0, center=0.0)
    assert np.all(f[..., 0] < np.pi) and np.all(f[..., 0] >= -np.pi)
    np.testing.assert_allclose(f[0, :, 1] - f[0, :, 0], th[0, :-1] - th[0, 1:], atol=1e-12)


def test_dtc_approximates_exact_mean():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(400, 2))
    y = np.sin(2 * X[:, 0]) * X[:, 1] + 0.3 * X[:, 0] ** 2 + 0.01 * rng.standard_normal(400)
    gp = fit_gp(X, y, kernel="se", ard=True, basis="pure_quadratic",
                fixed={"sigma_f": 1.0, "lengthscales": [0.6, 0.8], "sigma_n": 0.05})
    V = ((y - gp.y_mean[0]) / gp.y_scale[0])[:, None]
    a = dtc_fit(gp, X, V, 80, 0)
    like = KernelMean.dtc(gp, a["dtc_Z"], a["dtc_w"], a["dtc_beta"])
    Xs = rng.uniform(-1, 1, size=(200, 2))
    err = like(Xs) - gp.predict(Xs)
    assert np.sqrt(np.mean(err**2)) < 0.02 * np.std(y)


def test_train_models_on_smoke_prefilter(smoke, tmp_path):
    cfg, _, d = smoke
    metas = []
    for name in ("q_x", "dH_dp_x", "obj_n1"):
        meta = train_model(cfg, name, d / "fd85.parquet", tmp_path / name, "fd")
        metas.append(meta)
        with np.load(tmp_path / f"{name}.npz", allow_pickle=False) as a:
            assert a["X"].shape[0] == meta["n"]
        js = json.loads((tmp_path / f"{name}.json").read_text())
        spec = (cfg["gradient_models"]["models"].get(name)
                or cfg["gradient_models"]["objective_models"][name.removeprefix("obj_")])
        assert js["sigma_n"] >= spec["sigma_n_min"] * (1 - 1e-9)
        assert js["approx_error_vs_exact"]["rmse_over_target_std"] < 0.1
        assert js["n"] == min(spec["n_train"], js["n_available"])
    assert metas[0]["theta_center"] is not None and metas[2]["theta_center"] is not None
    # the objective n1 model recovers the axial stiffness EA = dn1/dnu1 from data alone
    P = rod_params(cfg)
    n1 = load_evaluator(tmp_path / "obj_n1")
    slope = (n1(np.array([[1.001, 0.0, 0.0]])) - n1(np.array([[0.999, 0.0, 0.0]])))[0] / 0.002
    assert slope == pytest.approx(P.EA, rel=0.1)
    df = table2([tmp_path / f"{n}.json" for n in ("q_x", "dH_dp_x")])
    assert {"sigma_f", "lengthscales", "sigma_n", "n", "paper_sigma_f", "paper_n"} <= set(df.columns)
    assert df.loc[df["model"] == "q_x", "paper_n"].iloc[0] == 7910
    assert set(PAPER_MODELS) >= set(df["model"])


def test_prefilter_arrays_roundtrip(smoke):
    cfg, traj, d = smoke
    import pandas as pd

    arr = prefiltered_arrays(pd.read_parquet(d / "fd85.parquet"))
    assert arr["x"].shape[1] == traj.params.N + 1


@pytest.mark.parametrize("threshold, expect_exact", [(1.0e-2, False), (1.0e-14, True)])
def test_rollout_mean_auto_integrates_dtc_only_where_it_equals_the_exact_mean(smoke, tmp_path,
                                                                                threshold, expect_exact):
    """``rollout_mean: auto``: a model whose DTC mean misses the exact mean by more than
    ``dtc_max_error`` target std at a check set rolls out on the exact mean, else on DTC."""
    cfg, _, d = smoke
    cfg = json.loads(json.dumps(cfg))
    cfg["gradient_models"].update(rollout_mean="auto", dtc_max_error=threshold)
    meta = train_model(cfg, "q_x", d / "fd85.parquet", tmp_path / "q_x", "fd")
    worst = max(e["max_abs"] for e in meta["dtc_error_vs_exact"].values()
                if np.isfinite(e["max_abs"])) / meta["target_std"]
    assert (worst > threshold) == expect_exact
    with np.load(tmp_path / "q_x.npz", allow_pickle=False) as a:
        assert ("mean_alpha" in a.files) == expect_exact
    assert ("exact" if expect_exact else "dtc") in meta["rollout_mean_choice"]
    X = np.load(tmp_path / "q_x.npz", allow_pickle=False)["X"][:50]
    ev = load_evaluator(tmp_path / "q_x")
    exact = KernelMean.exact(GP.load(tmp_path / "q_x"), tol=0.0)
    err = np.max(np.abs(ev(X) - exact(X))) / meta["target_std"]
    assert err <= (1e-9 if expect_exact else 10 * threshold)


def test_smooth_model_rolls_out_on_a_low_rank_dtc_mean(smoke):
    """A nearly linear law (obj_m's situation: lengthscales far beyond the data): rollout_mean
    auto picks DTC and ``dtc_rank_tol`` re-expresses it on a few pivots of its inducing inputs,
    still within dtc_max_error of the dense exact mean; the saved model loads as that mean."""
    from crgpr.learning.gradient_models import fit_model

    cfg = json.loads(json.dumps(smoke[0]))
    gm = {**cfg["gradient_models"], "rollout_mean": "auto", "dtc_max_error": 1e-3, "dtc_rank_tol": 1e-14,
          "inducing": 120, "check_points": 200}
    rng = np.random.default_rng(2)
    X = rng.uniform(-1.0, 1.0, (1500, 3))
    y = 0.8 * X[:, 0] - 0.3 * X[:, 1] + 0.01 * rng.standard_normal(1500)
    spec = {"kernel": "se", "ard": True, "basis": "linear", "sigma_n_min": 0.0, "n_train": 1500}
    gp, arrays, report = fit_model("obj_m", X, y, spec, gm, 0, X[:50] + 0.05)
    assert "rollout_pivots" in arrays and len(arrays["rollout_pivots"]) <= 60
    assert report["approx_error_vs_exact"]["max_abs"] <= 1e-3 * report["target_std"]
    exact = KernelMean.exact(gp, tol=0.0)
    Xs = rng.uniform(-1.0, 1.0, (100, 3))
    red = KernelMean.dtc(gp, arrays["dtc_Z"][arrays["rollout_pivots"]], arrays["rollout_w"][:, 0],
                         arrays["dtc_beta"][:, 0])
    assert np.max(np.abs(red(Xs) - exact(Xs))) <= 1e-2 * report["target_std"]


def test_a_trajectory_that_never_bends_is_refused_with_the_features_it_does_not_excite(smoke, tmp_path):
    """Released along gravity (90 deg) the rod only bounces axially: kappa is exactly 0 and the
    shear strain round-off (~1e-19) at every sample. Such a training trajectory cannot teach a
    bending law; the fit stops with one message naming the model, the features and the config
    key, instead of a singular basis solve (LinAlgError) or a GP of round-off noise."""
    cfg, _, _ = smoke
    traj = simulate(90.0, rod_params(cfg), sim_settings(cfg))
    assert np.ptp(traj.q[..., 2]) < 1e-12  # the premise: theta never moves
    df, _ = fd_prefilter(traj, int(cfg["prefilter"]["n_t_out"]))
    df.to_parquet(tmp_path / "fd90.parquet")
    with pytest.raises(ValueError, match=r"fd90.parquet: model obj_n1: the training trajectory does "
                                         r"not excite nu2 .*kappa .*gradient_models.min_input_spread"):
        train_model(cfg, "obj_n1", tmp_path / "fd90.parquet", tmp_path / "obj_n1", "fd")
    assert not (tmp_path / "obj_n1.npz").exists()  # (the 85 deg fits pass the same check: test above)
