"""Step 3: the gradient GPs of Table II (paper Sec. III-B step 3) and the objective variant.

One rule per model writes ``results/models/{prefilter}/{model}.npz`` + ``.json``:

* paper models (methods cr_gpr / cr_gpr_fd): ``q_x``, ``q_y`` (ARD-SE, pure-quadratic basis,
  sigma_n >= 3.4e-2), ``dH_dtheta`` (ARD-SE, constant basis, sigma_n >= 1.8e-3),
  ``dH_dp_x``, ``dH_dp_y``, ``dH_dp_theta`` (SE, no basis); inputs/targets in features.py;
* objective models (cr_gpr_objective): ``obj_n1``, ``obj_n2``, ``obj_m`` (local resultants
  from frame-indifferent strains; same kernels/bases as q_x, q_y, dH_dtheta).

Training set: all (t, node) or (t, segment) samples of the prefilter grid, then a seeded
random subset of ``n_train`` points (the paper's n). Hyperparameters: the exact vague-prior
marginal likelihood (gp.fit_gp) on a seeded random subset of ``gradient_models.n_hyper`` of
those points; the posterior is then conditioned on all n points.

Prediction inside the rollouts (20000 steps x 25 nodes) uses an approximation whose error
against the exact posterior mean is measured here and stored in the model's JSON:
* multi-dimensional models: the DTC / subset-of-regressors mean with M inducing inputs
  chosen by farthest-point sampling in lengthscale-scaled inputs, fitted to ALL n points,
  basis coefficients estimated jointly (flat prior):
      min_{beta, w} |v - H beta - K_XZ w|^2 + sigma_n^2 w^T K_ZZ w;
  the exact posterior mean (Cholesky over n points) is computed at ``check_points`` random
  training inputs when n <= ``exact_check_max_n``; above it, exact and DTC are compared on a
  random subset of ``exact_check_max_n`` points (both conditioned on that subset);
* 1D momentum models: the exact posterior mean tabulated on 4001 points over the training
  range +- 6 lengthscales (linear interpolation; 0, the prior mean, outside).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import numpy as np

from crgpr.config import ConfigError, rod_params
from crgpr.gp import GP, KernelMean, Table1D, dtc_fit, fit_gp
from crgpr.learning import features as ft
from crgpr.learning.prefilter import prefiltered_arrays, read_prefiltered
from crgpr.physics.params import RodParams
from crgpr.physics.rod import STATE_NAMES
from crgpr.seeds import stage_seed

log = logging.getLogger(__name__)

PAPER_MODELS: tuple[str, ...] = ("q_x", "q_y", "dH_dtheta", "dH_dp_x", "dH_dp_y", "dH_dp_theta")
OBJECTIVE_MODELS: tuple[str, ...] = ("obj_n1", "obj_n2", "obj_m")
ALL_MODELS = PAPER_MODELS + OBJECTIVE_MODELS
MOMENTUM_MODELS = ("dH_dp_x", "dH_dp_y", "dH_dp_theta")

# Paper Table II, for table2_hyperparameters.csv
PAPER_TABLE2: dict[str, dict[str, Any]] = {
    "q_x": {"kernel": "ARD-SE", "basis": "PureQuadratic", "sigma_f": 2.28, "ell": "[3.22, 2.47, 181]",
            "sigma_n": 3.4e-2, "n": 7910},
    "q_y": {"kernel": "ARD-SE", "basis": "PureQuadratic", "sigma_f": 1.66, "ell": "[3.11, 1.84, 131]",
            "sigma_n": 3.4e-2, "n": 8652},
    "dH_dtheta": {"kernel": "ARD-SE", "basis": "Constant", "sigma_f": 1.14,
                  "ell": "[0.97, 1.86, 21.7, 4.28, 2.04, 51.1]", "sigma_n": 1.8e-3, "n": 18975},
    "dH_dp_x": {"kernel": "SE", "basis": "None", "sigma_f": 134.7, "ell": "61.8", "sigma_n": 9.3e-3,
                "n": 966},
    "dH_dp_y": {"kernel": "SE", "basis": "None", "sigma_f": 698.3, "ell": "391.1", "sigma_n": 1.1e-2,
                "n": 966},
    "dH_dp_theta": {"kernel": "SE", "basis": "None", "sigma_f": 8.05, "ell": "54.5", "sigma_n": 1.6e-1,
                    "n": 980},
}


def paper_hyperparameters(name: str, x_scale: np.ndarray, y_scale: float, ard: bool,
                          inputs_standardised: bool = False) -> dict[str, Any]:
    """Table II's sigma_f, ell, sigma_n of model ``name`` in our standardised units (issue 11).

    Read in ORIGINAL units (MATLAB fitrgp's default, Standardize = false): ell_std = ell / x_scale,
    sigma_f_std = sigma_f / y_scale, sigma_n_std = sigma_n / y_scale. ``inputs_standardised``:
    read ell as already standardised (fitrgp with Standardize = true scales the predictors only).
    """
    row = PAPER_TABLE2[name]
    txt = str(row["ell"]).strip("[]")
    ell = np.array([float(v) for v in txt.split(",")])
    if not inputs_standardised:
        ell = ell / np.asarray(x_scale, dtype=float)[: ell.size] if ard else ell / float(np.ravel(x_scale)[0])
    return {"sigma_f": float(row["sigma_f"]) / y_scale, "lengthscales": ell,
            "sigma_n": float(row["sigma_n"]) / y_scale}


FEATURE_NAMES: dict[str, tuple[str, ...]] = {
    "q_x": ft.PAPER_Q_FEATURES, "q_y": ft.PAPER_Q_FEATURES, "dH_dtheta": ft.PAPER_THETA_FEATURES,
    "dH_dp_x": ("p_x",), "dH_dp_y": ("p_y",), "dH_dp_theta": ("p_theta",),
    "obj_n1": ft.OBJ_N_FEATURES, "obj_n2": ft.OBJ_N_FEATURES, "obj_m": ft.OBJ_M_FEATURES,
}


def model_spec(cfg: dict[str, Any], name: str) -> dict[str, Any]:
    """Kernel/basis/bound/n of one model from config section ``gradient_models``."""
    if "gradient_models" not in cfg:
        raise ConfigError("config: missing section 'gradient_models'")
    gm = cfg["gradient_models"]
    if name in PAPER_MODELS:
        return dict(gm["models"][name])
    if name in OBJECTIVE_MODELS:
        return dict(gm["objective_models"][name.removeprefix("obj_")])
    raise ConfigError(f"unknown gradient model {name!r}; expected one of {ALL_MODELS}")


def training_data(arr: dict[str, np.ndarray], params: RodParams, name: str,
                  center: float | None, trim_ends: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """All (X, y) samples of one model from the prefilter arrays (before subsampling).

    ``trim_ends``: leave out the first and last ``trim_ends`` segments (nodes) of the
    multi-dimensional models, where angles derived from positions are extrapolations
    (camera data, ``learning.camera``); the momentum models keep every node.
    """
    x, y, th = arr["x"], arr["y"], arr["theta"]
    ds = params.ds
    hz = ft.hz_targets(arr, params)
    if name in ("q_x", "q_y"):
        X = ft.paper_q_features(x, y, th, ds, center)
        tgt = ft.q_from_hz(hz[..., 0 if name == "q_x" else 1], params)
    elif name == "dH_dtheta":
        X = ft.paper_theta_features(x, y, th, ds, center)
        tgt = hz[:, 1:, 2]
    elif name in MOMENTUM_MODELS:
        k = MOMENTUM_MODELS.index(name)
        X = np.stack([arr[STATE_NAMES[3 + k]]], axis=-1)[:, 1:]
        tgt = hz[:, 1:, 3 + k]
    elif name in OBJECTIVE_MODELS:
        sg = ft.segments(x, y, th, ds)
        qx, qy = ft.q_from_hz(hz[..., 0], params), ft.q_from_hz(hz[..., 1], params)
        n1 = qx * sg["cos"] + qy * sg["sin"]
        n2 = -qx * sg["sin"] + qy * sg["cos"]
        if name == "obj_n1":
            X, tgt = ft.objective_n_features(x, y, th, ds), n1
        elif name == "obj_n2":
            X, tgt = ft.objective_n_features(x, y, th, ds), n2
        else:
            c = sg["nu1"] * n2 - sg["nu2"] * n1
            X, tgt = ft.objective_m_features(x, y, th, ds), ft.moments_from_htheta(hz[..., 2], c, params)
    else:
        raise ConfigError(f"unknown gradient model {name!r}")
    if trim_ends and name not in MOMENTUM_MODELS:
        X, tgt = X[:, trim_ends:-trim_ends], tgt[:, trim_ends:-trim_ends]
    return X.reshape(-1, X.shape[-1]), tgt.reshape(-1)


# ---------------------------------------------------------------------------------------------
# approximations of the posterior mean for the rollouts
# ---------------------------------------------------------------------------------------------
def _err(a: np.ndarray, b: np.ndarray, scale: float) -> dict[str, float]:
    d = a - b
    return {"rmse": float(np.sqrt(np.mean(d**2))), "max_abs": float(np.abs(d).max()),
            "rmse_over_target_std": float(np.sqrt(np.mean(d**2)) / scale)}


def fit_model(name: str, X: np.ndarray, y: np.ndarray, spec: dict[str, Any], gm: dict[str, Any],
              seed: int) -> tuple[GP, dict[str, np.ndarray], dict[str, Any]]:
    """Fit one gradient GP and its rollout approximation; returns (gp, arrays, report)."""
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    n_all = X.shape[0]
    n = min(int(spec["n_train"]), n_all)
    idx = np.sort(rng.choice(n_all, size=n, replace=False)) if n < n_all else np.arange(n_all)
    Xn, yn = X[idx], y[idx]
    one_d = X.shape[1] == 1
    # 1D momentum models: a nearly noise-free, nearly linear map; start from a long lengthscale
    # and a small noise (the LML surface is flat there), with extra restarts (cheap in 1D)
    init = ({"sigma_f": 3.0, "lengthscales": 5.0, "sigma_n": 1e-3} if one_d
            else {"sigma_f": 1.0, "lengthscales": 1.0, "sigma_n": 0.05})
    gp = fit_gp(Xn, yn, kernel=spec["kernel"], basis=spec["basis"], ard=bool(spec["ard"]),
                sigma_n_min=float(spec["sigma_n_min"]) or None,
                n_restarts=max(int(gm["n_restarts"]), 3) if one_d else int(gm["n_restarts"]),
                seed=seed, hyper_subset=int(gm["n_hyper"]), factorise=False, init=init)
    t_hyper = time.perf_counter() - t0
    report: dict[str, Any] = {"model": name, "n_available": int(n_all), "n": int(n),
                              "hyper_subset": int(min(int(gm["n_hyper"]), n)),
                              "hyper_subset_choice": f"uniform random without replacement, seed {seed}",
                              "seconds_hyper": t_hyper}
    ystd = float(np.std(yn)) or 1.0
    if gp.dim == 1:
        gp.ensure_factorised()
        ell = float(np.ravel(gp.lengthscales)[0] * gp.x_scale[0])
        grid = np.linspace(Xn.min() - 6 * ell, Xn.max() + 6 * ell, 4001)
        tab = Table1D.from_gp(gp, grid)
        arrays = {"table_x": grid, "table_y": tab.ty}
        xc = rng.uniform(grid[0], grid[-1], int(gm["check_points"]))
        approx = tab(xc)
        report["approximation"] = "exact mean tabulated (4001 points, linear interpolation)"
        report["approx_error_vs_exact"] = _err(approx, gp.predict(xc[:, None]), ystd)
    else:
        V = ((yn - gp.y_mean[0]) / gp.y_scale[0])[:, None]
        M = int(gm["inducing"])
        arrays = dtc_fit(gp, Xn, V, M, seed)
        like = KernelMean.dtc(gp, arrays["dtc_Z"], arrays["dtc_w"], arrays["dtc_beta"])
        n_chk = min(int(gm["check_points"]), n)
        ci = rng.choice(n, size=n_chk, replace=False)
        limit = int(gm["exact_check_max_n"])
        if n <= limit:
            gp.ensure_factorised()
            exact = gp.predict(Xn[ci])
            report["approx_check"] = f"exact posterior mean over all n = {n} points"
            report["approx_error_vs_exact"] = _err(like(Xn[ci]), exact, ystd)
        else:
            si = np.sort(rng.choice(n, size=limit, replace=False))
            sub = fit_gp(Xn[si], yn[si], kernel=gp.kernel, basis=gp.basis, ard=gp.ard,
                         fixed={"sigma_f": gp.sigma_f, "lengthscales": gp.lengthscales,
                                "sigma_n": gp.sigma_n}, factorise=False)
            sub.y_mean, sub.y_scale = gp.y_mean, gp.y_scale
            sub.x_mean, sub.x_scale = gp.x_mean, gp.x_scale
            sub._factorise()
            Vs = ((yn[si] - gp.y_mean[0]) / gp.y_scale[0])[:, None]
            sub_arr = dtc_fit(gp, Xn[si], Vs, M, seed)
            sub_like = KernelMean.dtc(gp, sub_arr["dtc_Z"], sub_arr["dtc_w"], sub_arr["dtc_beta"])
            cj = rng.choice(limit, size=min(n_chk, limit), replace=False)
            report["approx_check"] = (f"n = {n} > exact_check_max_n: exact vs DTC (M = {M}) both "
                                      f"conditioned on a random subset of {limit} points")
            report["approx_error_vs_exact"] = _err(sub_like(Xn[si][cj]), sub.predict(Xn[si][cj]),
                                                   ystd)
        report["approximation"] = f"DTC mean, M = {len(arrays['dtc_Z'])} farthest-point inducing inputs"
        report["fit_rmse_over_target_std"] = float(np.sqrt(np.mean((like(Xn) - yn) ** 2)) / ystd)
    report["target_std"] = ystd
    report["seconds"] = time.perf_counter() - t0
    log.info("%s: n = %d, %s, error vs exact %s, %.1f s", name, n, report["approximation"],
             report["approx_error_vs_exact"], report["seconds"])
    return gp, arrays, report


def train_model_arrays(cfg: dict[str, Any], name: str, arr: dict[str, np.ndarray], params: RodParams,
                       out_stem: str | Path, source: str, prefilter_method: str,
                       extra: dict[str, Any] | None = None, trim_ends: int = 0) -> dict[str, Any]:
    """Fit model ``name`` on derivative-data arrays (schema of ``prefiltered_arrays``) and save it.

    ``params`` is the rod the arrays live on (its N sets the node grid); ``extra`` is added
    to the model's JSON; ``trim_ends`` see ``training_data``. Used by stage 2 (prefilter
    files) and by ``crgpr learn`` (camera data).
    """
    gm = cfg["gradient_models"]
    spec = model_spec(cfg, name)
    if arr["x"].shape[1] != params.N + 1:
        raise ValueError(f"{source}: {arr['x'].shape[1]} nodes but the rod has N + 1 = {params.N + 1}")
    center = ft.theta_center(arr["theta"]) if gm["theta_wrap"] else None
    X, y = training_data(arr, params, name, center, trim_ends)
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(y))):
        raise ValueError(f"{source}: non-finite features or targets for model {name}")
    seed = stage_seed(cfg["seed"], "gradient_model", ALL_MODELS.index(name))
    gp, arrays, report = fit_model(name, X, y, spec, gm, seed)
    meta = {"name": name, "features": list(FEATURE_NAMES[name]), "theta_center": center,
            "prefilter": prefilter_method, "source": str(source), "seed": seed, **report,
            "target": "H_z = (J - R)^-1 (dz/dt - G u), features.py", **(extra or {})}
    gp.save(out_stem, extra=meta, extra_arrays=arrays)
    return meta


def train_model(cfg: dict[str, Any], name: str, prefiltered: str | Path, out_stem: str | Path,
                prefilter_method: str = "gp") -> dict[str, Any]:
    """Build the data set of ``name`` from a prefilter Parquet file, fit, and save."""
    arr = prefiltered_arrays(read_prefiltered(prefiltered))
    return train_model_arrays(cfg, name, arr, rod_params(cfg), out_stem, str(prefiltered), prefilter_method)


