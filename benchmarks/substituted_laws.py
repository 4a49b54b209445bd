"""Benchmark: which learned law misleads a rollout, by substituting nominal laws (docs/learned-laws.md).

    python benchmarks/substituted_laws.py --models benchmarks/learned_laws/before_runs/saturating_full \
        --name saturating --truth-set rod.material.bending_law=saturating \
        --truth-set rod.material.saturation_moment=0.08 --nominal n1,n2 --nominal n1,n2,p_x,p_y,p_theta

Loads a ``crgpr learn`` model directory (e.g. the ``before`` model of ``benchmarks/learned_laws.py``),
replaces the named laws by the nominal rod's (``learning.nominal.NominalLaw``: n1, n2, m, and the
momentum maps p_x, p_y, p_theta = p / (rho A), p / (rho I)), rolls the rod out at ``--angles``
and scores it against the true rod (the config's ``rod`` with the ``--truth-set`` overlays; RMSE
of theta, ``report.metrics.accuracy``). One row per (substitution, angle) is appended to ``--csv``.
"""

from __future__ import annotations

import argparse
import copy
from pathlib import Path

import pandas as pd
import yaml

from crgpr.commands.learn import load_learned
from crgpr.commands.rollout import rollout_settings
from crgpr.config import load_config, rod_params
from crgpr.learning.learned import LearnedRod, rollout
from crgpr.learning.nominal import NOMINAL_LAWS, NominalLaw
from crgpr.physics.simulate import simulate, trajectory_frame
from crgpr.report.metrics import accuracy


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--models", required=True)
    ap.add_argument("--name", required=True)
    ap.add_argument("--truth-set", action="append", default=[], help="config key=value under rod")
    ap.add_argument("--nominal", action="append", default=[], help="comma-separated laws to substitute")
    ap.add_argument("--angles", default="125,160")
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--csv", default="benchmarks/substituted_laws.csv")
    args = ap.parse_args()
    cfg = load_config(args.config)
    tcfg = copy.deepcopy(cfg)
    for item in args.truth_set:
        key, value = item.split("=", 1)
        d = tcfg
        *path, last = key.split(".")
        for k in path:
            d = d[k]
        d[last] = yaml.safe_load(value)
    truth = rod_params(tcfg)
    base, _ = load_learned(args.models)
    st = rollout_settings(cfg, base.params, None)
    rows = []
    for sub in args.nominal:
        laws = [k for k in sub.split(",") if k]
        comps = dict(base.components)
        comps.update({NOMINAL_LAWS[k]: NominalLaw(k, base.params) for k in laws})
        model = LearnedRod(comps, "objective", base.params)
        for a in (float(v) for v in args.angles.split(",")):
            gt = trajectory_frame(simulate(a, truth, st))
            try:
                e = accuracy(gt, trajectory_frame(rollout(model, a, st)), truth.L0)["rmse_theta"]
            except Exception as exc:  # noqa: BLE001 - a diverged rollout is a result, recorded as inf
                print(f"{sub} {a:g} deg: {exc}")
                e = float("inf")
            rows.append({"name": args.name, "models": args.models, "nominal": sub, "angle_deg": a,
                         "rmse_theta": e, "truth": " ".join(args.truth_set)})
            print(rows[-1], flush=True)
    csv = Path(args.csv)
    out = pd.DataFrame(rows)
    pd.concat([pd.read_csv(csv), out] if csv.exists() else [out]).to_csv(csv, index=False)


if __name__ == "__main__":
    main()
