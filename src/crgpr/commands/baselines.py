"""The paper's baselines (Sec. V, "Baseline Comparisons"): rules ``pinn_train``,
``pinn_rollout``, ``blackbox_train``, ``blackbox_rollout`` and ``baselines_table``.

Algorithms: ``crgpr.baselines.pinn``, ``crgpr.baselines.blackbox``; the comparison table
and figure: ``crgpr.report.comparison``.
"""

from __future__ import annotations

import json
import logging
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.baselines import blackbox, pinn
from crgpr.config import ConfigError, rod_params, sim_settings
from crgpr.io import (
    atomic_dir,
    atomic_path,
    read_metadata,
    read_parquet,
    write_csv,
    write_json,
    write_parquet,
    write_text,
)
from crgpr.learning.prefilter import PREFILTER_COLUMNS
from crgpr.physics.rod import STATE_NAMES
from crgpr.physics.simulate import TRAJECTORY_COLUMNS
from crgpr.report import comparison

log = logging.getLogger(__name__)


def pinn_train(cfg: dict[str, Any], variant: str, data: dict[int, str], weights_out: str,
               history_out: str, threads: int = 1) -> None:
    """Rule ``pinn_train``: train one variant, write the state dict and the loss history."""
    import torch

    model, hist, info = pinn.train_pinn(cfg, variant, data, threads)
    with atomic_path(weights_out, ".pt") as tmp:
        torch.save(model.state_dict(), tmp)
    write_parquet(hist, history_out, {"kind": "pinn_loss_history", **info})
    log.info("%s trained in %.1f s", variant, info["train_seconds"])


def pinn_rollout(cfg: dict[str, Any], variant: str, weights: str, ground_truth: str, angle: int,
                 out: str, threads: int = 1) -> None:
    """Rule ``pinn_rollout``: evaluate a trained PINN on the ground-truth (t, node) grid."""
    import torch

    torch.set_num_threads(max(1, int(threads)))
    params = rod_params(cfg)
    gt = read_parquet(ground_truth, required=TRAJECTORY_COLUMNS)
    t = np.unique(gt["t"].to_numpy())
    n_nodes = int(gt["node"].max()) + 1
    if n_nodes != params.N + 1:
        raise ConfigError(f"{ground_truth}: has {n_nodes} nodes but rod.N + 1 = {params.N + 1}")
    model = pinn.load_model(cfg, weights)
    z = pinn.predict(model, params, float(angle), t)
    write_parquet(pinn.prediction_frame(z, t, params, float(angle)), out,
                  {"kind": "rollout", "method": variant, "theta0_deg": float(angle),
                   "description": pinn.VARIANTS[variant], "rod": params.to_dict(), "diverged": False})


def blackbox_train(cfg: dict[str, Any], prefiltered: str, out_dir: str, summary: str) -> None:
    """Rule ``blackbox_train``: six GPs from the prefiltered training trajectory."""
    params = rod_params(cfg)
    st = blackbox.blackbox_settings(cfg)
    df = read_parquet(prefiltered, required=PREFILTER_COLUMNS)
    F, Y, center = blackbox.training_set(df, params, cfg)
    seed = int(cfg["seed"]) + 4000
    t0 = time.perf_counter()
    gps = blackbox.fit_blackbox(F, Y, st, seed)
    rows = []
    with atomic_dir(out_dir) as tmp:
        for name, gp in zip(blackbox.TARGETS, gps, strict=True):
            gp.save(tmp / name, {"features": list(blackbox.FEATURES), "target": name, "seed": seed,
                                 "theta_center": center})
            rows.append({"model": name, **gp.hyperparameters(), "fit_seconds": gp.info["fit_seconds"]})
    write_json({"kind": "blackbox_gp", "features": list(blackbox.FEATURES), "targets": list(blackbox.TARGETS),
                "seed": seed, "theta_center": center, "source": str(prefiltered),
                "seconds": time.perf_counter() - t0, "settings": st, "models": rows}, summary)


def blackbox_rollout(cfg: dict[str, Any], model_dir: str, summary: str, angle: int, out: str) -> None:
    """Rule ``blackbox_rollout``: integrate from the straight rod at ``angle`` deg."""
    params, settings = rod_params(cfg), sim_settings(cfg)
    meta = json.loads(Path(summary).read_text())
    gps = blackbox.load_models(model_dir)
    t0 = time.perf_counter()
    t, q, p, info = blackbox.rollout(gps, float(angle), params, settings, meta["theta_center"])
    n_t, n_nodes, _ = q.shape
    df = pd.DataFrame({
        "theta0_deg": np.full(n_t * n_nodes, float(angle)), "t": np.repeat(t, n_nodes),
        "node": np.tile(np.arange(n_nodes, dtype=np.int32), n_t), "s": np.tile(params.s, n_t),
    })
    for c, name in enumerate(STATE_NAMES):
        df[name] = (q if c < 3 else p)[..., c % 3].ravel()
    write_parquet(df[list(TRAJECTORY_COLUMNS)], out,
                  {"kind": "rollout", "method": "blackbox_gp", "theta0_deg": float(angle),
                   "rod": params.to_dict(), "simulation": settings.to_dict(), "seed": meta["seed"],
                   "seconds": time.perf_counter() - t0, **info})
    if info["diverged"]:
        log.warning("blackbox_gp %s deg: diverged at t = %.4g s (node %s); frozen afterwards", angle,
                    info["t_diverged"], info["node_diverged"])


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
