"""Scores and figure of the actuated study (docs/ports.md, ``commands.ports.actuated_accuracy``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from crgpr.io import atomic_path  # noqa: E402
from crgpr.report.metrics import accuracy  # noqa: E402

COLUMNS: tuple[str, ...] = ("method", "train_signal", "test_signal", "theta0_deg", "rmse_theta",
                            "tip_rmse_over_L", "energy_balance_residual")


def balance_residual(H: Any, input_work: Any, dissipated: Any) -> float:
    """Largest |H(t) - H(0) - W(t) + D(t)| over the run, relative to the energy that flowed,
    max |W| + D(T) (W the port work int y^T u dt, D the dissipated energy; H the model's own
    stored energy plus gravity): 0 for an exact port-Hamiltonian balance."""
    H, W, D = (np.asarray(a, dtype=float) for a in (H, input_work, dissipated))
    res = H - H[0] - W + D
    return float(np.abs(res).max() / (np.abs(W).max() + abs(D[-1])))


def accuracy_row(method: str, train: str, test: str, theta0: float, gt: pd.DataFrame, pred: pd.DataFrame,
                 L0: float, residual: float) -> dict[str, Any]:
    """One row of ``actuated_accuracy.csv`` (``COLUMNS``; RMSE as in ``report.metrics.accuracy``)."""
    acc = accuracy(gt, pred, L0)
    return {"method": method, "train_signal": train, "test_signal": test, "theta0_deg": theta0,
            "rmse_theta": acc["rmse_theta"], "tip_rmse_over_L": acc["tip_rmse_over_L"],
            "energy_balance_residual": residual}


def diverged_row(method: str, train: str, test: str, theta0: float) -> dict[str, Any]:
    """The row of a rollout that diverged: its errors and balance are NaN."""
    nan = float("nan")
    return {"method": method, "train_signal": train, "test_signal": test, "theta0_deg": theta0,
            "rmse_theta": nan, "tip_rmse_over_L": nan, "energy_balance_residual": nan}


def actuated_figure(curves: dict[str, dict[str, Any]], out: str | Path) -> None:
    """Tip height over time under every sequence: the record (black) and each method's rollout."""
    sigs = list(curves)
    fig, axes = plt.subplots(len(sigs), 1, figsize=(7, 2.0 * len(sigs)), sharex=True, squeeze=False)
    for ax, sig in zip(axes[:, 0], sigs, strict=True):
        for name, tr in curves[sig].items():
            style = {"color": "k", "lw": 2.0} if name == "truth" else {"lw": 1.0, "ls": "--"}
            ax.plot(tr.t, tr.q[:, -1, 1], label=name, **style)
        ax.set_ylabel("tip y [m]")
        ax.set_title(sig, fontsize=9)
    axes[0, 0].legend(fontsize=7, ncol=4)
    axes[-1, 0].set_xlabel("t [s]")
    fig.tight_layout()
    with atomic_path(out, ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)


UQ_COLUMNS: tuple[str, ...] = ("method", "test_signal", "theta0_deg", "n_samples", "n_diverged", "level",
                               "expected_coverage", "tip_coverage", "theta_coverage",
                               "tip_band_width_mean_over_L", "theta_band_width_mean", "seconds")


def uq_figure(bands: dict[tuple[str, str], tuple[Any, Any, Any]], level: float, out: str | Path) -> None:
    """Tip height under every sequence: the record (black) and each method's ``level`` % band of
    its posterior-sample rollouts (``bands``: (method, signal) -> (t, tip xy of the samples
    (S, n_t, 2), tip xy of the record (n_t, 2)))."""
    from crgpr.uq.settings import band_percentiles

    methods = sorted({m for m, _ in bands})
    sigs = list(dict.fromkeys(s for _, s in bands))
    fig, axes = plt.subplots(len(sigs), len(methods), figsize=(4.5 * max(len(methods), 1), 1.9 * len(sigs)),
                             sharex=True, squeeze=False)
    lo, hi = band_percentiles(level)
    for i, sig in enumerate(sigs):
        for j, m in enumerate(methods):
            ax = axes[i, j]
            if (m, sig) not in bands:
                ax.set_axis_off()
                continue
            t, tips, truth = bands[(m, sig)]
            qlo, qhi = np.percentile(tips[..., 1], [lo, hi], axis=0)
            ax.fill_between(t, qlo, qhi, color="C0", alpha=0.35, lw=0, label=f"{level:g} % band")
            ax.plot(t, truth[:, 1], color="k", lw=1.0, label="record")
            ax.set_title(f"{m}, {sig}", fontsize=8)
            if j == 0:
                ax.set_ylabel("tip y [m]")
    axes[0, 0].legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    fig.tight_layout()
    with atomic_path(out, ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
