"""Figures of the trajectory UQ (paper Sec. V, "Uncertainty Quantification Results", Fig. 6
right): rod shapes with the sampled band, and the reliability diagram (nominal vs observed
coverage per method, beside the coverage a calibrated model reaches with the S used).

Matplotlib's Agg backend; written atomically (io.atomic_path).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from crgpr.io import atomic_path  # noqa: E402
from crgpr.uq.settings import band_percentiles  # noqa: E402


def _save(fig: plt.Figure, path: str | Path) -> None:
    with atomic_path(path, ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=150, bbox_inches="tight")
    plt.close(fig)


def band_figure(arr: np.ndarray, t: np.ndarray, truth: np.ndarray, level: float,
                time_fractions: Sequence[float], out: str | Path, method: str, theta0_deg: float,
                mean_model: np.ndarray | None = None) -> None:
    """Rod configurations at a few instants: the ``level`` % band (percentiles over the samples
    of the normal offsets from the median shape) shaded, the sampled shapes thin, the mean-model
    rollout solid red (else the sample median), the ground truth dashed blue.

    ``arr`` (S, n_t, n_nodes, 2) sampled x, y; ``truth`` and ``mean_model`` (n_t, n_nodes, 2)."""
    lo, hi = band_percentiles(level)
    qmed = np.percentile(arr, 50.0, axis=0)
    idx = [int(round(f * (len(t) - 1))) for f in time_fractions]
    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    colors = plt.cm.viridis(np.linspace(0.0, 0.85, len(idx)))
    for c, k in zip(colors, idx, strict=True):
        med = qmed[k]
        tan = np.gradient(med, axis=0)
        tan /= np.maximum(np.linalg.norm(tan, axis=1, keepdims=True), 1e-12)
        nrm = np.stack([-tan[:, 1], tan[:, 0]], axis=1)
        off = np.einsum("snk,nk->sn", arr[:, k] - med, nrm)  # (S, n_nodes) normal offsets
        o_lo, o_hi = np.percentile(off, [lo, hi], axis=0)
        # the tip: extend the band along the tangent by the tangential spread of the tip samples
        tang = np.einsum("sk,k->s", arr[:, k, -1] - med[-1], tan[-1])
        t_hi = max(float(np.percentile(tang, hi)), 0.0)
        poly = np.vstack([med + o_hi[:, None] * nrm, med[-1] + t_hi * tan[-1],
                          (med + o_lo[:, None] * nrm)[::-1]])
        ax.fill(poly[:, 0], poly[:, 1], color=c, alpha=0.3, lw=0)
        for smp in arr[:, k]:
            ax.plot(smp[:, 0], smp[:, 1], "-", color=c, lw=0.3, alpha=0.4)
        centre = med if mean_model is None else mean_model[k]
        ax.plot(centre[:, 0], centre[:, 1], "-", color="tab:red", lw=1.6)
        ax.plot(truth[k, :, 0], truth[k, :, 1], "--", color="tab:blue", lw=1.6)
        ax.annotate(f"t = {t[k]:.2f} s", med[-1], textcoords="offset points", xytext=(4, 4), fontsize=8,
                    color=c)
    S = arr.shape[0]
    ax.plot([], [], "-", color="tab:red",
            label="mean model" if mean_model is not None else f"median of S = {S}")
    ax.plot([], [], "-", color="gray", lw=0.4, label=f"S = {S} posterior samples")
    ax.plot([], [], "--", color="tab:blue", label="ground truth")
    ax.fill([], [], color="gray", alpha=0.3, label=f"{level:g} % band ({lo:g}-{hi:g} percentiles)")
    ax.plot(0, 0, "ks", ms=5)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{method}, theta0 = {theta0_deg:g} deg: rod shapes with the {level:g} % band")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    _save(fig, out)


def reliability_diagram(table: pd.DataFrame, out: str | Path) -> None:
    """Nominal level vs observed theta coverage (mean over the angles, each angle thin), one
    panel per method, for every S reported; the dotted curve is the coverage a calibrated model
    reaches with that S (``expected_coverage``), the diagonal the nominal level; bars are
    +-2 measured Monte Carlo standard errors of the mean; the shaded band (largest S) is +-2
    ``calibrated_coverage_sd`` around the calibrated curve: where a calibrated model's
    angle-mean coverage of ONE truth falls (leave-one-sample-out; crgpr.uq.coverage)."""
    methods = list(dict.fromkeys(table["method"]))
    fig, axes = plt.subplots(1, len(methods), figsize=(4.2 * len(methods), 4.2), squeeze=False)
    for ax, method in zip(axes[0], methods, strict=True):
        d = table[table["method"] == method]
        per_angle = d[d["theta0_deg"].notna()]
        mean = d[d["theta0_deg"].isna()]
        sizes = sorted(per_angle["n_samples"].unique())
        colors = plt.cm.tab10(np.arange(len(sizes)))
        ax.plot([0, 1], [0, 1], "-", color="0.6", lw=1, label="nominal")
        for c, S in zip(colors, sizes, strict=True):
            pa = per_angle[per_angle["n_samples"] == S]
            for _, g in pa.groupby("theta0_deg"):
                ax.plot(g["level"] / 100, g["theta_coverage"], "-", color=c, lw=0.5, alpha=0.35)
            m = mean[mean["n_samples"] == S].sort_values("level")
            ax.errorbar(m["level"] / 100, m["theta_coverage"], yerr=2 * m["mc_se"].fillna(0.0), fmt="o-",
                        color=c, lw=1.6, ms=4, capsize=2, label=f"S = {S}: observed (mean of angles)")
            ax.plot(m["level"] / 100, m["expected_coverage"], ":", color=c, lw=1.4,
                    label=f"S = {S}: calibrated model")
            sd = m["calibrated_coverage_sd"].to_numpy(dtype=float)
            if S == max(sizes) and np.isfinite(sd).all():  # the ensemble's own S only (legibility)
                e = m["expected_coverage"].to_numpy(dtype=float)
                ax.fill_between(m["level"] / 100, e - 2 * sd, e + 2 * sd, color=c, alpha=0.12, lw=0,
                                label=f"S = {S}: calibrated, one truth (+-2 sd)")
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.set_aspect("equal")
        ax.set_xlabel("nominal band level")
        ax.set_ylabel(r"observed $\theta$ coverage")
        ax.set_title(method)
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=6)
    fig.tight_layout()
    _save(fig, out)
