"""Figures of the CR-GPR results (paper Figs. 3-5): overlays, rod shapes, dissipated power and energy balance.

All figures use matplotlib's Agg backend and are written atomically (io.atomic_path).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from crgpr.io import (  # noqa: E402
    atomic_path,  # noqa: E402
    frame_to_grid,
)
from crgpr.physics.rod import STATE_NAMES  # noqa: E402

LABELS = {"x": "x [m]", "y": "y [m]", "theta": r"$\theta$ [rad]", "p_x": r"$p_x$ [kg/s]",
          "p_y": r"$p_y$ [kg/s]", "p_theta": r"$p_\theta$ [kg m/s]"}


def _save(fig: plt.Figure, path: str | Path) -> None:
    with atomic_path(path, ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=130, bbox_inches="tight")
    plt.close(fig)


def _arrays(df: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    return frame_to_grid(df, STATE_NAMES)


def overlays(gt: pd.DataFrame, pred: pd.DataFrame, out: str | Path, method: str, angle: float) -> None:
    """Ground truth (solid) vs learned (dashed) at base, mid and tip nodes for all six states (Fig. 3)."""
    tg, zg = _arrays(gt)
    tp, zp = _arrays(pred)
    N = zg.shape[1] - 1
    nodes = [1, N // 2, N]
    colors = ["tab:blue", "tab:green", "tab:red"]
    fig, axes = plt.subplots(3, 2, figsize=(10, 8), sharex=True)
    for k, name in enumerate(STATE_NAMES):
        ax = axes[k % 3, k // 3]
        for c, i in zip(colors, nodes, strict=True):
            ax.plot(tg, zg[:, i, k], color=c, lw=1.4, label=f"node {i} truth")
            ax.plot(tp, zp[:, i, k], color=c, lw=1.4, ls="--", label=f"node {i} {method}")
        ax.set_ylabel(LABELS[name])
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    axes[0, 0].legend(fontsize=7, ncol=2)
    fig.suptitle(f"Ground truth (solid) vs {method} (dashed), theta0 = {angle:g} deg")
    _save(fig, out)


def shapes(gt_train: pd.DataFrame, gt_test: pd.DataFrame, pred_test: pd.DataFrame, out: str | Path,
           method: str, train_angle: float, test_angle: float, n_frames: int = 6) -> None:
    """Rod shapes over time: training trajectory (left), test angle truth vs learned (right) (Fig. 4)."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.5))
    t0, z0 = _arrays(gt_train)
    idx = np.linspace(0, t0.size - 1, n_frames).round().astype(int)
    cmap = plt.get_cmap("viridis")
    for j, i in enumerate(idx):
        axes[0].plot(z0[i, :, 0], z0[i, :, 1], "-o", ms=2, color=cmap(j / max(1, n_frames - 1)),
                     label=f"t = {t0[i]:.2f} s")
    axes[0].set_title(f"Ground truth, training trajectory (theta0 = {train_angle:g} deg)")
    tg, zg = _arrays(gt_test)
    tp, zp = _arrays(pred_test)
    idx = np.linspace(0, tg.size - 1, 4).round().astype(int)
    for j, i in enumerate(idx):
        c = cmap(j / 3)
        ip = int(np.argmin(np.abs(tp - tg[i])))
        axes[1].plot(zg[i, :, 0], zg[i, :, 1], "--", color=c, lw=2, label=f"truth t = {tg[i]:.2f} s")
        axes[1].plot(zp[ip, :, 0], zp[ip, :, 1], "-", color=c, lw=1.2, label=f"{method} t = {tp[ip]:.2f} s")
    axes[1].set_title(f"{method} vs ground truth (theta0 = {test_angle:g} deg)")
    for ax in axes:
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    _save(fig, out)


def energy(learned: pd.DataFrame, gt_energy: pd.DataFrame, out: str | Path, method: str,
           angle: float) -> None:
    """Dissipated power E(t) = H_z^T R H_z (Fig. 5) and the learned model's energy balance."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    ax = axes[0]
    ax.plot(gt_energy["t"], gt_energy["dissipation_rate"], color="k", lw=1.2, label="ground truth")
    ax.plot(learned["t"], learned["dissipation_rate"], color="tab:red", ls="--", lw=1.2, label=method)
    ax.set_yscale("symlog", linthresh=1e-6)
    ax.set_xlabel("t [s]")
    ax.set_ylabel(r"$E(t) = H_z^T R H_z$ [W]")
    ax.set_title(f"Dissipated power (min {learned['dissipation_rate'].min():.2e} W >= 0)")
    ax.legend()
    ax.grid(alpha=0.3)
    ax = axes[1]
    h0 = learned["H_learned"].iloc[0]
    ax.plot(learned["t"], learned["H_learned"] - h0, color="tab:red",
            label=r"learned $\Delta(\hat H + U_g)$ (path integral of $\hat H_z$)")
    ax.plot(learned["t"], -learned["dissipated"], color="tab:orange", ls=":", lw=2,
            label=r"$-\int_0^t E\,dt$ (learned)")
    ax.plot(gt_energy["t"], gt_energy["H"] - gt_energy["H"].iloc[0], color="k", lw=1,
            label=r"ground truth $\Delta(H + U_g)$")
    ax.plot(learned["t"], learned["balance_residual"], color="tab:purple", lw=1, label="balance residual")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("energy [J]")
    ax.set_title(f"Energy balance of {method}, theta0 = {angle:g} deg")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    _save(fig, out)


def oracle_ablation_figure(table: pd.DataFrame, pointwise: pd.DataFrame, out: str | Path,
                           paper_mean: float = 0.222) -> None:
    """Oracle ablation: RMSE(theta) per variant (left), pointwise errors / target std (right)."""
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.2), gridspec_kw={"width_ratios": [1.5, 1]})
    order = list(dict.fromkeys(table["variant"]))
    for k, v in enumerate(order):
        sub = table[table["variant"] == v]
        vals = sub["rmse_theta"].to_numpy(dtype=float)
        ok = np.isfinite(vals)
        ax1.bar(k, np.nanmean(vals) if ok.any() else 0.0, color="C0" if v == "all_oracle" else
                ("C3" if v == "all_learned" else "C7"), alpha=0.6)
        ax1.plot(np.full(ok.sum(), k), vals[ok], "k.", ms=4)
        if (~ok).any():
            ax1.text(k, ax1.get_ylim()[1] if ok.any() else 1.0, f"{(~ok).sum()} diverged", ha="center",
                     fontsize=7, rotation=90, va="top")
    ax1.axhline(paper_mean, color="C2", ls="--", label=f"paper cr_gpr mean {paper_mean}")
    ax1.set_yscale("log")
    ax1.set_xticks(range(len(order)), [v.replace("learned_", "learned ") for v in order], rotation=35,
                   ha="right", fontsize=8)
    ax1.set_ylabel(r"RMSE($\theta$) [rad], bars = mean over test angles")
    ax1.set_title("rest oracle, named component learned")
    ax1.legend(fontsize=8)
    x = np.arange(len(pointwise))
    floor = 1e-16
    ax2.bar(x - 0.2, np.maximum(pointwise["oracle_rmse_over_std"], floor), 0.4, label="oracle", color="C0")
    ax2.bar(x + 0.2, np.maximum(pointwise["learned_rmse_over_std"], floor), 0.4, label="learned (cr_gpr)",
            color="C3")
    ax2.axhline(1.0, color="k", lw=0.8, ls=":")
    ax2.set_yscale("log")
    ax2.set_xticks(x, pointwise["component"], rotation=35, ha="right", fontsize=8)
    ax2.set_ylabel("RMS error / target std (85 deg, true H_z)")
    ax2.set_title("pointwise, training trajectory")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    _save(fig, out)
