"""Black-box GP baseline (paper Sec. V, "Baseline Comparisons"): rules ``blackbox_train`` and
``blackbox_rollout``.

Algorithm: ``crgpr.baselines.blackbox``. Writes ``results/baselines/blackbox_gp/models/``
(atomically, locked), ``summary.json`` and ``results/rollouts/blackbox_gp/{angle}.parquet``.
"""

from __future__ import annotations

import json
import logging
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.baselines import blackbox
from crgpr.config import rod_params, sim_settings
from crgpr.io import atomic_dir, read_parquet, write_json, write_parquet
from crgpr.learning.prefilter import PREFILTER_COLUMNS
from crgpr.physics.rod import STATE_NAMES
from crgpr.physics.simulate import TRAJECTORY_COLUMNS
from crgpr.seeds import stage_seed

log = logging.getLogger(__name__)


def blackbox_train(cfg: dict[str, Any], prefiltered: str, out_dir: str, summary: str) -> None:
    """Rule ``blackbox_train``: six GPs from the prefiltered training trajectory."""
    params = rod_params(cfg)
    st = blackbox.blackbox_settings(cfg)
    df = read_parquet(prefiltered, required=PREFILTER_COLUMNS)
    F, Y, center = blackbox.training_set(df, params, bool(cfg["gradient_models"]["theta_wrap"]))
    seed = stage_seed(cfg["seed"], "blackbox")
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


def blackbox_rollout(cfg: dict[str, Any], model_dir: str, summary: str, angles: list[int],
                     outs: list[str]) -> None:
    """Rule ``blackbox_rollout``: integrate from the straight rod at each of ``angles`` deg, one
    file of ``outs`` per angle (the GPs loaded once)."""
    params, settings = rod_params(cfg), sim_settings(cfg)
    meta = json.loads(Path(summary).read_text())
    gps = blackbox.load_models(model_dir)
    for angle, out in zip(angles, outs, strict=True):
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
