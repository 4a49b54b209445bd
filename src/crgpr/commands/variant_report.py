"""Reports of the pipeline variants: rules ``variant_metrics`` and ``crgpr_sensitivity``.

Algorithms: ``crgpr.report.metrics`` (the accuracy metrics of every method),
``crgpr.report.sensitivity`` (the sensitivity table and figure). The variants themselves:
``crgpr.commands.variants`` and workflow/rules/variants.smk.
"""

from __future__ import annotations

from typing import Any

from crgpr.io import read_metadata, read_parquet, write_csv, write_parquet
from crgpr.report import metrics as metrics_mod
from crgpr.report import sensitivity


def variant_metrics(cfg: dict[str, Any], variant: str, method: str, angles: list[int],
                    ground_truth: list[str], rollouts: list[str], out: str) -> None:
    """Rule ``variant_metrics``: the accuracy of one variant's rollouts against its own ground truth.

    Columns ``crgpr.report.sensitivity.VARIANT_ACCURACY`` (the main metrics' columns plus the
    variant and whether the rollout diverged, from its metadata), one row per test angle.
    """
    if len(ground_truth) != len(angles) or len(rollouts) != len(angles):
        raise ValueError(f"variant_metrics: {len(ground_truth)} ground-truth and {len(rollouts)} rollout "
                         f"files for {len(angles)} angles")
    pairs = [(method, a, g, r) for a, g, r in zip(angles, ground_truth, rollouts, strict=True)]
    acc = metrics_mod.accuracy_table(pairs, float(cfg["rod"]["L0"]))
    if len(acc) != len(angles):
        raise FileNotFoundError(f"variant_metrics: rollouts missing among {rollouts}")
    metas = [read_metadata(r) for r in rollouts]
    acc.insert(0, "variant", variant)
    write_parquet(acc, out, {"kind": "variant_accuracy", "variant": variant, "method": method,
                             "angles": angles, "definitions": metrics_mod.__doc__,
                             "inputs": {r: m.get("code_version")
                                        for r, m in zip(rollouts, metas, strict=True)}})


def crgpr_sensitivity(cfg: dict[str, Any], variants: list[str], accuracy: list[str], table_out: str,
                      figure_out: str) -> None:
    """Rule ``crgpr_sensitivity``: results/tables/crgpr_sensitivity.csv and its figure, from the
    variants' accuracy files only (``accuracy`` in the order of ``variants``)."""
    angles = [int(a) for a in cfg["angles"]["test_deg"]]
    acc = {v: read_parquet(p, required=list(sensitivity.VARIANT_ACCURACY))
           for v, p in zip(variants, accuracy, strict=True)}
    tab = sensitivity.table(acc, cfg["variants"]["definitions"], angles)
    write_csv(tab, table_out, float_format="%.4f")
    sensitivity.figure(tab, angles, figure_out, reference=variants[0])

