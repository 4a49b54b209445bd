"""PINN baselines (paper Sec. V, "Baseline Comparisons"): rules ``pinn_train`` and ``pinn_rollout``.

Algorithm: ``crgpr.baselines.pinn``. Writes ``results/baselines/pinn/{variant}.pt`` (a state
dict, loaded with ``weights_only=True``), its loss history, and
``results/rollouts/{variant}/{angle}.parquet``.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from crgpr.baselines import pinn
from crgpr.config import ConfigError, rod_params
from crgpr.io import atomic_path, read_parquet, write_parquet
from crgpr.physics.simulate import TRAJECTORY_COLUMNS

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


def pinn_rollout(cfg: dict[str, Any], variant: str, weights: str, ground_truths: list[str], angles: list[int],
                 outs: list[str], threads: int = 1) -> None:
    """Rule ``pinn_rollout``: evaluate one trained PINN on the ground-truth (t, node) grid of every
    test angle (``ground_truths``, ``angles`` and ``outs`` in the same order), one file per angle.
    Every ground truth is checked before anything is written."""
    import torch

    torch.set_num_threads(max(1, int(threads)))
    params = rod_params(cfg)
    if not len(ground_truths) == len(angles) == len(outs):
        raise ValueError("pinn_rollout: ground_truths, angles and outs differ in length")
    grids = []
    for path in ground_truths:
        gt = read_parquet(path, required=TRAJECTORY_COLUMNS)
        n_nodes = int(gt["node"].max()) + 1
        if n_nodes != params.N + 1:
            raise ConfigError(f"{path}: has {n_nodes} nodes but rod.N + 1 = {params.N + 1}")
        grids.append(np.unique(gt["t"].to_numpy()))
    model = pinn.load_model(cfg, weights)
    for angle, t, out in zip(angles, grids, outs, strict=True):
        z = pinn.predict(model, params, float(angle), t)
        write_parquet(pinn.prediction_frame(z, t, params, float(angle)), out,
                      {"kind": "rollout", "method": variant, "theta0_deg": float(angle),
                       "description": pinn.VARIANTS[variant], "rod": params.to_dict(), "diverged": False})
