"""Issue 13 experiment: obj_m's basis coefficients sampled from their delete-a-block jackknife
(cluster-robust) covariance instead of c^2 x the iid-noise posterior's (uq4 notes).

obj_m is in effect a Bayesian linear law (the LML switched its kernel off: sigma_f at its lower
bound), so its band is the spread of its 6 basis coefficients. A scalar scale c can match the
size of that spread but not its shape; here the coefficient deviations of every stored sample are
replaced by draws from N(0, C_jk), C_jk = (B - 1) / B sum_b (beta_-b - mean_b beta_-b)
(beta_-b - ...)^T over the ``uq.heldout_blocks`` leave-one-block-out DTC posteriors (the same
blocks as ``heldout_block_scale``); the kernel part of each sample is kept. Writes a samples
directory with that obj_m and links of the other sample files; rolling it out and scoring is
the ``uq_rollout`` / ``uq_coverage`` functions (e.g. /tmp/uq4/chain.py with the steps
``rollout coverage``).

    python benchmarks/uq_basis_jackknife.py MODEL_STEM SAMPLES_DIR OUT_SAMPLES_DIR [SEED]
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np

from crgpr.config import load_config
from crgpr.gp.sampling import CompressedSamples, sparse_posterior, subset_spec
from crgpr.io import load_npz, write_npz
from crgpr.uq.samples import load_gp_spec


def main() -> None:
    stem, src, dst = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3])
    seed = int(sys.argv[4]) if len(sys.argv) > 4 else 0
    B = int(load_config("config.yaml")["uq"]["heldout_blocks"])
    name = Path(stem).name
    spec, Z, _ = load_gp_spec(stem, name)
    n = spec.Xs.shape[0]
    edges = np.linspace(0, n, B + 1).astype(int)
    betas = []
    for b in range(B):
        tr = np.concatenate([np.arange(0, edges[b]), np.arange(edges[b + 1], n)])
        betas.append(sparse_posterior(subset_spec(spec, tr), Z).mean_coefficients()[0])
    bs = np.asarray(betas)
    C = (B - 1) / B * (bs - bs.mean(0)).T @ (bs - bs.mean(0))
    arr = load_npz(src / f"{name}.npz")
    comp = CompressedSamples.from_arrays(arr)
    centre = np.ravel(spec.rollout_arrays["dtc_beta"])
    old_sd = (comp.beta - centre).std(0)
    w, V = np.linalg.eigh(C)
    xi = np.random.default_rng(seed).standard_normal(comp.beta.shape)
    arr["beta"] = centre + (xi * np.sqrt(np.maximum(w, 0.0))) @ V.T
    dst.mkdir(parents=True, exist_ok=True)
    for f in src.glob("*"):
        if f.name not in (f"{name}.npz",):
            shutil.copy(f, dst / f.name)
    write_npz(dst / f"{name}.npz", **arr)
    print(name, "jackknife sd of beta (standardised):", np.sqrt(np.diag(C)))
    print(name, "sd of the stored samples' beta:     ", old_sd)
    print(name, "sd of the new samples' beta:        ", arr["beta"].std(0))


if __name__ == "__main__":
    main()
