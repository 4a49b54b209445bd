"""Stage timings from Snakemake ``benchmark:`` files, beside the paper's timing table.

Stage definitions (paper Table "Computational cost"):
1. GP prefiltering of the training trajectory (prefilter job of the training angle),
2. gradient learning (sum of the six gradient-model jobs),
3. one CR-GPR forward simulation (the ``cr_gpr`` rollout job integrates all test angles in one
   batch: its time / the number of angles),
4. UQ / RFF sampling: drawing the S function samples (once) plus one angle's S-sample rollout
   (the UQ rollout job integrates all angles in one batch: its time / the number of angles).

Each stage is given as ``{"sum": [files], "mean": [files], "per_job": n}``: its minutes are the
sum of the first group plus the mean of the second divided by ``per_job`` (default 1; the
angles one job of a per-angle stage covers).
"""

from __future__ import annotations

import os
import platform
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

PAPER_MINUTES = {"stage1": 3.0, "stage2": 8.0, "stage3": 2.4, "stage4": 36.0}
DESCRIPTION = {
    "stage1": "GP prefiltering (fit state GPs, extract z-dot), training angle",
    "stage2": "Gradient learning (train the 6 dH/dz models), total",
    "stage3": "Simulation: one 2 s CR-GPR rollout (mean per angle)",
    "stage4": "UQ / RFF sampling: S trajectory samples of one angle (mean per angle)",
}


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


def timing_table(stage_files: dict[str, dict[str, Any]]) -> pd.DataFrame:
    """One row per stage: minutes = sum of the "sum" files + mean of the "mean" files / per_job."""
    rows = []
    for stage, groups in stage_files.items():
        summed = [read_benchmark(f) for f in groups.get("sum", [])]
        averaged = [read_benchmark(f) for f in groups.get("mean", [])]
        per = int(groups.get("per_job", 1))
        secs = float(np.sum(summed)) + (float(np.mean(averaged)) / per if averaged else 0.0)
        how = " + ".join(x for x in (f"sum of {len(summed)}" if summed else "",
                                      (f"mean of {len(averaged)}" + (f" / {per}" if per != 1 else ""))
                                      if averaged else "") if x)
        rows.append({"stage": stage, "description": DESCRIPTION[stage], "minutes": secs / 60.0,
                     "jobs": len(summed) + len(averaged), "how": how,
                     "paper_minutes": PAPER_MINUTES[stage], "machine": machine()})
    return pd.DataFrame(rows)
