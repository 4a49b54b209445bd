"""Table II: the gradient GPs' hyperparameters beside the paper's (``table2_hyperparameters.csv``),
and the log marginal likelihood of ours and of the paper's values on the same data
(``paper_hyp_lml.csv``).

Reads the models' files (step 3, ``crgpr.learning.gradient_models``); values in the models'
output and input units.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.gp import GP, basis_matrix_std
from crgpr.gp._gpr import _neg_lml
from crgpr.learning.gradient_models import PAPER_TABLE2, paper_hyperparameters


def table2(model_jsons: list[str | Path]) -> pd.DataFrame:
    """Table II: our hyperparameters (output/input units) beside the paper's, one row per model.

    ``approx_rmse_over_target_std``: RMS of (the mean the rollout integrates - the dense exact
    posterior mean over all n points) / target std, the larger of its values at random training
    inputs and at the test angles' ground-truth states (``approx_measured_at``);
    ``truncation_bound_over_target_std``: a bound on that error at any input (exact mean);
    ``dtc_rmse_over_target_std``: the same for the DTC mean the UQ samples are centred on;
    ``fit_rmse_over_target_std``: RMS of (exact posterior mean - target) / target std at the
    training inputs (how much of its own training data the GP explains).
    """
    rows = []
    for p in model_jsons:
        meta = json.loads(Path(p).read_text())
        name = meta["name"]
        paper = PAPER_TABLE2.get(name, {})
        dtc = meta.get("dtc_error_vs_exact", {})
        rows.append({
            "model": name, "prefilter": meta.get("prefilter"),
            "hyperparameters": meta.get("hyperparameters", "fitted"),
            "kernel": ("ARD-" if meta["ard"] else "") + meta["kernel"].upper(), "basis": meta["basis"],
            "features": " ".join(meta["features"]),
            "sigma_f": meta["sigma_f"],
            "lengthscales": "[" + ", ".join(f"{v:.4g}" for v in meta["lengthscales"]) + "]",
            "sigma_n": meta["sigma_n"],
            "sigma_n_lower_bound": meta["info"].get("sigma_n_lower_std", math.nan) * meta["y_scale"][0],
            "n": meta["n"], "n_hyper": meta["hyper_subset"], "lml_hyper_subset": meta.get("lml_hyper_subset"),
            "rollout_mean": meta.get("approximation", ""),
            "approx_rmse_over_target_std": meta["approx_error_vs_exact"]["rmse_over_target_std"],
            "approx_measured_at": meta.get("approx_check", ""),
            "truncation_bound_over_target_std": meta.get("truncation_bound_over_target_std", math.nan),
            "dtc_rmse_over_target_std": max((v["rmse_over_target_std"] for v in dtc.values()),
                                            default=math.nan),
            "fit_rmse_over_target_std": meta.get("fit_rmse_over_target_std", math.nan),
            "paper_kernel": paper.get("kernel", ""), "paper_basis": paper.get("basis", ""),
            "paper_sigma_f": paper.get("sigma_f", math.nan), "paper_lengthscales": paper.get("ell", ""),
            "paper_sigma_n": paper.get("sigma_n", math.nan), "paper_n": paper.get("n", math.nan),
        })
    return pd.DataFrame(rows)


def lml(gp: GP, sigma_f: float, lengthscales: np.ndarray, sigma_n: float, idx: np.ndarray) -> float:
    """Vague-prior log marginal likelihood (R&W eq. (2.45)) of standardised hyperparameters on
    rows ``idx`` of ``gp``'s training data (its standardisation)."""
    U = gp.Xs[idx]
    V = gp.y[idx][:, None]
    th = np.r_[math.log(sigma_f), np.log(np.ravel(lengthscales)), math.log(sigma_n)]
    return -float(_neg_lml(th, gp.kernel, gp.ard, U, V, basis_matrix_std(gp.basis, U))[0])


def lml_table(fitted_stems: list[str | Path]) -> pd.DataFrame:
    """LML of our fitted hyperparameters and of the paper's Table II values on the SAME data: the
    seeded subset on which ours were searched (``fit_gp``'s draw: its seed and ``hyper_n``).

    Table II read in original units (``paper_hyperparameters``, the mapping of
    ``cr_gpr_paper_hyp``) and, for comparison, with ell read as standardised.
    """
    rows = []
    for stem in fitted_stems:
        stem = Path(stem).with_suffix("")
        gp = GP.load(stem)
        meta = json.loads(stem.with_suffix(".json").read_text())
        name = meta["name"]
        m = int(gp.info.get("hyper_n", gp.n))
        idx = np.arange(gp.n)
        if m < gp.n:
            idx = np.sort(np.random.default_rng(int(gp.info["seed"])).choice(gp.n, size=m, replace=False))
        ys = gp.out_scale
        paper = paper_hyperparameters(name, gp.x_scale, ys, gp.ard)
        paper_std = paper_hyperparameters(name, gp.x_scale, ys, gp.ard, inputs_standardised=True)
        rows.append({
            "model": name, "prefilter": meta.get("prefilter"), "n_lml": int(idx.size),
            "seed": int(gp.info["seed"]),
            "lml_ours": lml(gp, gp.sigma_f, gp.lengthscales, gp.sigma_n, idx),
            "lml_ours_saved": gp.lml,
            "lml_paper_table2": lml(gp, paper["sigma_f"], paper["lengthscales"], paper["sigma_n"], idx),
            "lml_paper_table2_ell_standardised": lml(gp, paper_std["sigma_f"], paper_std["lengthscales"],
                                                     paper_std["sigma_n"], idx),
            "ours_sigma_f_std": gp.sigma_f,
            "ours_lengthscales_std": " ".join(f"{v:.4g}" for v in np.ravel(gp.lengthscales)),
            "ours_sigma_n_std": gp.sigma_n,
            "paper_sigma_f_std": paper["sigma_f"],
            "paper_lengthscales_std": " ".join(f"{v:.4g}" for v in np.ravel(paper["lengthscales"])),
            "paper_sigma_n_std": paper["sigma_n"],
        })
    return pd.DataFrame(rows)
