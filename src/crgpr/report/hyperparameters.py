"""Table II: the gradient GPs' hyperparameters beside the paper's (``table2_hyperparameters.csv``).

Reads the models' JSON files (step 3, ``crgpr.learning.gradient_models``); values in the
models' output and input units.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd

from crgpr.learning.gradient_models import PAPER_TABLE2

# Paper Table II (gradient GPs): kernel, basis, sigma_f, lengthscales, sigma_n, n


def table2(model_jsons: list[str | Path]) -> pd.DataFrame:
    """Table II: our hyperparameters (output/input units) beside the paper's, one row per model."""
    rows = []
    for p in model_jsons:
        meta = json.loads(Path(p).read_text())
        name = meta["name"]
        paper = PAPER_TABLE2.get(name, {})
        rows.append({
            "model": name, "prefilter": meta.get("prefilter"),
            "kernel": ("ARD-" if meta["ard"] else "") + meta["kernel"].upper(), "basis": meta["basis"],
            "features": " ".join(meta["features"]),
            "sigma_f": meta["sigma_f"],
            "lengthscales": "[" + ", ".join(f"{v:.4g}" for v in meta["lengthscales"]) + "]",
            "sigma_n": meta["sigma_n"],
            "sigma_n_lower_bound": meta["info"].get("sigma_n_lower_std", math.nan) * meta["y_scale"][0],
            "n": meta["n"], "n_hyper": meta["hyper_subset"],
            "approx_rmse_over_target_std": meta["approx_error_vs_exact"]["rmse_over_target_std"],
            "paper_kernel": paper.get("kernel", ""), "paper_basis": paper.get("basis", ""),
            "paper_sigma_f": paper.get("sigma_f", math.nan), "paper_lengthscales": paper.get("ell", ""),
            "paper_sigma_n": paper.get("sigma_n", math.nan), "paper_n": paper.get("n", math.nan),
        })
    return pd.DataFrame(rows)
