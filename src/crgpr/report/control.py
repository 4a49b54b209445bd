"""Figure of the control study (docs/control.md): the tracked tip path against its target, and
the rod's shape at a few instants of a regulation run."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from crgpr.io import atomic_path  # noqa: E402


def control_figure(runs: dict[tuple[str, str, str, str], Any], out: str | Path) -> None:
    """Left: tracking on the ground-truth plant, tip path of every controller and the target.
    Right: regulation from rest on the ground-truth plant by the learned-model controller, rod
    shapes at the kept instants, and the target."""
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4.5))
    first = True
    for (task, plant, name, _), run in runs.items():
        if task != "tracking" or plant != "ground_truth":
            continue
        if first:
            ax1.plot(run.target[:, 0], run.target[:, 1], "k--", lw=1.5, label="target")
            first = False
        ax1.plot(run.pose[:, 0], run.pose[:, 1], lw=1, label=name)
    ax1.set(xlabel="x [m]", ylabel="y [m]", title="tracking, ground-truth plant", aspect="equal")
    ax1.legend(fontsize=8)
    run = runs[("regulation", "ground_truth", "learned", "rest")]
    for k, (t, q) in enumerate(zip(run.t_shapes, run.shapes, strict=True)):
        ax2.plot(q[:, 0], q[:, 1], color=plt.cm.viridis(k / max(1, len(run.shapes) - 1)), lw=1.2,
                 label=f"t = {t:.2g} s")
    ax2.plot(run.pose[:, 0], run.pose[:, 1], "k:", lw=0.8, label="tip path")
    ax2.plot(*run.target[0, :2], "r+", ms=12, mew=2, label="target")
    ax2.set(xlabel="x [m]", ylabel="y [m]", title="regulation from rest (learned-model controller)",
            aspect="equal")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    with atomic_path(out, ".png") as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
