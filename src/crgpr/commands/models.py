"""Gradient GPs, step 3 of the paper's Sec. III-B: rule ``gradient_model`` and
``crgpr train-gradient-model``.

Writes ``results/models/{prefilter}/{model}.npz`` + ``.json`` (algorithm:
``crgpr.learning.gradient_models``; their Table II is the report stage's ``table2``).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from crgpr.config import load_config
from crgpr.learning import gradient_models as gm


def gradient_model(cfg: dict[str, Any], model: str, prefilter_method: str, prefiltered: str,
                   out_npz: str) -> None:
    """Rule ``gradient_model``: fit one gradient GP on the prefiltered training trajectory."""
    gm.train_model(cfg, model, prefiltered, Path(out_npz).with_suffix(""), prefilter_method)


def add_cli(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("train-gradient-model", help="step 3: fit one gradient GP of Table II",
                       description="Fit one gradient GP (targets H_z of eq. (13), Sec. III-B step 3) "
                                   "from a prefilter Parquet file.")
    p.add_argument("--model", choices=gm.ALL_MODELS, required=True)
    p.add_argument("--prefiltered", required=True, help="prefilter Parquet file (step 2)")
    p.add_argument("--prefilter-method", default="gp", choices=("gp", "fd"))
    p.add_argument("--out", required=True, help="output stem: writes STEM.npz and STEM.json")
    p.add_argument("--config", default="config.yaml")
    p.set_defaults(func=lambda a: gm.train_model(load_config(a.config), a.model, a.prefiltered, a.out,
                                                 a.prefilter_method))
