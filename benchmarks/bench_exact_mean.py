"""Issue 11, part 3: the GP the rollout integrates vs the fitted GP's exact posterior mean.

    python benchmarks/bench_exact_mean.py [--models results/models/gp] [--angle 125] [--out CSV]

1. Rolls the ``cr_gpr`` model out as the pipeline does (``gp.load_evaluator``: DTC means on 600
   inducing inputs, tabulated 1-D means) and records the states it visits.
2. At those visited states, compares each component's Approx value with the exact posterior
   mean over all n training points (``gp.exact.ExactMean``): RMS error / target std.
3. Times one 2 s rollout with the exact means (``ExactMean`` components) and reports its
   RMSE(theta) against the simulator.
Timings on the shared 2-core machine are upper bounds.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.config import load_config, rod_params, sim_settings
from crgpr.gp import load_evaluator
from crgpr.gp.exact import ExactMean
from crgpr.learning import features as ft
from crgpr.learning.learned import LearnedRod, rollout
from crgpr.physics.simulate import simulate

NAMES = ("q_x", "q_y", "dH_dtheta", "dH_dp_x", "dH_dp_y", "dH_dp_theta")


def visited_features(traj, P, center):
    q, p = traj.q[1:], traj.p[1:]
    x, y, th = q[..., 0], q[..., 1], q[..., 2]
    Xq = ft.paper_q_features(x, y, th, P.ds, center).reshape(-1, 3)
    out = {"q_x": Xq, "q_y": Xq,
           "dH_dtheta": ft.paper_theta_features(x, y, th, P.ds, center).reshape(-1, 6)}
    for k, n in enumerate(NAMES[3:]):
        out[n] = p[:, 1:, k].reshape(-1)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--models", default="results/models/gp")
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--angle", type=float, default=125.0)
    ap.add_argument("--out", default=None)
    ap.add_argument("--only", default=",".join(NAMES),
                    help="models to compare (comma list); the exact rollout runs only when all six are given")
    a = ap.parse_args(argv)
    cfg = load_config(a.config)
    P, S = rod_params(cfg), sim_settings(cfg)
    mdir = Path(a.models)
    gt = simulate(a.angle, P, S)
    approx = LearnedRod.from_dir(mdir, "paper", P)
    t0 = time.perf_counter()
    tr_a = rollout(approx, a.angle, S)
    t_approx = time.perf_counter() - t0
    t0 = time.perf_counter()
    only = [n for n in a.only.split(",") if n]
    exact = {n: ExactMean(mdir / n) for n in only}
    t_build = time.perf_counter() - t0
    rows = []
    feats = visited_features(tr_a, P, approx.center)
    sub = slice(None, None, 10)
    for n in only:
        X = feats[n][sub]
        ea, ee = approx.components[n](X), exact[n](X)
        std = float(load_evaluator(mdir / n).meta["target_std"])
        rows.append({"model": n, "angle": a.angle, "points": len(X),
                     "approx_rmse_over_target_std_visited": float(np.sqrt(np.mean((ea - ee) ** 2)) / std),
                     "target_std": std, "truncation_bound": exact[n].truncation_bound})
    rm = lambda tr: float(np.sqrt(np.mean((tr.q[:, 1:, 2] - gt.q[:, 1:, 2]) ** 2)))  # noqa: E731
    df = pd.DataFrame(rows).assign(rmse_theta_approx=rm(tr_a), seconds_approx_rollout=t_approx,
                                   seconds_exact_build=t_build)
    msg = (f"rollout {a.angle:g} deg: Approx {t_approx:.1f} s, RMSE(theta) {rm(tr_a):.4f}; "
           f"build {t_build:.1f} s")
    if set(only) == set(NAMES):
        model = LearnedRod(exact, "paper", P, approx.center)
        t0 = time.perf_counter()
        tr_e = rollout(model, a.angle, S)
        t_exact = time.perf_counter() - t0
        df = df.assign(rmse_theta_exact=rm(tr_e), seconds_exact_rollout=t_exact)
        msg += f"; ExactMean rollout {t_exact:.1f} s, RMSE(theta) {rm(tr_e):.4f}"
    print(df.to_string(index=False))
    print(msg)
    if a.out:
        df.to_csv(a.out, index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
