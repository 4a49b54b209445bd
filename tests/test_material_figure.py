"""The materials study's figure (``report.materials.material_figure``): a learned bending law
along s is drawn as one curve per tabulated arclength, each over its own curvature grid."""

from __future__ import annotations

import numpy as np
import pandas as pd
from paper_rod import PAPER_ROD

import crgpr.report.materials as rm


def _law_along_s(at_s: list[float], n: int = 21) -> pd.DataFrame:
    """A laws.parquet-like table of m = EI(s) kappa at each arclength of ``at_s``."""
    x = np.linspace(-10.0, 10.0, n)
    return pd.concat([pd.DataFrame({"law": "obj_m", "input": "kappa", "x": x, "sd": 1e-4, "at_s": s,
                                    "mean": PAPER_ROD.EI * (1 + s) * x}) for s in at_s], ignore_index=True)


def _tips() -> pd.DataFrame:
    t = np.linspace(0.0, 1.0, 5)
    return pd.concat([pd.DataFrame({"model": m, "theta0_deg": 60.0, "t": t, "tip_x": 0.1 * t, "tip_y": 0.0})
                      for m in ("learned", "nominal", "truth")], ignore_index=True)


def test_a_law_along_s_is_one_curve_per_arclength_never_joined(tmp_path, monkeypatch):
    figs = []
    monkeypatch.setattr(rm.plt, "close", figs.append)
    rows = pd.DataFrame({"input": ["full_state"], "law_rmse": [0.0], "law_band_coverage": [1.0],
                         "rmse_theta": [0.0], "nominal_rmse_theta": [0.1]})
    kappa = np.linspace(-10.0, 10.0, 50)[:, None].repeat(PAPER_ROD.N, 1)
    rm.material_figure("graded", {"full_state": _law_along_s([0.01, 0.25, 0.49])}, {"full_state": _tips()},
                       PAPER_ROD, PAPER_ROD, kappa, rows, tmp_path / "f.png")
    ax = figs[0].axes[0]
    learned = [ln for ln in ax.get_lines() if ln.get_color() == rm.COLORS["full_state"]]
    assert len(learned) == 3
    for ln in learned:  # each over its own grid, left to right: no segment back to the start of the next
        assert np.all(np.diff(ln.get_xdata()) > 0)
    assert (tmp_path / "f.png").is_file()
