"""Prefilter, step 2 of the paper's Sec. III-B: rule ``prefilter`` and ``crgpr prefilter``.

Writes the derivative data set E (eq. (12)) of one trajectory,
``results/prefilter/{gp,fd}/{angle}.parquet`` (algorithm: ``crgpr.learning.prefilter``).
"""

from __future__ import annotations

import argparse
import time
from typing import Any

from crgpr.config import load_config, rod_params
from crgpr.io import read_parquet, write_parquet
from crgpr.learning import prefilter as pf
from crgpr.physics.simulate import TRAJECTORY_COLUMNS, trajectory_from_frame
from crgpr.seeds import stage_seed


def prefilter(cfg: dict[str, Any], method: str, angle: int, gt: str, out: str) -> None:
    """Rule ``prefilter``: smooth one ground-truth trajectory, write E with its metadata."""
    params = rod_params(cfg)
    if method == "fd":  # central differences use only the output grid size
        settings = pf.PrefilterSettings(n_t_out=int(cfg["prefilter"]["n_t_out"]))
        seed = None
    else:
        settings = pf.PrefilterSettings.from_config(cfg)
        seed = stage_seed(cfg["seed"], "prefilter", int(angle))
    traj = trajectory_from_frame(read_parquet(gt, required=TRAJECTORY_COLUMNS), params)
    t0 = time.perf_counter()
    df, meta = pf.prefilter(traj, method, settings, seed or 0)
    meta.update({"kind": "prefilter", "theta0_deg": angle, "source": str(gt),
                 "seconds": time.perf_counter() - t0, "rod": params.to_dict()})
    if seed is not None:
        meta["seed"] = seed
    write_parquet(df, out, meta)


def add_cli(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("prefilter", help="step 2: smooth a trajectory and estimate its derivatives",
                       description="Write the derivative data set E (eq. (12), Sec. III-B step 2) of a "
                                   "ground-truth trajectory Parquet file.")
    p.add_argument("--method", choices=pf.METHODS, default="gp")
    p.add_argument("--trajectory", required=True, help="ground-truth trajectory Parquet file")
    p.add_argument("--out", required=True, help="Parquet file to write")
    p.add_argument("--config", default="config.yaml", help="config.yaml (sections rod, prefilter, seed)")
    p.set_defaults(func=_cli)


def _cli(args: argparse.Namespace) -> None:
    cfg = load_config(args.config)
    df = read_parquet(args.trajectory, required=TRAJECTORY_COLUMNS)
    if len(df) == 0:
        raise ValueError(f"{args.trajectory}: no rows")
    angle = int(round(float(df["theta0_deg"].iloc[0])))
    prefilter(cfg, args.method, angle, args.trajectory, args.out)
