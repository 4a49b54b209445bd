"""Diagnosis: each posterior-scale statistic of ``heldout_block_scale`` against the
truth at the test states (function level; nothing here is fitted to the truth).

For the saved gradient models of a method (``results/models/gp/{model}``): the scales c of
the statistics rms, median and jackknife from the training rows only, then at
ground-truth states of the test angles (``n_times`` times each) the error of the rollout's
mean against the analytic rod's value (``crgpr.uq.calibration.true_targets``), z = error /
(c x posterior sd), and per statistic the median |z| (calibrated: 0.674) and 95 % coverage.

    python benchmarks/uq_scale_function_level.py --results results obj_m obj_n1
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from crgpr.config import load_config, rod_params
from crgpr.gp.sampling import exact_posterior, heldout_block_scale, se_kernel, sparse_posterior
from crgpr.io import read_parquet
from crgpr.physics.simulate import trajectory_from_frame
from crgpr.uq.calibration import model_features, true_targets
from crgpr.uq.samples import load_gp_spec


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--results", default="results")
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--n-times", type=int, default=100)
    ap.add_argument("models", nargs="+")
    a = ap.parse_args()
    cfg = load_config(a.config)
    P = rod_params(cfg)
    B = int(cfg["uq"]["heldout_blocks"])
    tests = {}
    for ang in cfg["uq"]["angles_deg"]:
        tr = trajectory_from_frame(read_parquet(f"{a.results}/ground_truth/{ang}.parquet"), P)
        k = np.unique(np.linspace(1, len(tr.q) - 1, a.n_times).round().astype(int))
        tests[ang] = (tr.q[k], tr.p[k])
    for name in a.models:
        spec, Z, _ = load_gp_spec(f"{a.results}/models/gp/{name}", name)
        t0 = time.perf_counter()
        full = sparse_posterior(spec, Z) if (Z is not None and spec.dim > 1) else exact_posterior(spec)
        _, info = heldout_block_scale(spec, B, Z if spec.dim > 1 else None, "median",
                                      int(cfg["uq"]["check_points"]), full)
        scales = {s: info[f"heldout_scale_{s}"] for s in ("rms", "median", "jackknife")}
        scales["none"] = 1.0
        print(f"{name}: {time.perf_counter() - t0:.0f} s; scales",
              {k: f"{v:.3g}" for k, v in scales.items()},
              {k: info[k] for k in ("jackknife_scale_mean", "jackknife_sd_median", "latent_sd_median",
                                    "heldout_rms_residual")}, flush=True)
        ra = getattr(spec, "rollout_arrays", {})
        zs: dict[str, list[np.ndarray]] = {s: [] for s in scales}
        for ang, (q, p) in tests.items():
            F = model_features(q, p, P, None)[name]
            F = F.reshape(-1, F.shape[-1])
            mean, var = full.mean_var(F)
            if "dtc_w" in ra:
                xs = spec.standardise(F)
                k = se_kernel(xs, ra["dtc_Z"], spec.sigma_f, spec.ell)
                mean = spec.to_output(k @ np.ravel(ra["dtc_w"])
                                      + spec.basis_fn(xs) @ np.ravel(ra["dtc_beta"]))
            err = true_targets(q, p, P)[name].reshape(-1) - mean
            sd = np.sqrt(np.maximum(var, 1e-300))
            line = [f"{ang:>3} deg rmse {np.sqrt(np.mean(err**2)):.2e} sd_med {np.median(sd):.2e}"]
            for s, c in scales.items():
                z = err / (c * sd)
                zs[s].append(z)
                line.append(f"{s} {np.median(np.abs(z)):.2f}/{np.mean(np.abs(z) < 1.96):.2f}")
            print("   ", " | ".join(line), flush=True)
        za = {s: np.abs(np.concatenate(z)) for s, z in zs.items()}
        print("    all angles (median |z| / cov95; calibrated 0.67 / 0.95):",
              " | ".join(f"{s} {np.median(z):.2f}/{np.mean(z < 1.96):.2f}" for s, z in za.items()),
              flush=True)


if __name__ == "__main__":
    main()
