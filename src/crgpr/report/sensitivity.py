"""Sensitivity of the faithful CR-GPR pipeline to what the paper leaves open.

One row per pipeline variant (``variants.sensitivity``): the paper's pipeline with one choice
changed (Poisson ratio, angle wrapping, n_train, n_hyper, sigma_n floors, the prefilter),
scored on the six test angles against the variant's own ground truth (the paper's Table III
metric, RMSE(theta) [rad] over every node and record), with the number of diverged rollouts.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from crgpr.io import atomic_path  # noqa: E402

# columns every variant's accuracy file carries (crgpr.commands.variant_report.variant_metrics)
VARIANT_ACCURACY = ("variant", "method", "theta0_deg", "rmse_theta", "r2_theta", "tip_rmse_over_L",
                    "diverged", "t_diverged")


def table(accuracy: dict[str, pd.DataFrame], definitions: dict[str, dict[str, Any]],
          angles: list[int]) -> pd.DataFrame:
    """Rows ``variant, method, overlay, rmse_theta_mean, rmse_theta_<angle>..., r2_theta_mean,
    tip_rmse_over_L_mean, divergences, diverged_at, n_angles`` in the order of ``accuracy``.

    ``overlay`` is the variant's config overlay as compact JSON; a missing angle is NaN and
    makes the mean NaN (no mean over a subset of angles).
    """
    rows = []
    for name, acc in accuracy.items():
        sel = acc.set_index("theta0_deg")
        row: dict[str, Any] = {"variant": name, "method": definitions[name]["method"],
                               "overlay": json.dumps(definitions[name]["overlay"], sort_keys=True,
                                                     separators=(",", ":"))}
        per = [float(sel.loc[float(a), "rmse_theta"]) if float(a) in sel.index else np.nan for a in angles]
        row["rmse_theta_mean"] = float(np.mean(per))
        for a, v in zip(angles, per, strict=True):
            row[f"rmse_theta_{a}"] = v
        for c in ("r2_theta", "tip_rmse_over_L"):
            vals = [float(sel.loc[float(a), c]) if float(a) in sel.index else np.nan for a in angles]
            row[f"{c}_mean"] = float(np.mean(vals))
        div = sel[sel["diverged"].astype(bool)]
        row["divergences"] = int(len(div))
        row["diverged_at"] = "; ".join(f"{a:g} deg at {t:.3g} s" for a, t in zip(div.index, div["t_diverged"],
                                                                                strict=True))
        row["n_angles"] = int(sum(np.isfinite(per)))
        rows.append(row)
    return pd.DataFrame(rows)


def figure(tab: pd.DataFrame, angles: list[int], path: str | Path, reference: str | None = None) -> None:
    """Per-angle RMSE(theta) of each variant (markers) and its mean (bar); ``reference`` dashed."""
    fig, ax = plt.subplots(figsize=(max(6.0, 0.9 * len(tab) + 2), 4.0))
    x = np.arange(len(tab))
    ax.bar(x, tab["rmse_theta_mean"], color="0.8", label="mean over the test angles")
    for k, a in enumerate(angles):
        ax.plot(x + (k - (len(angles) - 1) / 2) * 0.08, tab[f"rmse_theta_{a}"], "o", ms=4, label=f"{a} deg")
    for i, n in enumerate(tab["divergences"]):
        if n:
            ax.annotate(f"{n} div.", (x[i], tab["rmse_theta_mean"].iloc[i]), ha="center", va="bottom",
                        fontsize=8)
    if reference is not None and reference in set(tab["variant"]):
        ref = float(tab.loc[tab["variant"] == reference, "rmse_theta_mean"].iloc[0])
        ax.axhline(ref, ls="--", color="k", lw=0.8, label=f"{reference} mean")
    ax.set_xticks(x, tab["variant"], rotation=30, ha="right")
    ax.set_ylabel(r"RMSE($\theta$) [rad]")
    ax.set_title("CR-GPR (paper features) sensitivity, six test angles")
    ax.legend(fontsize=7, ncol=2)
    with atomic_path(path, ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=130, bbox_inches="tight")
    plt.close(fig)
