"""Figure of one materials-study case (``results/figures/material_<case>.png``, docs/materials.md):
left, the learned bending laws m(kappa) (posterior mean and 95 % band, mean +- 1.96 sd, of each
input's model, ``laws.parquet``; a law along s at each of its tabulated arclengths) beside the
nominal law EI (kappa - kappa0) and the true law of the segments at s = 0, L0 / 2 and L0
(``rod.segment_moment_law``) over the curvatures the training record reached; right, the tip's
distance from the clamp's vertical, x_tip(t), at the first test angle: the true rod, the
nominal rod and the learned rods. Written atomically.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from crgpr.io import atomic_path  # noqa: E402
from crgpr.physics.params import RodParams  # noqa: E402
from crgpr.physics.rod import segment_moment_law  # noqa: E402

Z95 = 1.959963984540054
COLORS = {"full_state": "C0", "camera": "C1"}


def material_figure(case: str, laws: dict[str, pd.DataFrame | None], tips: dict[str, pd.DataFrame],
                    truth: RodParams, nominal: RodParams, kappa: np.ndarray, rows: pd.DataFrame,
                    out: str | Path) -> None:
    """The case's figure (module docstring). ``laws``: input -> law table (or None); ``tips``:
    input -> tip paths (``commands.materials.TIP_COLUMNS``); ``kappa`` (n_t, N): the true rod's
    training curvatures; ``rows``: the case's table rows (for the titles)."""
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 3.8), constrained_layout=True)
    lo, hi = float(kappa.min()), float(kappa.max())
    x = np.linspace(lo, hi, 201)
    true = segment_moment_law(truth, x)
    for j, ls in ((0, "-"), (truth.N // 2, "-."), (truth.N - 1, ":")):
        ax.plot(x, true[:, j], color="C3", ls=ls, lw=2.0,
                label=f"true, s = {(j + 0.5) * truth.ds:.2f} m")
    for inp, tab in laws.items():
        if tab is None:
            continue
        d = tab[(tab["law"] == "obj_m") & (tab["input"] == "kappa")]
        # one curve per arclength a law along s is shown at (NaN: a law without s)
        for i, (_, e) in enumerate(d.groupby(d["at_s"].fillna(-1.0), sort=True)):
            xx, m, s = e["x"].to_numpy(), e["mean"].to_numpy(), e["sd"].to_numpy()
            ax.fill_between(xx, m - Z95 * s, m + Z95 * s, color=COLORS[inp], alpha=0.25)
            ax.plot(xx, m, color=COLORS[inp], lw=1, label=f"learned, {inp} (95 % band)" if i == 0 else None)
    ax.plot(x, nominal.EI * (x - nominal.kappa0), "k--", lw=1, label="nominal")
    span = np.ptp(true)
    ax.set_xlim(lo, hi)
    ax.set_ylim(true.min() - 0.3 * span, true.max() + 0.3 * span)
    ax.set_xlabel(r"$\kappa$ [1/m]")
    ax.set_ylabel("m [N m]")
    agg = rows.groupby("input")[["law_rmse", "law_band_coverage"]].first()
    ax.set_title(f"{case}: bending law\nlaw RMSE / spread: " + ", ".join(
        f"{i} {agg.loc[i, 'law_rmse']:.3g}" for i in agg.index), fontsize=8)
    ax.legend(fontsize=6)
    first = None
    for inp, tp in tips.items():
        first = float(tp["theta0_deg"].iloc[0]) if first is None else first
        d = tp[np.isclose(tp["theta0_deg"], first)]
        if inp == next(iter(tips)):
            for model, style in (("truth", {"color": "C3", "lw": 2}),
                                 ("nominal", {"color": "k", "ls": "--", "lw": 1})):
                e = d[d["model"] == model]
                bx.plot(e["t"], e["tip_x"], label="true rod" if model == "truth" else "nominal rod", **style)
        e = d[d["model"] == "learned"]
        bx.plot(e["t"], e["tip_x"], color=COLORS[inp], lw=1, label=f"learned, {inp}")
    means = rows.groupby("input")[["rmse_theta", "nominal_rmse_theta"]].mean()
    bx.set_title(f"rollout at {first:g} deg\nmean RMSE(theta) over the test angles: " + ", ".join(
        f"{i} {means.loc[i, 'rmse_theta']:.3g}" for i in means.index)
        + f", nominal {means['nominal_rmse_theta'].iloc[0]:.3g} rad", fontsize=8)
    bx.set_xlabel("t [s]")
    bx.set_ylabel("tip x [m]")
    bx.legend(fontsize=7)
    with atomic_path(out, ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=130, bbox_inches="tight")
    plt.close(fig)
