"""Stage timings from Snakemake ``benchmark:`` files, beside the paper's timing table.

Stage definitions (paper Table "Computational cost"):
1. GP prefiltering of the training trajectory (prefilter job of the training angle),
2. gradient learning (sum of the six gradient-model jobs),
3. one CR-GPR forward simulation (mean over the rollout jobs of ``cr_gpr``),
4. UQ / RFF sampling, S samples of one angle (mean over the UQ jobs).
"""

from __future__ import annotations

import os
import platform
from pathlib import Path

import numpy as np
import pandas as pd

from .io import write_parquet

PAPER_MINUTES = {"stage1": 3.0, "stage2": 8.0, "stage3": 2.4, "stage4": 36.0}
DESCRIPTION = {
    "stage1": "GP prefiltering (fit state GPs, extract z-dot), training angle",
    "stage2": "Gradient learning (train the 6 dH/dz models), total",
    "stage3": "Simulation: one 2 s CR-GPR rollout (mean per angle)",
    "stage4": "UQ / RFF sampling: S trajectory samples of one angle (mean per angle)",
}
HOW = {"stage1": "sum", "stage2": "sum", "stage3": "mean", "stage4": "mean"}


def machine() -> str:
    cpu = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{os.cpu_count()} cores ({cpu}), {platform.system()}, Python {platform.python_version()}"


def read_benchmark(path: str | Path) -> float:
    """Wall seconds of one Snakemake benchmark file (mean over its repeats)."""
    df = pd.read_csv(path, sep="\t")
    if "s" not in df.columns:
        raise ValueError(f"{path}: not a Snakemake benchmark file (no column 's')")
    return float(df["s"].mean())


def timing_table(stage_files: dict[str, list[str]]) -> pd.DataFrame:
    rows = []
    for stage, files in stage_files.items():
        secs = [read_benchmark(f) for f in files]
        total = float(np.sum(secs)) if HOW[stage] == "sum" else float(np.mean(secs)) if secs else np.nan
        rows.append({"stage": stage, "description": DESCRIPTION[stage], "minutes": total / 60.0,
                     "jobs": len(files), "how": HOW[stage], "paper_minutes": PAPER_MINUTES[stage],
                     "machine": machine()})
    return pd.DataFrame(rows)


def rule(stage_files: dict[str, list[str]], out: str) -> None:
    write_parquet(timing_table(stage_files), out, {"kind": "timing"})
