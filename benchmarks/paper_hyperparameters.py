"""Issue 11, part 3: log marginal likelihood of our fitted hyperparameters and of the paper's
Table II values on the same data (two readings of the paper's units), and the
paper-hyperparameter models (``cr_gpr_paper_hyp``).

    python benchmarks/paper_hyperparameters.py [--models results/models/gp] [--n-lml 2000]
        [--out results/tables/paper_hyp_lml.csv] [--save results/models/paper_hyp]

Mapping of Table II onto our scaling: the paper's sigma_f, ell, sigma_n are read in ORIGINAL
units (MATLAB fitrgp's default, Standardize = false), i.e. ell_std = ell / x_scale,
sigma_f_std = sigma_f / y_scale, sigma_n_std = sigma_n / y_scale, with our per-feature
standardisation (x_scale = std of the feature, y_scale = std of the target). The LML is the
vague-prior (restricted) one of gp._gpr (R&W eq. 2.45) on the same seeded random subset of
``n_lml`` training points for both.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.gp import GP, basis_matrix_std, fit_gp
from crgpr.gp._gpr import _neg_lml
from crgpr.learning.gradient_models import PAPER_MODELS, paper_hyperparameters


def paper_std_hyper(gp: GP, name: str, inputs_standardised: bool = False) -> dict[str, object]:
    ys = float(np.ravel(gp.y_scale)[0])
    return paper_hyperparameters(name, gp.x_scale, ys, gp.ard, inputs_standardised)


def lml(gp: GP, hyp: dict[str, object], idx: np.ndarray) -> float:
    U = gp.standardise_x(gp.X[idx])
    V = ((np.ravel(gp.Y)[idx] - gp.y_mean[0]) / gp.y_scale[0])[:, None]
    ell = np.ravel(hyp["lengthscales"])
    th = np.r_[math.log(hyp["sigma_f"]), np.log(ell), math.log(hyp["sigma_n"])]
    return -float(_neg_lml(th, gp.kernel, gp.ard, U, V, basis_matrix_std(gp.basis, U))[0])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--models", default="results/models/gp")
    ap.add_argument("--n-lml", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--out", default="results/tables/paper_hyp_lml.csv")
    ap.add_argument("--save", default=None, help="write the paper-hyperparameter models here")
    a = ap.parse_args(argv)
    rows = []
    for name in PAPER_MODELS:
        gp = GP.load(Path(a.models) / name)
        rng = np.random.default_rng(a.seed)
        idx = np.sort(rng.choice(gp.n, size=min(a.n_lml, gp.n), replace=False))
        ours = {"sigma_f": gp.sigma_f, "lengthscales": np.ravel(gp.lengthscales), "sigma_n": gp.sigma_n}
        paper = paper_std_hyper(gp, name)
        rows.append({"model": name, "n_lml": idx.size, "lml_ours": lml(gp, ours, idx),
                     "lml_paper_table2": lml(gp, paper, idx),
                     "lml_paper_table2_ell_standardised": lml(gp, paper_std_hyper(gp, name, True), idx),
                     "paper_sigma_f_std": paper["sigma_f"],
                     "paper_lengthscales_std": " ".join(f"{v:.4g}" for v in np.ravel(paper["lengthscales"])),
                     "paper_sigma_n_std": paper["sigma_n"], "ours_sigma_f_std": gp.sigma_f,
                     "ours_lengthscales_std": " ".join(f"{v:.4g}" for v in np.ravel(gp.lengthscales)),
                     "ours_sigma_n_std": gp.sigma_n})
        if a.save:
            meta = json.loads((Path(a.models) / f"{name}.json").read_text())
            pg = fit_gp(gp.X, np.ravel(gp.Y), kernel=gp.kernel, basis=gp.basis, ard=gp.ard, fixed=paper,
                        factorise=False)
            Path(a.save).mkdir(parents=True, exist_ok=True)
            pg.save(Path(a.save) / name, extra={"name": name, "features": meta["features"],
                                                 "theta_center": meta.get("theta_center"),
                                                 "hyperparameters": "paper Table II, original units"})
        print(rows[-1], flush=True)
    pd.DataFrame(rows).to_csv(a.out, index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
