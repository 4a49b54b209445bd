"""Diagnosis: which learned component of ``cr_gpr_objective`` carries its trajectory error.

Mean rollouts (``learning.learned.rollout``, the pipeline's own model and integrator) of the
``cr_gpr_objective`` model in ``results/models/gp`` with one group of learned components replaced
by the rod's analytic law (m = EI (kappa - kappa0); n1 = EA (nu1 - nu1_0), n2 = GA (nu2 - nu2_0);
the momentum maps p / (rho A), p / (rho I) of ``learning.oracle``). Prints RMSE(theta) against
``results/ground_truth/{angle}.parquet`` (nodes 1..N, every record).

    python benchmarks/uq_objective_ablation.py 125 learned oracle_m oracle_mom oracle_n
    python benchmarks/uq_objective_ablation.py --models results/camera/models/main/1mm_gp_objective \
        125 learned oracle_m oracle_mom      # a `crgpr learn` directory (cr_gpr_objective_camera)
"""

from __future__ import annotations

import sys
import time

import numpy as np

from crgpr.commands.learn import load_learned
from crgpr.config import load_config, rod_params, sim_settings
from crgpr.io import read_parquet
from crgpr.learning.learned import LearnedRod, rollout
from crgpr.learning.oracle import oracle_components


class ObjectiveLaw:
    """The analytic local resultant of the objective features (m: [kappa, ...], n: [nu1, nu2, kappa])."""

    def __init__(self, kind: str, P) -> None:
        self.kind, self.P = kind, P

    def __call__(self, X: np.ndarray) -> np.ndarray:
        P = self.P
        if self.kind == "m":
            return P.EI * (X[..., 0] - P.kappa0)
        if self.kind == "n1":
            return P.EA * (X[..., 0] - P.nu1_0)
        return P.GA * (X[..., 1] - P.nu2_0)


def main() -> None:
    cfg = load_config("config.yaml")
    sim = sim_settings(cfg)
    args = sys.argv[1:]
    if args[0] == "--models":
        base, _ = load_learned(args[1])
        P, args = base.params, args[2:]
    else:
        P = rod_params(cfg)
        base = LearnedRod.from_dir("results/models/gp", "objective", P)
    orc = oracle_components(P)
    angle = float(args[0])
    gt = read_parquet(f"results/ground_truth/{int(angle)}.parquet").sort_values(["t", "node"])
    th_gt = gt["theta"].to_numpy().reshape(-1, gt["node"].nunique())
    variants = {"learned": {}, "oracle_m": {"obj_m": ObjectiveLaw("m", P)},
                "oracle_n": {"obj_n1": ObjectiveLaw("n1", P), "obj_n2": ObjectiveLaw("n2", P)},
                "oracle_mom": {m: orc[m] for m in ("dH_dp_x", "dH_dp_y", "dH_dp_theta")}}
    for name in args[1:]:
        comps = dict(base.components)
        comps.update(variants[name])
        t0 = time.perf_counter()
        th = rollout(LearnedRod(comps, "objective", P), angle, sim).q[..., 2]
        rmse = np.sqrt(np.mean((th[:, 1:] - th_gt[:, 1:]) ** 2))
        dt = time.perf_counter() - t0
        print(f"{name} {angle:g} deg: rmse_theta {rmse:.4g} rad ({dt:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
