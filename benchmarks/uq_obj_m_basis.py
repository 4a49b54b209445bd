"""Diagnosis: function-level calibration of obj_m under other bases / noise floors.

Refits obj_m (``gradient_models.fit_model``, the pipeline's fit and DTC rollout approximation) on
the 85 deg prefilter data with ``basis[:sigma_n_min]`` from the command line, and scores it at
ground-truth states of the six test angles (every 20th record): RMSE of the rollout mean against
the analytic m, median |z| and 95 % coverage with the sparse posterior's sd, overall and for the
states whose curvature lies above the training range (extrapolation).

    python benchmarks/uq_obj_m_basis.py constant linear linear:0
"""

from __future__ import annotations

import sys
import time

import numpy as np

from crgpr.config import load_config, rod_params
from crgpr.gp import KernelMean
from crgpr.gp.sampling import heldout_block_scale, sparse_posterior, spec_from_gp
from crgpr.io import read_parquet
from crgpr.learning.gradient_models import ALL_MODELS, fit_model, model_spec, training_data
from crgpr.learning.prefilter import prefiltered_arrays, read_prefiltered
from crgpr.seeds import stage_seed
from crgpr.uq.calibration import model_features, true_targets


def _truth(angle: int) -> tuple[np.ndarray, np.ndarray]:
    gt = read_parquet(f"results/ground_truth/{angle}.parquet").sort_values(["t", "node"])
    nt, nn = gt["t"].nunique(), gt["node"].nunique()
    q = np.stack([gt[c].to_numpy().reshape(nt, nn) for c in ("x", "y", "theta")], -1)
    p = np.stack([gt[c].to_numpy().reshape(nt, nn) for c in ("p_x", "p_y", "p_theta")], -1)
    k = np.arange(1, nt, 20)
    return q[k], p[k]


def main() -> None:
    cfg = load_config("config.yaml")
    P = rod_params(cfg)
    arr = prefiltered_arrays(read_prefiltered("results/prefilter/gp/85.parquet"))
    X, y = training_data(arr, P, "obj_m", None)
    gm = dict(cfg["gradient_models"], exact_check_max_n=1500)
    tests = {a: _truth(a) for a in cfg["uq"]["angles_deg"]}
    for arg in sys.argv[1:]:
        spec = model_spec(cfg, "obj_m")
        spec["basis"] = arg.split(":")[0]
        if ":" in arg:
            spec["sigma_n_min"] = float(arg.split(":")[1])
        t0 = time.perf_counter()
        gp, arrays, _ = fit_model("obj_m", X, y, spec, gm,
                                  stage_seed(cfg["seed"], "gradient_model", ALL_MODELS.index("obj_m")))
        print(arg, f"fit {time.perf_counter() - t0:.0f} s, lengthscales (std)",
              np.round(np.ravel(gp.lengthscales), 3), "sigma_f", gp.sigma_f, "sigma_n", gp.sigma_n,
              flush=True)
        gspec = spec_from_gp(gp, "obj_m")
        post = sparse_posterior(gspec, arrays["dtc_Z"])
        c, cinfo = heldout_block_scale(gspec, int(cfg["uq"]["heldout_blocks"]), arrays["dtc_Z"])
        print(f"  held-out-block scale c = {c:.3g}",
              {k: v for k, v in cinfo.items() if k != "posterior_scale"}, flush=True)
        mean_fn = KernelMean.dtc(gp, arrays["dtc_Z"], arrays["dtc_w"], arrays["dtc_beta"])
        for a, (q, p) in tests.items():
            F = model_features(q, p, P, None)["obj_m"].reshape(-1, 5)
            err = true_targets(q, p, P)["obj_m"].reshape(-1) - mean_fn(F)
            z = err / np.sqrt(post.mean_var(F)[1]) / c
            out = F[:, 0] > X[:, 0].max()
            o = (f"out {np.sqrt(np.mean(err[out] ** 2)):.2e} med|z| {np.median(np.abs(z[out])):.2f} "
                 f"cov95 {np.mean(np.abs(z[out]) < 1.96):.3f}") if out.any() else "out: none"
            print(f"  {a} deg: rmse {np.sqrt(np.mean(err ** 2)):.2e} med|z| {np.median(np.abs(z)):.2f} "
                  f"cov95 {np.mean(np.abs(z) < 1.96):.3f}; "
                  f"kappa above training range ({out.mean():.3f}): {o}",
                  flush=True)


if __name__ == "__main__":
    main()
