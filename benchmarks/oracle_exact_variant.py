"""Issue 11: the ``exact_dH_dtheta`` oracle-ablation variant alone, on the current results.

Runs the rule ``oracle_ablation``'s own functions (``exact_subset_mean``, ``exact_gap``,
``run_variant``) for that one variant, so its numbers can be measured without rerunning the
nine other variants. Reads ``config.yaml`` (section ``oracle``), ``results/models/gp`` and
``results/ground_truth``; prints the DTC-vs-exact gap table and the rollout RMSE(theta).

    python benchmarks/oracle_exact_variant.py [--subset N] [--gap-only] [--out DIR]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import pandas as pd
import yaml

from crgpr.commands import oracle_ablation as oa
from crgpr.config import rod_params, sim_settings
from crgpr.gp import load_evaluator
from crgpr.io import read_parquet
from crgpr.physics.simulate import trajectory_from_frame


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--subset", type=int, default=None, help="override oracle.exact_subset")
    ap.add_argument("--gap-only", action="store_true")
    ap.add_argument("--out", default=None, help="folder for the two CSVs")
    a = ap.parse_args()
    cfg = yaml.safe_load(Path(a.config).read_text())
    o = cfg["oracle"]
    P, S = rod_params(cfg), sim_settings(cfg)
    mdir = Path("results/models/gp")
    dtc = load_evaluator(mdir / "dH_dtheta")
    center = dtc.meta.get("theta_center")
    t0 = time.perf_counter()
    n_sub = o["exact_subset"] if a.subset is None else a.subset
    ex, idx = oa.exact_subset_mean(mdir / "dH_dtheta", n_sub, o["exact_seed"], o["exact_tol"])
    print(f"exact weights on {idx.size} points: {time.perf_counter() - t0:.1f} s", flush=True)
    gts = {float(x): read_parquet(f"results/ground_truth/{x}.parquet") for x in cfg["angles"]["test_deg"]}
    tests = {x: trajectory_from_frame(df, P) for x, df in gts.items()}
    gap = oa.exact_gap(tests, P, dtc, ex, center, o["exact_check_every"])
    print(gap.to_string(), flush=True)
    if a.out:
        Path(a.out).mkdir(parents=True, exist_ok=True)
        gap.to_csv(Path(a.out) / f"gap_{idx.size}.csv", index=False)
    if a.gap_only:
        return
    rows = oa.run_variant("exact_dH_dtheta", ("dH_dtheta",), {"dH_dtheta": oa.Flat(ex)}, P, S, center,
                          o["theta_closure"], gts, f"exact mean (KernelMean.exact) on {idx.size} points")
    df = pd.DataFrame(rows)
    print(df[["variant", "theta0_deg", "rmse_theta", "r2_theta", "status", "seconds_batch"]].to_string())
    print(f"mean rmse_theta {df['rmse_theta'].mean():.4f}")
    if a.out:
        df.to_csv(Path(a.out) / f"exact_{idx.size}.csv", index=False)


if __name__ == "__main__":
    main()
