"""Step 3: the gradient GPs of Table II (paper Sec. III-B step 3) and the objective variant.

One rule per model writes ``results/models/{prefilter}/{model}.npz`` + ``.json``:

* paper models (methods cr_gpr / cr_gpr_fd): ``q_x``, ``q_y`` (ARD-SE, pure-quadratic basis,
  sigma_n >= 3.4e-2), ``dH_dtheta`` (ARD-SE, constant basis, sigma_n >= 1.8e-3),
  ``dH_dp_x``, ``dH_dp_y``, ``dH_dp_theta`` (SE, no basis); inputs/targets in features.py;
* objective models (cr_gpr_objective): ``obj_n1``, ``obj_n2``, ``obj_m`` (local resultants
  from frame-indifferent strains; same kernels/bases as q_x, q_y, dH_dtheta).

Training set: all (t, node) or (t, segment) samples of the prefilter grid, then a seeded
random subset of ``n_train`` points (the paper's n). Hyperparameters: the exact vague-prior
marginal likelihood (gp.fit_gp, R&W eq. (2.45)) on a seeded random subset of
``gradient_models.n_hyper`` of those points, inside box bounds (``hyper_bounds``, standardised
units) that exclude the degenerate optima found on small subsets: each lengthscale in
[ell_min_over_spread, ell_max_over_spread] x the spread (max - min) of its input over the
training set (below: a white-noise fit that interpolates single samples and returns the basis
between them; above: an input that no longer matters, kept for conditioning), sigma_f in
[sigma_f_min_std, sigma_f_max_std] x the target's std. ``hyper: paper_table2`` instead fixes
the paper's Table II values (``paper_hyperparameters``: read in original units). The posterior
is then conditioned on all n points.

The rollout mean (``rollout_mean``; ``auto``: per model, ``dtc`` where the DTC mean's largest
error against the dense exact mean at both check sets is below ``dtc_max_error`` target std,
else ``exact``; the choice is recorded as ``rollout_mean_choice``):
* ``exact``: the EXACT posterior mean over all n points (``gp.KernelMean.exact``): weights from
  one Cholesky factorisation here (stored as ``mean_alpha``, ``mean_beta``), kernel sums
  truncated below ``exact_tol`` sigma_f^2 in the rollout (bound stored);
* ``dtc``: the DTC / subset-of-regressors mean with M = ``inducing`` farthest-point inducing
  inputs fitted to all n points (basis jointly, flat prior):
      min_{beta, w} |v - H beta - K_XZ w|^2 + sigma_n^2 w^T K_ZZ w.
The DTC arrays (``dtc_Z``, ``dtc_w``, ``dtc_beta``) are stored in either case: the UQ samplers
(``crgpr.uq.samples``) are built on that inducing set. 1D momentum models: the exact mean
tabulated over the training range +- min(6 lengthscales, 10 ranges) on 4001 points, more where
the step would exceed a twentieth of the lengthscale (``gp.evaluators.law_grid``; linear
interpolation; 0, the prior mean, outside).
Every approximation is measured against the dense exact posterior mean, in units of the
target's std: at ``check_points`` random training inputs and at the ground-truth states of the
test angles (every ``check_every``-th record), the states the rollouts are meant to visit
(``approx_error_vs_exact``), plus the truncation bound, valid at every input.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import numpy as np

from crgpr.config import ConfigError, rod_params
from crgpr.gp import GP, KernelMean, Table1D, dtc_fit, exact_weights, fit_gp
from crgpr.gp.evaluators import law_grid
from crgpr.gp.sparse import nystrom_reduce
from crgpr.io import read_parquet
from crgpr.learning import features as ft
from crgpr.learning.prefilter import prefiltered_arrays, read_prefiltered
from crgpr.physics.params import RodParams
from crgpr.physics.rod import STATE_NAMES
from crgpr.physics.simulate import trajectory_from_frame
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
    """Table II's sigma_f, ell, sigma_n of model ``name`` in our standardised units.

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


def model_features(x: np.ndarray, y: np.ndarray, th: np.ndarray, p: np.ndarray, ds: float, name: str,
                   center: float | None) -> np.ndarray:
    """Inputs of model ``name`` at states (n_t, N+1): positions x, y, angle th, momenta p (.., 3)."""
    if name in ("q_x", "q_y"):
        return ft.paper_q_features(x, y, th, ds, center)
    if name == "dH_dtheta":
        return ft.paper_theta_features(x, y, th, ds, center)
    if name in MOMENTUM_MODELS:
        return p[:, 1:, MOMENTUM_MODELS.index(name)][..., None]
    if name in ("obj_n1", "obj_n2"):
        return ft.objective_n_features(x, y, th, ds)
    if name == "obj_m":
        return ft.objective_m_features(x, y, th, ds)
    raise ConfigError(f"unknown gradient model {name!r}")


def subset_keeping_extremes(x: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Sorted indices of n of the samples ``x`` (n,) drawn uniformly without replacement, with the
    samples of least and largest x in place of two of the drawn ones where the draw missed them."""
    n_all = x.size
    if n >= n_all:
        return np.arange(n_all)
    idx = rng.choice(n_all, size=n, replace=False)
    ends = list(dict.fromkeys((int(np.argmin(x)), int(np.argmax(x)))))[:n]
    missing = [i for i in ends if i not in set(idx.tolist())]
    free = [k for k in range(n) if int(idx[k]) not in ends][:len(missing)]
    idx[free] = missing
    return np.sort(idx)


def inner_segments(n_segments: int, trim_ends: int) -> np.ndarray:
    """Segment mask without the first and last ``trim_ends`` segments."""
    keep = np.ones(n_segments, dtype=bool)
    if trim_ends:
        keep[:trim_ends] = keep[-trim_ends:] = False
    return keep


KAPPA_OPERATOR = "kappa_operator"  # key of the arrays: L (N, N), rebuilt curvature = L true curvature
KAPPA_CALIBRATION = "kappa_calibration"  # key of the arrays: (2, N) mean, shrink factor of each rebuilt kappa


def training_data(arr: dict[str, np.ndarray], params: RodParams, name: str,
                  center: float | None, segments: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """All (X, y) samples of one model from the prefilter arrays (before subsampling).

    ``segments``: a boolean mask over the N segments (nodes) of a constitutive model, the ones
    kept (camera data, ``crgpr learn``: the ends, whose angles derived from positions are
    extrapolations (``inner_segments``), or the segments whose curvature the positions do not
    resolve are left out); the momentum models keep every node. Where the arrays carry the
    curvature reconstruction's operator L (``KAPPA_OPERATOR``, camera data:
    ``learning.camera``), the bending moments of ``obj_m`` are L m per frame, smoothed along the
    rod as its rebuilt curvatures are. Where they carry ``KAPPA_CALIBRATION`` (rows: mean mu_j and
    factor lambda_j of each segment, ``learning.camera.curvature_calibration``), ``obj_m``'s own
    curvature input kappa_j is mu_j + lambda_j (kappa_j - mu_j) (errors in variables).
    """
    x, y, th = arr["x"], arr["y"], arr["theta"]
    ds = params.ds
    hz = ft.hz_targets(arr, params)
    p = np.stack([arr[STATE_NAMES[3 + k]] for k in range(3)], axis=-1)
    X = model_features(x, y, th, p, ds, name, center)
    if name == "obj_m" and KAPPA_CALIBRATION in arr:
        mu, lam = np.asarray(arr[KAPPA_CALIBRATION], dtype=float)
        X[..., 0] = mu + lam * (X[..., 0] - mu)
    if name in ("q_x", "q_y"):
        tgt = ft.q_from_hz(hz[..., 0 if name == "q_x" else 1], params)
    elif name == "dH_dtheta":
        tgt = hz[:, 1:, 2]
    elif name in MOMENTUM_MODELS:
        tgt = hz[:, 1:, 3 + MOMENTUM_MODELS.index(name)]
    else:
        sg = ft.segments(x, y, th, ds)
        qx, qy = ft.q_from_hz(hz[..., 0], params), ft.q_from_hz(hz[..., 1], params)
        n1 = qx * sg["cos"] + qy * sg["sin"]
        n2 = -qx * sg["sin"] + qy * sg["cos"]
        if name == "obj_n1":
            tgt = n1
        elif name == "obj_n2":
            tgt = n2
        else:
            c = sg["nu1"] * n2 - sg["nu2"] * n1
            tgt = ft.moments_from_htheta(hz[..., 2], c, params)
            if KAPPA_OPERATOR in arr:
                tgt = tgt @ np.asarray(arr[KAPPA_OPERATOR]).T
    if segments is not None and name not in MOMENTUM_MODELS:
        X, tgt = X[:, segments], tgt[:, segments]
    return X.reshape(-1, X.shape[-1]), tgt.reshape(-1)


def state_inputs(paths: list[str | Path], params: RodParams, name: str, center: float | None,
                 every: int) -> np.ndarray:
    """Inputs of model ``name`` at every ``every``-th record (t > 0) of ground-truth files."""
    out = []
    for path in paths:
        tr = trajectory_from_frame(read_parquet(path), params)
        q, p = tr.q[1::every], tr.p[1::every]
        X = model_features(q[..., 0], q[..., 1], q[..., 2], p, params.ds, name, center)
        out.append(X.reshape(-1, X.shape[-1]))
    return np.concatenate(out) if out else np.zeros((0, 1))


# ---------------------------------------------------------------------------------------------
# approximations of the posterior mean for the rollouts
# ---------------------------------------------------------------------------------------------
def _err(a: np.ndarray, b: np.ndarray, scale: float) -> dict[str, float]:
    d = a - b
    if d.size == 0:
        return {"rmse": float("nan"), "max_abs": float("nan"), "rmse_over_target_std": float("nan")}
    return {"rmse": float(np.sqrt(np.mean(d**2))), "max_abs": float(np.abs(d).max()),
            "rmse_over_target_std": float(np.sqrt(np.mean(d**2)) / scale)}


def _dtc_worst_over_std(errs: dict[str, dict[str, float]], ystd: float) -> float:
    """Largest |DTC - exact| over the check sets (an empty set does not count), x target std."""
    worst = [e["max_abs"] for e in errs.values() if np.isfinite(e["max_abs"])]
    return max(worst) / ystd if worst else float("inf")


def _use_exact_mean(gm: dict[str, Any], dtc_errs: dict[str, dict[str, float]], ystd: float) -> bool:
    """``rollout_mean``: exact, dtc, or auto = exact unless the DTC mean's largest measured error
    at both check sets is below ``dtc_max_error`` target std (then the two integrate the same
    model and DTC costs M instead of up to n kernel terms a state)."""
    if gm["rollout_mean"] == "auto":
        return not _dtc_worst_over_std(dtc_errs, ystd) <= float(gm["dtc_max_error"])
    return gm["rollout_mean"] == "exact"


def _choice_note(gm: dict[str, Any], use_exact: bool) -> str:
    if gm["rollout_mean"] != "auto":
        return f"rollout_mean {gm['rollout_mean']} (config)"
    side = "above" if use_exact else "below"
    return (f"rollout_mean auto: {'exact' if use_exact else 'dtc'} (DTC's largest error at the check "
            f"sets {side} dtc_max_error = {float(gm['dtc_max_error']):g} target std)")


def _reduced_dtc(gp: GP, arrays: dict[str, np.ndarray], gm: dict[str, Any], sets: dict[str, np.ndarray],
                 dense: Any, ystd: float) -> tuple[KernelMean, np.ndarray, np.ndarray] | None:
    """The DTC mean on the pivoted-Cholesky subset of its inducing inputs (``nystrom_reduce``,
    ``dtc_rank_tol``): used for the rollout if it has at most half the terms and stays within
    ``dtc_max_error`` target std of the exact mean at both check sets; else None."""
    tol = float(gm["dtc_rank_tol"])
    if tol <= 0:
        return None
    piv, w = nystrom_reduce(arrays["dtc_Z"], arrays["dtc_w"], gp.kernel, gp.ell, tol)
    if len(piv) > arrays["dtc_Z"].shape[0] // 2:
        return None
    ev = KernelMean.dtc(gp, arrays["dtc_Z"][piv], w[:, 0], arrays["dtc_beta"][:, 0])
    worst = _dtc_worst_over_std({k: _err(ev(v), dense(v), ystd) for k, v in sets.items()}, ystd)
    return (ev, piv, w) if worst <= float(gm["dtc_max_error"]) else None


def hyper_bounds(X: np.ndarray, hb: dict[str, Any]
                 ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[float, float]]:
    """Lengthscale and sigma_f bounds in standardised units (``gradient_models.hyper_bounds``):
    ell_k in [lo, hi] x spread_k, spread_k = (max - min) / std of input k over X; sigma_f in
    [sigma_f_min_std, sigma_f_max_std] (the target's std is 1 in these units)."""
    sd = X.std(0)
    sd[sd <= 1e-300] = 1.0
    spread = (X.max(0) - X.min(0)) / sd
    spread[spread <= 0] = 1.0
    return ((float(hb["ell_min_over_spread"]) * spread, float(hb["ell_max_over_spread"]) * spread),
            (float(hb["sigma_f_min_std"]), float(hb["sigma_f_max_std"])))


def fit_model(name: str, X: np.ndarray, y: np.ndarray, spec: dict[str, Any], gm: dict[str, Any],
              seed: int, check_X: np.ndarray | None = None, hyper: str = "fitted"
              ) -> tuple[GP, dict[str, np.ndarray], dict[str, Any]]:
    """Fit one gradient GP and its rollout mean; returns (gp, arrays, report).

    ``check_X``: inputs at ground-truth test states where the rollout mean is compared with the
    dense exact mean; ``hyper``: 'fitted' (marginal likelihood, bounded) or 'paper_table2'.
    """
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    n_all = X.shape[0]
    n = min(int(spec["n_train"]), n_all)
    idx = np.sort(rng.choice(n_all, size=n, replace=False)) if n < n_all else np.arange(n_all)
    Xn, yn = X[idx], y[idx]
    one_d = X.shape[1] == 1
    common = {"kernel": spec["kernel"], "basis": spec["basis"], "ard": bool(spec["ard"]),
              "sigma_n_min": float(spec["sigma_n_min"]) or None, "factorise": False}
    bounds: dict[str, Any] = {}
    if hyper == "paper_table2":
        probe = fit_gp(Xn, yn, fixed={"sigma_f": 1.0, "lengthscales": 1.0, "sigma_n": 1.0}, **common)
        fixed = paper_hyperparameters(name, probe.x_scale, float(probe.y_scale[0]), bool(spec["ard"]))
        gp = fit_gp(Xn, yn, fixed=fixed, **{**common, "sigma_n_min": None})
        hyp_src = "paper Table II in original units (paper_hyperparameters)"
    elif hyper == "fitted":
        # 1D momentum models: a nearly noise-free, nearly linear map; start from a long lengthscale
        # and a small noise (the LML surface is flat there), with extra restarts (cheap in 1D)
        ell_b, sf_b = hyper_bounds(Xn, gm["hyper_bounds"])
        bounds = {"ell_bounds_std": [ell_b[0].tolist(), ell_b[1].tolist()], "sigma_f_bounds_std": list(sf_b)}
        init = ({"sigma_f": 3.0, "lengthscales": 5.0, "sigma_n": 1e-3} if one_d
                else {"sigma_f": 1.0, "lengthscales": 1.0, "sigma_n": 0.05})
        # low-dimensional laws (1D; the bending law of kappa and s) are cheap to refit and their
        # LML surface has several optima: at least three starts
        starts = max(int(gm["n_restarts"]), 3) if X.shape[1] <= 2 else int(gm["n_restarts"])
        gp = fit_gp(Xn, yn, n_restarts=starts,
                    seed=seed, hyper_subset=int(gm["n_hyper"]), init=init, ell_bounds=ell_b,
                    sigma_f_bounds=sf_b, **common)
        hyp_src = f"marginal likelihood on {min(int(gm['n_hyper']), n)} points, bounded (hyper_bounds)"
    else:
        raise ConfigError(f"gradient model {name}: unknown hyperparameter source {hyper!r}")
    t_hyper = time.perf_counter() - t0
    ystd = float(np.std(yn)) or 1.0
    report: dict[str, Any] = {"model": name, "n_available": int(n_all), "n": int(n),
                              "hyper_subset": int(min(int(gm["n_hyper"]), n)) if hyper == "fitted" else 0,
                              "hyper_subset_choice": f"uniform random without replacement, seed {seed}",
                              "hyperparameters": hyper, "hyperparameter_source": hyp_src,
                              **bounds, "seconds_hyper": t_hyper,
                              "lml_hyper_subset": gp.lml, "target_std": ystd}
    check_X = np.zeros((0, X.shape[1])) if check_X is None else np.asarray(check_X, dtype=float)
    ci = rng.choice(n, size=min(int(gm["check_points"]), n), replace=False)
    sets = {"training inputs": Xn[ci], "ground-truth test states": check_X}
    if gp.dim == 1:
        alpha, beta = exact_weights(gp)
        dense = KernelMean.exact(gp, tol=0.0, weights=(alpha, beta))
        grid = law_grid(Xn[:, 0], float(np.ravel(gp.lengthscales)[0] * gp.x_scale[0]))
        tab = Table1D(grid, dense(grid))
        arrays = {"table_x": grid, "table_y": tab.ty}
        sets["training inputs"] = rng.uniform(grid[0], grid[-1], int(gm["check_points"]))[:, None]
        report["approximation"] = f"exact mean tabulated ({grid.size} points, linear interpolation)"
        rollout_ev: Any = lambda Z: tab(Z[:, 0])  # noqa: E731
        report["truncation_bound_over_target_std"] = 0.0
    else:
        V = ((yn - gp.y_mean[0]) / gp.y_scale[0])[:, None]
        M = int(gm["inducing"])
        arrays = dtc_fit(gp, Xn, V, M, seed)
        dtc = KernelMean.dtc(gp, arrays["dtc_Z"], arrays["dtc_w"], arrays["dtc_beta"])
        t1 = time.perf_counter()
        alpha, beta = exact_weights(gp)
        report["seconds_exact_weights"] = time.perf_counter() - t1
        dense = KernelMean.exact(gp, tol=0.0, weights=(alpha, beta))
        tol = float(gm["exact_tol"])
        report["exact_tol"] = tol
        report["dtc_error_vs_exact"] = {k: _err(dtc(v), dense(v), ystd) for k, v in sets.items()}
        use_exact = _use_exact_mean(gm, report["dtc_error_vs_exact"], ystd)
        if use_exact:
            arrays.update(mean_alpha=alpha, mean_beta=beta)
            rollout_ev = KernelMean.exact(gp, tol=tol, weights=(alpha, beta))
            report["approximation"] = (f"exact posterior mean over all n = {n} points, kernel sums "
                                       f"truncated below {tol:g} sigma_f^2 (cell grid)")
            report["truncation_bound_over_target_std"] = rollout_ev.truncation_bound / ystd
        else:
            rollout_ev = dtc
            report["approximation"] = f"DTC mean, M = {len(arrays['dtc_Z'])} farthest-point inducing inputs"
            report["truncation_bound_over_target_std"] = float("nan")
            red = _reduced_dtc(gp, arrays, gm, sets, dense, ystd)
            if red is not None:
                rollout_ev, arrays["rollout_pivots"], arrays["rollout_w"] = red
                r_tol, r = float(gm["dtc_rank_tol"]), len(arrays["rollout_pivots"])
                report["approximation"] += (f", on the {r} pivoted-Cholesky pivots of its inducing inputs "
                                            f"(dtc_rank_tol {r_tol:g})")
        report["rollout_mean_choice"] = _choice_note(gm, use_exact)
        report["fit_rmse_over_target_std"] = float(np.sqrt(np.mean((dense(Xn) - yn) ** 2)) / ystd)
    errs = {k: _err(rollout_ev(v), dense(v), ystd) for k, v in sets.items()}
    worst = max(sets, key=lambda k: np.nan_to_num(errs[k]["rmse_over_target_std"], nan=-1.0))
    report["approx_error_vs_exact_at"] = errs
    report["approx_error_vs_exact"] = errs[worst]
    report["approx_error_measured_at"] = worst
    report["approx_check"] = (f"dense exact posterior mean over all n = {n} points at "
                              f"{len(sets['training inputs'])} training inputs and {len(check_X)} "
                              f"ground-truth test states; the larger error ({worst})")
    report["seconds"] = time.perf_counter() - t0
    log.info("%s: n = %d, %s, error vs exact %s, %.1f s", name, n, report["approximation"],
             report["approx_error_vs_exact_at"], report["seconds"])
    return gp, arrays, report


def train_model_arrays(cfg: dict[str, Any], name: str, arr: dict[str, np.ndarray], params: RodParams,
                       out_stem: str | Path, source: str, prefilter_method: str,
                       extra: dict[str, Any] | None = None, segments: np.ndarray | None = None,
                       check_states: list[str] | None = None, hyper: str = "fitted",
                       columns: list[int] | None = None, odd_about: float | None = None,
                       arclength: bool = False) -> dict[str, Any]:
    """Fit model ``name`` on derivative-data arrays (schema of ``prefiltered_arrays``) and save it.

    ``params`` is the rod the arrays live on (its N sets the node grid); ``extra`` is added
    to the model's JSON; ``segments`` see ``training_data``; ``check_states``:
    ground-truth trajectory files at whose states the rollout mean is checked; ``hyper``: 'fitted' or
    'paper_table2'; ``columns``: fit on these columns of the model's features only (recorded as
    ``feature_columns``; the evaluator must be given the same columns, ``crgpr learn``'s
    grey-box bending law); ``odd_about``: a 1-D law odd about this input value (the bending
    moment of a rod with a symmetric section about its rest curvature, m(2 k0 - k) = -m(k)):
    n_train / 2 samples and their reflections (2 k0 - x, -y) are the training set; ``arclength``:
    the segment's arclength s (midpoint, ``features.segment_arclength``) is appended as the last
    input (a law varying along the rod; recorded as ``arclength_input``; with ``odd_about`` only
    the first input is reflected). Used by stage 2 (prefilter files) and by ``crgpr learn``
    (camera data).
    """
    gm = cfg["gradient_models"]
    spec = model_spec(cfg, name)
    if arr["x"].shape[1] != params.N + 1:
        raise ValueError(f"{source}: {arr['x'].shape[1]} nodes but the rod has N + 1 = {params.N + 1}")
    center = ft.theta_center(arr["theta"]) if gm["theta_wrap"] else None
    X, y = training_data(arr, params, name, center, segments)
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(y))):
        raise ValueError(f"{source}: non-finite features or targets for model {name}")
    seed = stage_seed(cfg["seed"], "gradient_model", ALL_MODELS.index(name))
    check_X = (state_inputs(check_states, params, name, center, int(gm["check_every"]))
               if check_states else None)
    feats = list(FEATURE_NAMES[name])
    if columns is not None:
        X = X[:, columns]
        check_X = None if check_X is None else check_X[:, columns]
        feats = [feats[c] for c in columns]
    if arclength:
        if check_X is not None or name != "obj_m":
            raise ConfigError(f"model {name}: arclength as an input is for obj_m without check states")
        s_mid = ft.segment_arclength(params.N, params.ds)
        S = np.broadcast_to(s_mid, (arr["x"].shape[0], params.N))
        X = np.column_stack([X, (S if segments is None else S[:, segments]).reshape(-1)])
        feats = [*feats, "s"]
    spread = np.ptp(X, axis=0)
    flat = [f"{f} (spread {sp:.1e})" for f, sp in zip(feats, spread, strict=True)
            if sp <= float(gm["min_input_spread"])]
    if flat:
        raise ValueError(f"{source}: model {name}: the training trajectory does not excite "
                         f"{', '.join(flat)} (config key gradient_models.min_input_spread); "
                         "train on a trajectory that moves them (angles.train_deg)")
    if odd_about is not None:
        if X.shape[1] != 1 + int(arclength):
            raise ConfigError(f"model {name}: an odd-symmetric law needs one input (and s), got {X.shape[1]}")
        # n_train / 2 samples (seeded) and their reflections: the training set is exactly symmetric;
        # the subset keeps the samples of least and largest curvature, so that the law's covered
        # range (and the reach of its data beyond the linear trend) is the record's, not the subset's
        keep = subset_keeping_extremes(X[:, 0], min(int(spec["n_train"]) // 2, X.shape[0]),
                                       np.random.default_rng(seed))
        X, y = X[keep], y[keep]
        Xr = X.copy()
        Xr[:, 0] = 2.0 * odd_about - X[:, 0]
        X, y = np.concatenate([X, Xr]), np.concatenate([y, -y])
    gp, arrays, report = fit_model(name, X, y, spec, gm, seed, check_X, hyper)
    meta = {"name": name, "features": feats, "theta_center": center,
            **({"feature_columns": list(columns)} if columns is not None else {}),
            **({"odd_about": float(odd_about)} if odd_about is not None else {}),
            **({"arclength_input": True} if arclength else {}),
            "prefilter": prefilter_method, "source": str(source), "seed": seed, **report,
            "check_states": [str(c) for c in (check_states or [])],
            "target": "H_z = (J - R)^-1 (dz/dt - G u), features.py", **(extra or {})}
    gp.save(out_stem, extra=meta, extra_arrays=arrays)
    return meta


def train_model(cfg: dict[str, Any], name: str, prefiltered: str | Path, out_stem: str | Path,
                prefilter_method: str = "gp", check_states: list[str] | None = None,
                hyper: str = "fitted") -> dict[str, Any]:
    """Build the data set of ``name`` from a prefilter Parquet file, fit, and save."""
    arr = prefiltered_arrays(read_prefiltered(prefiltered))
    return train_model_arrays(cfg, name, arr, rod_params(cfg), out_stem, str(prefiltered), prefilter_method,
                              check_states=check_states, hyper=hyper)
