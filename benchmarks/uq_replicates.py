"""Calibration judged over independent truths (replicate training trajectories).

One training trajectory gives ONE realisation of the fitted law's error, shared by every test
angle, so a calibrated model's angle-mean coverage of that one truth scatters with sd 0.11-0.16
(``calibrated_coverage_sd`` of uq_coverage.csv) and cannot resolve a coverage target of ±0.05.
Each replicate here is the same pipeline (config.yaml with only ``angles.train_deg`` changed,
so a different training trajectory and a different fitted law) run to ``uq_coverage.csv``; the
statistic is the mean over replicates of the six-angle mean theta coverage. Its calibrated
reference distribution: in every replicate one sample, drawn independently per replicate, is the
'truth' covered by the band of the other S - 1 (leave-one-out, the same sample at every angle of
that replicate, ``crgpr.uq.coverage.loo_coverages``); 100 000 such draws give the reference's mean,
sd and the one-sided fraction >= the observed (near 0: the band is too wide; near 1: too narrow).
That reference assumes the replicates' law errors independent; the script prints the
correlation between replicates of the mean models' theta error (mean rollout - truth, over every
time, node and angle) so that this can be checked: near 1, the replicates are one truth again.

    python benchmarks/uq_replicates.py --method cr_gpr_objective --out benchmarks/uq/replicates.csv \
        --make 80 75 70 --workdir replicates .

RUN_DIR (positional, e.g. ``.`` for the main run): a workflow directory with
results/uq/{method}/{angle}.parquet, results/rollouts/{method}/{angle}.parquet and
results/ground_truth/{angle}.parquet (the config's ``uq.angles_deg``, ``uq.levels``).
``--make DEG ...`` first builds one replicate per training angle under ``--workdir``/DEG: this
config with ``angles.train_deg`` = DEG (also in place of the training angle in
``angles.pinn_train_deg``) and ``uq.methods`` = [method], run by Snakemake to
results/tables/uq_coverage.csv (about 7 min per replicate on the 2 cores); then it is added to the
RUN_DIRs. Column ``mean_error_corr_first``: that correlation against the first RUN_DIR.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from crgpr.io import read_parquet
from crgpr.physics.simulate import TRAJECTORY_COLUMNS
from crgpr.uq.coverage import coverage_rows, expected_coverage, sample_arrays, truth_arrays
from crgpr.uq.rollout import UQ_COLUMNS


def replicate(run: Path, method: str, angles: list[float], levels: list[float]
              ) -> tuple[dict[float, float], dict[float, np.ndarray], int, dict[float, float]]:
    """(observed angle-mean theta coverage per level, leave-one-out angle-mean coverages per
    level (S,), S, angle-mean theta band width per level [rad]) of one workflow directory."""
    rows: list[dict] = []
    n_s = None
    for a in angles:
        df = read_parquet(run / f"results/uq/{method}/{a:g}.parquet", required=UQ_COLUMNS)
        arr = sample_arrays(df, ("x", "y", "theta"))
        t = np.sort(df["t"].unique())
        g = truth_arrays(read_parquet(run / f"results/ground_truth/{a:g}.parquet",
                                      required=TRAJECTORY_COLUMNS), t, ("x", "y", "theta"))
        if n_s is not None and arr.shape[0] != n_s:
            raise SystemExit(f"{run}: {arr.shape[0]} samples at {a:g} deg, {n_s} elsewhere (a sample "
                             "diverged); the leave-one-out needs the same samples at every angle")
        n_s = arr.shape[0]
        rows += coverage_rows(arr, g, levels, [n_s])  # the rule's own rows, with their "loo"
    by_level = {lv: [r for r in rows if r["level"] == lv] for lv in levels}
    obs = {lv: [r["theta_coverage"] for r in rs] for lv, rs in by_level.items()}
    loo = {lv: [r["loo"] for r in rs] for lv, rs in by_level.items()}
    width = {lv: [r["theta_band_width_mean"] for r in rs] for lv, rs in by_level.items()}
    return ({lv: float(np.mean(v)) for lv, v in obs.items()},
            {lv: np.mean(v, axis=0) for lv, v in loo.items()}, int(n_s),
            {lv: float(np.mean(v)) for lv, v in width.items()})


def mean_error(run: Path, method: str, angles: list[float]) -> np.ndarray:
    """Theta error of the mean model's rollout (results/rollouts) against the truth, flattened."""
    out = []
    for a in angles:
        m = read_parquet(run / f"results/rollouts/{method}/{a:g}.parquet", required=TRAJECTORY_COLUMNS)
        t = np.sort(m["t"].unique())
        g = truth_arrays(read_parquet(run / f"results/ground_truth/{a:g}.parquet",
                                      required=TRAJECTORY_COLUMNS), t, ("theta",))
        out.append((truth_arrays(m, t, ("theta",)) - g)[1:, 1:].ravel())
    return np.concatenate(out)


def make_replicate(config: Path, method: str, deg: int, workdir: Path) -> Path:
    """One replicate workflow directory: the config with ``angles.train_deg`` = deg, run by
    Snakemake to uq_coverage.csv (Snakemake skips what is already up to date)."""
    cfg = yaml.safe_load(config.read_text())
    train = cfg["angles"]["train_deg"]
    cfg["angles"]["train_deg"] = deg
    cfg["angles"]["pinn_train_deg"] = [deg if x == train else x for x in cfg["angles"]["pinn_train_deg"]]
    cfg["uq"]["methods"] = [method]
    run = workdir / str(deg)
    run.mkdir(parents=True, exist_ok=True)
    (run / "config.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    snakefile = Path(__file__).resolve().parents[1] / "Snakefile"
    subprocess.run([sys.executable, "-m", "snakemake", "-j2", "--snakefile", str(snakefile),
                    "--configfile", str(run / "config.yaml"), "-d", str(run),
                    "results/tables/uq_coverage.csv"], check=True)
    return run


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="*", type=Path)
    ap.add_argument("--make", nargs="*", type=int, default=[], metavar="DEG")
    ap.add_argument("--workdir", type=Path, default=Path("replicates"))
    ap.add_argument("--method", default="cr_gpr_objective")
    ap.add_argument("--config", type=Path, default=Path("config.yaml"))
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--draws", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    uq = yaml.safe_load(a.config.read_text())["uq"]
    angles = [float(x) for x in uq["angles_deg"]]
    levels = [float(x) for x in uq["levels"]]
    rng = np.random.default_rng(a.seed)
    a.runs = list(a.runs) + [make_replicate(a.config, a.method, d, a.workdir) for d in a.make]
    if len(a.runs) < 2:
        raise SystemExit("uq_replicates: give at least two RUN_DIRs or --make angles")
    err = np.array([mean_error(run, a.method, angles) for run in a.runs])
    corr = np.corrcoef(err)
    rows, per = [], []
    for i, run in enumerate(a.runs):
        train = yaml.safe_load((run / "config.yaml").read_text())["angles"]["train_deg"] \
            if (run / "config.yaml").exists() else None
        obs, loo, n_s, width = replicate(run, a.method, angles, levels)
        per.append((obs, loo))
        for lv in levels:
            rows.append({"method": a.method, "train_deg": train, "run": str(run), "level": lv,
                         "n_samples": n_s, "theta_coverage": obs[lv],
                         "expected_coverage": expected_coverage(n_s, lv),
                         "calibrated_coverage_sd": float(np.std(loo[lv], ddof=1)),
                         "calibrated_fraction_at_least": float(np.mean(loo[lv] >= obs[lv])),
                         "theta_band_width_mean": float(f"{width[lv]:.4g}"),
                         "rms_mean_error": float(f"{np.sqrt(np.mean(err[i] ** 2)):.4g}"),
                         "mean_error_corr_first": float(corr[0, i])})
    for lv in levels:
        pooled = float(np.mean([o[lv] for o, _ in per]))
        ref = np.mean([loo_lv[lv][rng.integers(0, loo_lv[lv].size, a.draws)] for _, loo_lv in per],
                      axis=0)
        rows.append({"method": a.method, "train_deg": "pooled", "run": f"{len(per)} replicates",
                     "level": lv, "n_samples": per[0][1][lv].size, "theta_coverage": pooled,
                     "expected_coverage": float(np.mean([r["expected_coverage"] for r in rows if
                                                         r["level"] == lv and r["train_deg"] != "pooled"])),
                     "calibrated_coverage_sd": float(np.std(ref)),
                     "calibrated_fraction_at_least": float(np.mean(ref >= pooled)),
                     "loo_reference_mean": float(np.mean(ref))})
    print("correlation of the mean models' theta errors between replicates:")
    print(np.array2string(corr, precision=2))
    print("rms theta error of the mean models:", np.array2string(np.sqrt(np.mean(err**2, axis=1)),
                                                                 precision=6))
    df = pd.DataFrame(rows)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    df.round({c: 5 for c in df.columns if c not in ("theta_band_width_mean", "rms_mean_error")}).to_csv(
        a.out, index=False)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(df.drop(columns="run").round(4).to_string(index=False))


if __name__ == "__main__":
    main()
