"""Benchmark: the materials study's camera models with and without the record fit.

    python benchmarks/record_fit.py --results results \
        --cases exponential,saturating,precurved,graded,viscoelastic

(docs/learned-laws.md). For each case, the study's records (``results/materials/<case>/``
``camera.parquet``, ``train.parquet``, ``test.parquet``, written by ``snakemake -j2 all``) are
learned twice with the
study's own rules (``commands.materials.material_learn`` / ``material_score``), once with the
config's ``camera.learn.record_fit`` and once with its ``mode: none`` (the law as the regression
learned it), and scored at the study's six test angles. One row per (case, mode) is written to
``--csv``: mean RMSE(theta) over the angles, the worst ``ratio_to_nominal``, the record fit's
decision (kept, the warp's number of terms, held-out log error ratio and se), its RMSE of theta
over the training record before and after, and its wall time.
"""

from __future__ import annotations

import argparse
import copy
import json
import tempfile
from pathlib import Path

import pandas as pd

from crgpr.commands.materials import material_learn, material_score
from crgpr.config import load_config


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--results", default="results")
    ap.add_argument("--cases", default="linear,exponential,saturating,precurved,graded,viscoelastic")
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--csv", default="benchmarks/record_fit.csv")
    ap.add_argument("--modes", default="none,auto", help="record_fit modes to run, in this order")
    args = ap.parse_args()
    cfg = load_config(args.config)
    rows = []
    for case in args.cases.split(","):
        src = Path(args.results) / "materials" / case
        for mode in args.modes.split(","):
            c = copy.deepcopy(cfg)
            c["camera"]["learn"]["record_fit"]["mode"] = mode
            with tempfile.TemporaryDirectory() as tmp:
                material_learn(c, "camera", str(src / "camera.parquet"), f"{tmp}/model")
                material_score(c, case, "camera", f"{tmp}/model", str(src / "train.parquet"),
                               str(src / "test.parquet"), f"{tmp}/scores.parquet", f"{tmp}/tips.parquet")
                sc = pd.read_parquet(f"{tmp}/scores.parquet")
                fit = json.loads(Path(f"{tmp}/model/manifest.json").read_text()).get("record_fit") or {}
            row = {"case": case, "record_fit": mode, "rmse_theta_mean": sc["rmse_theta"].mean(),
                   "worst_ratio_to_nominal": sc["ratio_to_nominal"].max(), "kept": fit.get("kept"),
                   "warp_terms": fit.get("warp_terms"), "heldout_log_ratio": fit.get("heldout_log_ratio"),
                   "heldout_log_ratio_se": fit.get("heldout_log_ratio_se"),
                   "record_rmse_learned": fit.get("rmse_learned"),
                   "record_rmse_fitted": fit.get("rmse_fitted"),
                   "fit_seconds": fit.get("seconds")}
            print(row, flush=True)
            rows.append(row)
    pd.DataFrame(rows).to_csv(args.csv, index=False, float_format="%.6g")


if __name__ == "__main__":
    main()
