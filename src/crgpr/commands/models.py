"""Gradient GPs, step 3 of the paper's Sec. III-B: rules ``gradient_model``,
``gradient_model_paper_hyp``, ``paper_hyp_lml`` and ``crgpr train-gradient-model``.

Writes ``results/models/{prefilter}/{model}.npz`` + ``.json`` (algorithm:
``crgpr.learning.gradient_models``; their Table II is the report stage's ``table2``), the
paper-hyperparameter models under ``results/models/{prefilter}_paper_hyp/``, and the LML of our
and of the paper's hyperparameters on the same data (``results/tables/paper_hyp_lml.csv``).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from crgpr.config import load_config
from crgpr.learning import gradient_models as gm


def gradient_model(cfg: dict[str, Any], model: str, prefilter_method: str, prefiltered: str,
                   out_npz: str, gt_tests: list[str]) -> None:
    """Rule ``gradient_model``: fit one gradient GP on the prefiltered training trajectory
    (``gt_tests``: ground-truth files where the rollout mean is checked against the exact mean)."""
    gm.train_model(cfg, model, prefiltered, Path(out_npz).with_suffix(""), prefilter_method, gt_tests)


def gradient_model_paper_hyp(cfg: dict[str, Any], model: str, prefilter_method: str, prefiltered: str,
                             out_npz: str, gt_tests: list[str]) -> None:
    """Rule ``gradient_model_paper_hyp``: one gradient GP with the paper's Table II
    hyperparameters (``gradient_models.paper_hyperparameters``), conditioned on the same data."""
    gm.train_model(cfg, model, prefiltered, Path(out_npz).with_suffix(""), prefilter_method, gt_tests,
                   hyper="paper_table2")


def paper_hyp_lml(model_jsons: list[str], out: str) -> None:
    """Rule ``paper_hyp_lml``: LML of our fitted and of the paper's Table II hyperparameters on
    the subset our search used (``report.hyperparameters.lml_table``)."""
    from crgpr.io import write_csv
    from crgpr.report.hyperparameters import lml_table

    write_csv(lml_table(model_jsons), out)


def add_cli(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("train-gradient-model", help="step 3: fit one gradient GP of Table II",
                       description="Fit one gradient GP (targets H_z of eq. (13), Sec. III-B step 3) "
                                   "from a prefilter Parquet file.")
    p.add_argument("--model", choices=gm.ALL_MODELS, required=True)
    p.add_argument("--prefiltered", required=True, help="prefilter Parquet file (step 2)")
    p.add_argument("--prefilter-method", default="gp", choices=("gp", "fd"))
    p.add_argument("--out", required=True, help="output stem: writes STEM.npz and STEM.json")
    p.add_argument("--hyperparameters", default="fitted", choices=("fitted", "paper_table2"),
                   help="fit by the marginal likelihood, or the paper's Table II values")
    p.add_argument("--config", default="config.yaml")
    p.set_defaults(func=lambda a: gm.train_model(load_config(a.config), a.model, a.prefiltered, a.out,
                                                 a.prefilter_method, hyper=a.hyperparameters))
