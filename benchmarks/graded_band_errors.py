"""Benchmark: why the graded rod's full-state law band misses the true law (docs/materials.md).

    python benchmarks/graded_band_errors.py --results results

Reads the materials study's graded rod (``results/materials/graded/``: ``train.parquet`` and the
full-state model ``models/full_state/obj_m``, written by ``snakemake -j2 all``) and refits the
model's bending GP, with its own hyperparameters and training inputs, to other targets:

* ``as learned``: the model's own moment targets (the study's row);
* ``true law``: the true law at the same inputs (no target error);
* ``shuffled``: the true law plus the model's target errors (target minus true law) permuted
  among the samples (each sample and its mirror image keep opposite errors);
* ``shuffled within segment and |kappa| tercile``: the same, permuted only among samples of the
  same segment and the same third of |kappa|.

Each fit's posterior mean is scored against the true law with the model's own latent sd over
the covered grid (``law_band_coverage`` of ``report.metrics.law_accuracy``, no jackknife
widening); ``--seeds`` permutations each. Rows go to ``--csv``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.config import load_config, material_case_rod
from crgpr.gp import GP
from crgpr.io import read_parquet
from crgpr.physics.rod import segment_moment_law, strains
from crgpr.physics.simulate import trajectory_from_frame
from crgpr.report.metrics import law_accuracy


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--results", default="results")
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--csv", default="benchmarks/graded_band_errors.csv")
    args = ap.parse_args()
    cfg = load_config(args.config)
    truth = material_case_rod(cfg, "graded")
    d = Path(args.results) / "materials" / "graded"
    gp = GP.load(d / "models" / "full_state" / "obj_m")
    X, Y = gp.X, np.ravel(gp.Y)
    h = X.shape[0] // 2  # the samples, then their reflections (odd law)
    seg = np.round(X[:, 1] / truth.ds - 0.5).astype(int)
    m_true = segment_moment_law(truth, X[:, 0])[np.arange(X.shape[0]), seg]
    err = (Y - m_true)[:h]
    train = trajectory_from_frame(read_parquet(d / "train.parquet").assign(theta0_deg=math.nan), truth)
    kappa = strains(train.q, truth)["kappa"]
    n_grid = int(cfg["camera"]["learn"]["law_table"]["n_grid"])
    x = np.linspace(float(kappa.min()), float(kappa.max()), n_grid)
    where = (x[:, None] >= kappa.min(axis=0)[None]) & (x[:, None] <= kappa.max(axis=0)[None])
    s_mid = (np.arange(truth.N) + 0.5) * truth.ds
    grid = np.stack([np.repeat(x, truth.N), np.tile(s_mid, x.size)], axis=1)
    true_grid = segment_moment_law(truth, x)

    def fit(targets: np.ndarray) -> GP:
        return GP(kernel=gp.kernel, ard=gp.ard, basis=gp.basis, sigma_f=gp.sigma_f,
                  lengthscales=gp.lengthscales, sigma_n=gp.sigma_n, x_mean=gp.x_mean, x_scale=gp.x_scale,
                  y_mean=gp.y_mean, y_scale=gp.y_scale, X=X, Y=targets[:, None])
    _, var = gp.predict(grid, return_var=True)
    sd = np.sqrt(np.asarray(var, dtype=float)).reshape(x.size, truth.N)

    def score(targets: np.ndarray) -> dict[str, float]:
        mean = np.asarray(fit(targets).predict(grid), dtype=float).reshape(x.size, truth.N)
        return law_accuracy(mean, sd, true_grid, where)

    def with_errors(e: np.ndarray) -> np.ndarray:
        return m_true + np.concatenate([e, -e])

    rows = [{"targets": "as learned", "seed": None, **score(Y)},
            {"targets": "true law", "seed": None, **score(m_true)}]
    ak = np.abs(X[:h, 0])
    cell = seg[:h] * 3 + np.digitize(ak, np.quantile(ak, [1 / 3, 2 / 3]))
    for seed in range(args.seeds):
        rng = np.random.default_rng(seed)
        rows.append({"targets": "shuffled", "seed": seed, **score(with_errors(rng.permutation(err)))})
        p = np.arange(h)
        for c in np.unique(cell):
            idx = np.flatnonzero(cell == c)
            p[idx] = rng.permutation(idx)
        rows.append({"targets": "shuffled within segment and |kappa| tercile", "seed": seed,
                     **score(with_errors(err[p]))})
    out = pd.DataFrame(rows)
    print(out.to_string(index=False))
    out.to_csv(args.csv, index=False, float_format="%.6g")


if __name__ == "__main__":
    main()
