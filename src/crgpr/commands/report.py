"""Reports: rules ``metrics``, ``figures_crgpr``, ``table2``, ``baselines_table``, ``timing``,
``paper_tables`` and ``paper_claims_sweeps``; the commands ``crgpr accuracy`` and ``crgpr paper-tables``.

Algorithms: ``crgpr.report.metrics`` (accuracy, Tables III and V), ``crgpr.report.figures``,
``crgpr.report.hyperparameters`` (Table II), ``crgpr.report.comparison`` (the baselines),
``crgpr.report.timing`` (Table IV), ``crgpr.report.paper`` (every number of the paper beside ours).
"""

from __future__ import annotations

import argparse
import logging
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.io import read_metadata, read_parquet, write_csv, write_parquet, write_text
from crgpr.physics.simulate import TRAJECTORY_COLUMNS
from crgpr.report import comparison, hyperparameters
from crgpr.report import figures as figures_mod
from crgpr.report import metrics as metrics_mod
from crgpr.report import paper as paper_mod
from crgpr.report import timing as timing_mod

log = logging.getLogger(__name__)


def _accuracy_file(cfg: dict[str, Any], methods: list[str], angles: list[int], ground_truth: list[str],
                   rollouts: list[str], variant_accuracy: dict[str, str], out: str, kind: str
                   ) -> pd.DataFrame:
    """Score every (method, angle) rollout against the ground truth and write the accuracy file.

    ``ground_truth`` has one file per angle, ``rollouts`` one per (method, angle), method-major.
    ``variant_accuracy``: method -> a pipeline variant's accuracy file (rule ``variant_metrics``,
    scored against the variant's own ground truth); its rows join under that method name.
    """
    n = len(angles)
    if len(ground_truth) != n or len(rollouts) != len(methods) * n:
        raise ValueError(f"metrics: {len(ground_truth)} ground-truth and {len(rollouts)} rollout files "
                         f"for {len(methods)} methods x {n} angles")
    pairs = [(m, a, ground_truth[j], rollouts[i * n + j])
             for i, m in enumerate(methods) for j, a in enumerate(angles)]
    acc = metrics_mod.accuracy_table(pairs, float(cfg["rod"]["L0"]))
    provenance = {p: read_metadata(p).get("code_version") for _, _, _, p in pairs if Path(p).exists()}
    cols = list(metrics_mod.ACCURACY_COLUMNS)
    for method, path in variant_accuracy.items():
        rows = read_parquet(path, required=cols).assign(method=method)
        acc = pd.concat([acc, rows[rows["theta0_deg"].isin([float(a) for a in angles])][cols]],
                        ignore_index=True)
        provenance[path] = read_metadata(path).get("code_version")
    write_parquet(acc, out, {"kind": kind, "methods": [*methods, *variant_accuracy], "angles": angles,
                             "definitions": metrics_mod.__doc__, "inputs": provenance})
    return acc


def metrics(cfg: dict[str, Any], methods: list[str], angles: list[int], ground_truth: list[str],
            rollouts: list[str], out: str, table1_out: str, table4_out: str) -> None:
    """Rule ``metrics``: accuracy.parquet of every method of `all` and angle, the paper's Tables
    III and V (``_accuracy_file``)."""
    acc = _accuracy_file(cfg, methods, angles, ground_truth, rollouts, {}, out, "accuracy")
    rc = cfg["rollouts"]
    write_csv(metrics_mod.table1(acc, rc["table1_method"], angles), table1_out, float_format="%.4f")
    write_csv(metrics_mod.table4(acc, list(rc["ablation_methods"])), table4_out, float_format="%.4f")


def metrics_studies(cfg: dict[str, Any], methods: list[str], angles: list[int], ground_truth: list[str],
                    rollouts: list[str], variant_accuracy: dict[str, str], out: str) -> None:
    """Rule ``metrics_studies`` (target `sweeps`): accuracy_studies.parquet, the same columns as
    accuracy.parquet, for ``rollouts.study_methods`` and the ``variants.methods``."""
    _accuracy_file(cfg, methods, angles, ground_truth, rollouts, variant_accuracy, out, "accuracy_studies")


def figures_crgpr(cfg: dict[str, Any], method: str, angle: float, gt_train: str, gt_test: str,
                  gt_test_energy: str, rollout: str, rollout_energy: str, overlays_out: str,
                  shapes_out: str, energy_out: str) -> None:
    """Rule ``figures_crgpr``: overlays, rod shapes and energy of one method at one angle."""
    train = float(cfg["angles"]["train_deg"])
    gtt = read_parquet(gt_test)
    pred = read_parquet(rollout)
    figures_mod.overlays(gtt, pred, overlays_out, method, angle)
    figures_mod.shapes(read_parquet(gt_train), gtt, pred, shapes_out, method, train, angle)
    figures_mod.energy(read_parquet(rollout_energy), read_parquet(gt_test_energy), energy_out, method, angle)


def table2(model_jsons: list[str], out: str) -> None:
    """Rule ``table2``: the hyperparameters of every fitted gradient GP beside the paper's Table II."""
    write_csv(hyperparameters.table2(model_jsons), out)


def baselines_table(cfg: dict[str, Any], accuracy: str, rollouts: dict[str, list[str]],
                    ground_truth: list[str], pinn_histories: dict[str, str], table: str, notes: str,
                    figure: str) -> None:
    """Rule ``baselines_table``: table, notes and figure from the metrics and rollouts."""
    angles = [int(a) for a in cfg["angles"]["test_deg"]]
    acc = read_parquet(accuracy, required=["method", "theta0_deg", *comparison.METRICS])
    truth = {int(round(float(read_parquet(p, required=["theta0_deg"])["theta0_deg"].iloc[0]))): p
             for p in ground_truth}
    extra: dict[str, dict[str, Any]] = {}
    for method, files in rollouts.items():
        ratios, div = [], []
        for f in files:
            pred = read_parquet(f, required=["theta0_deg", "node", "theta"])
            a = int(round(float(pred["theta0_deg"].iloc[0])))
            ratios.append(comparison.motion_ratio(pred, read_parquet(truth[a])))
            meta = read_metadata(f)
            if meta.get("diverged"):
                div.append(f"{a} deg at t = {meta.get('t_diverged'):.3g} s, node {meta.get('node_diverged')}")
        extra[method] = {"motion_ratio": float(np.mean(ratios)), "n_diverged": len(div),
                         "diverged_at": "; ".join(div)}
    for method, path in pinn_histories.items():
        h = read_parquet(path, required=["loss", "loss_momentum", "loss_data"])
        meta = read_metadata(path)
        extra.setdefault(method, {}).update({
            "train_seconds": meta.get("train_seconds"),
            "final_loss_momentum": float(h["loss_momentum"].iloc[-1]),
            "final_loss_data": float(h["loss_data"].iloc[-1])})
    df = comparison.baseline_table(acc, angles, extra)
    write_csv(df, table, float_format="%.6g")
    write_text(comparison.notes_markdown(df, angles), notes)
    comparison.plot_baselines(df, figure)
    log.info("baselines table:\n%s", df.to_string())


def timing(stage_files: dict[str, dict[str, list[str]]], out: str) -> None:
    """Rule ``timing``: the paper's Table IV stages from the Snakemake benchmark files."""
    write_parquet(timing_mod.timing_table(stage_files), out, {"kind": "timing"})


def paper_tables(values: str, accuracy: str | None, hyper: str | None, timing: str | None,
                 uq: str | None, out_csv: str, out_md: str, out_claims: str,
                 noise: str | None = None) -> None:
    """Rule ``paper_tables``: every number and claim of the paper beside ours (csv, md, claims).

    ``noise``: ``noise_ablation.csv`` of the ``sweeps`` target. The rule leaves it
    out (the ablation is not part of ``all``), so the claims on it are left out of the tables
    (``report.paper.sweep_claims``); ``crgpr paper-tables`` after ``snakemake sweeps`` adds them.
    """
    paper_mod.build(values, accuracy, hyper, timing, uq, out_csv, out_md, out_claims, noise)


def paper_claims_sweeps(values: str, noise: str, out_claims: str) -> None:
    """Rule ``paper_claims_sweeps`` (target ``sweeps``): the paper's claims on the noise
    ablation, which ``paper_tables`` leaves out, evaluated on ``noise_ablation.csv``."""
    paper_mod.build_sweep_claims(values, noise, out_claims)


def add_cli(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("accuracy", help="metrics of one rollout against ground truth",
                       description="RMSE(theta), R^2, tip RMSE / L0 and Group-nRMSE (paper Sec. V).")
    p.add_argument("--ground-truth", required=True)
    p.add_argument("--rollout", required=True)
    p.add_argument("--L0", type=float, help="rod length [m] (default: from the ground truth's metadata)")
    p.set_defaults(func=_accuracy_cli)
    p = sub.add_parser("paper-tables", help="regenerate results/tables/paper_vs_reproduction.{csv,md}")
    p.add_argument("--values", default="workflow/paper_values.yaml")
    p.add_argument("--results", default="results", help="results directory of a run")
    p.set_defaults(func=_paper_tables_cli)


def _accuracy_cli(args: argparse.Namespace) -> None:
    gt = read_parquet(args.ground_truth, required=TRAJECTORY_COLUMNS)
    L0 = args.L0 if args.L0 is not None else read_metadata(args.ground_truth).get("rod", {}).get("L0")
    if L0 is None or not math.isfinite(L0) or L0 <= 0:
        raise ValueError(f"{args.ground_truth}: no rod length in its metadata; pass --L0 (> 0) [m]")
    print(metrics_mod.accuracy(gt, read_parquet(args.rollout), L0, args.ground_truth, args.rollout))


def _paper_tables_cli(args: argparse.Namespace) -> None:
    r = Path(args.results)
    tables = r / "tables"
    paper_mod.build(args.values, str(r / "metrics/accuracy.parquet"),
                    str(tables / "table2_hyperparameters.csv"), str(r / "metrics/timing.parquet"),
                    str(tables / "uq_coverage.csv"),
                    str(tables / "paper_vs_reproduction.csv"), str(tables / "paper_vs_reproduction.md"),
                    str(tables / "paper_claims.csv"),
                    str(tables / "noise_ablation.csv") if (tables / "noise_ablation.csv").exists() else None)
