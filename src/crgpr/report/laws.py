"""Figure of the learned constitutive laws (``crgpr learn``'s ``laws.png``): each law against each
input, the posterior mean with its 95 % band (mean +- 1.96 sd, ``learning.law_tables``) beside
the nominal rod's law, the covered range of the input shaded, the bending law's continuation
beyond its reach (``learning.extrapolation``, column ``continued``) dotted over it. Written
atomically (io.atomic_path).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from crgpr.io import atomic_path  # noqa: E402

Z95 = 1.959963984540054
LAW_LABELS = {"obj_m": "m [N m]", "obj_n1": "$n_1$ [N]", "obj_n2": "$n_2$ [N]"}
INPUT_LABELS = {"kappa": r"$\kappa$ [1/m]", "nu1": r"$\nu_1$ [-]", "nu2": r"$\nu_2$ [-]",
                "kappa_jm1": r"$\kappa_{j-1}$ [1/m]", "kappa_jp1": r"$\kappa_{j+1}$ [1/m]", "s": "$s$ [m]"}


def law_figure(table: pd.DataFrame, out: str | Path, title: str = "") -> None:
    """One panel per (law, input) of a law table (columns of ``learning.law_tables.law_table``)."""
    panels = list(table.groupby(["law", "input"], sort=False))
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.4), squeeze=False)
    for ax, ((law, inp), d) in zip(axes[0], panels, strict=True):
        ax.axvspan(float(d["covered_lo"].iloc[0]), float(d["covered_hi"].iloc[0]), color="0.92",
                   label="covered range")
        at_s = d["at_s"] if "at_s" in d else pd.Series(float("nan"), index=d.index)
        labelled = False
        for i, (sv, e) in enumerate(d.groupby(at_s.fillna(-1.0), sort=True)):
            x, m, s = e["x"].to_numpy(), e["mean"].to_numpy(), e["sd"].to_numpy()
            tag = "" if sv < 0 else f" at s = {sv:.3g} m"
            ax.fill_between(x, m - Z95 * s, m + Z95 * s, color=f"C{i}", alpha=0.3, label="95 % band" + tag)
            ax.plot(x, m, color=f"C{i}", label="learned (mean)" + tag)
            if "continued" in e:
                cont = e["continued"].to_numpy(dtype=bool)
                lo, hi = float(d["covered_lo"].iloc[0]), float(d["covered_hi"].iloc[0])
                for part in (cont & (x < lo), cont & (x > hi)):  # each side beyond its reach
                    if part.any():
                        ax.plot(x[part], m[part], ":", color="k", lw=1.2,
                                label=None if labelled else "continued beyond the reach")
                        labelled = True
        ax.plot(x, d["nominal"].to_numpy()[: len(x)], "k--", lw=1, label="nominal rod")
        ax.set_xlabel(INPUT_LABELS.get(inp, inp))
        ax.set_ylabel(LAW_LABELS.get(law, law))
    axes[0][0].legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=9)
    with atomic_path(out, ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=130, bbox_inches="tight")
    plt.close(fig)
