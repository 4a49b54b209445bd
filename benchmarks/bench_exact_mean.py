"""Speed and accuracy of the exact-mean rollout (``rollout_mean: exact``).

    python benchmarks/bench_exact_mean.py [--models results/models/gp] [--features paper]
        [--angle 125] [--every 20] [--out CSV]

1. Loads the saved models as the pipeline does (``gp.load_evaluator``: the exact posterior
   mean over all n training points, kernel sums truncated below ``exact_tol`` sigma_f^2 on a
   cell grid; tabulated 1-D momentum means) and times the build.
2. Times one rollout over ``simulation.t_end_s`` (2 s in config.yaml) with the ground truth's
   integrator and dt, one thread (as the rules run), and its RMSE(theta) against
   ``results/ground_truth/{angle}.parquet`` when that file exists.
3. At the states that rollout visited (every ``--every``-th record, t > 0), compares each
   multi-dimensional component with its DENSE (untruncated) exact mean: RMS / target std,
   next to the a-priori truncation bound.
Timings on the shared 2-core machine are upper bounds.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from crgpr.config import load_config, rod_params, sim_settings  # noqa: E402
from crgpr.io import read_parquet  # noqa: E402
from crgpr.learning.gradient_models import model_features  # noqa: E402
from crgpr.learning.learned import LearnedRod, rollout  # noqa: E402
from crgpr.physics.params import SimSettings  # noqa: E402
from crgpr.physics.simulate import trajectory_from_frame  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default="results/models/gp")
    ap.add_argument("--features", default="paper", choices=("paper", "objective"))
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--angle", type=float, default=125.0)
    ap.add_argument("--every", type=int, default=20)
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)
    cfg = load_config(a.config)
    P, S = rod_params(cfg), sim_settings(cfg)
    t0 = time.perf_counter()
    model = LearnedRod.from_dir(a.models, a.features, P)
    t_build = time.perf_counter() - t0
    warm = SimSettings(dt=S.dt, t_end=20 * S.dt, record_every=S.record_every, scheme=S.scheme)
    rollout(model, a.angle, warm)  # compile the numba kernels outside the timing
    t0 = time.perf_counter()
    tr = rollout(model, a.angle, S)
    t_roll = time.perf_counter() - t0
    gt_path = Path("results/ground_truth") / f"{a.angle:g}.parquet"
    rmse = float("nan")
    if gt_path.exists():
        gt = trajectory_from_frame(read_parquet(gt_path), P)
        rmse = float(np.sqrt(np.mean((tr.q[:, 1:, 2] - gt.q[:, 1:, 2]) ** 2)))
    q, p = tr.q[1::a.every], tr.p[1::a.every]
    rows = []
    for name, ev in model.components.items():
        if getattr(ev, "kind", "") != "exact":
            continue
        X = model_features(q[..., 0], q[..., 1], q[..., 2], p, P.ds, name, model.center)
        X = X.reshape(-1, X.shape[-1])
        got, dense = ev(X), ev.dense()(X)
        std = float(ev.meta["target_std"])
        rows.append({"model": name, "angle": a.angle, "points": len(X), "target_std": std,
                     "trunc_rmse_over_target_std_visited": float(np.sqrt(np.mean((got - dense) ** 2)) / std),
                     "truncation_bound_over_target_std": ev.truncation_bound / std,
                     "n_centres": ev.Z.shape[0]})
    df = pd.DataFrame(rows).assign(seconds_build=t_build, seconds_rollout=t_roll, t_end_s=S.t_end,
                                   rmse_theta=rmse)
    print(df.to_string(index=False))
    print(f"exact-mean rollout {a.angle:g} deg, {S.t_end:g} s simulated: {t_roll:.1f} s wall "
          f"(build {t_build:.1f} s); RMSE(theta) {rmse:.4f} rad; load average {os.getloadavg()[0]:.1f}")
    if a.out:
        df.to_csv(a.out, index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
