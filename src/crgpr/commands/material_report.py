"""The materials study's table and figures (docs/materials.md, "The materials study"): rule
``material_laws`` (workflow/rules/materials.smk) on the rows and tip paths of ``material_score``
(``commands.materials``), apart from it so that a change of the figures reruns only this rule.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pandas as pd

from crgpr.commands.learn_laws import LAW_TABLE
from crgpr.commands.materials import COLUMNS, INPUTS
from crgpr.config import material_case_rod, rod_params
from crgpr.io import read_parquet, write_csv
from crgpr.physics.rod import strains
from crgpr.physics.simulate import trajectory_from_frame
from crgpr.report.materials import material_figure


def material_table(scores: list[str], out_csv: str) -> pd.DataFrame:
    """The score rows of ``material_score`` (``COLUMNS``), in the order given, written to
    ``out_csv``: ``material_laws.csv``, and rule ``material_laws_defaults``'s table of the camera
    records learned with ``crgpr learn``'s own settings (target ``sweeps``)."""
    table = pd.concat([read_parquet(p) for p in scores], ignore_index=True)[list(COLUMNS)]
    write_csv(table, out_csv)
    return table


def material_laws(cfg: dict[str, Any], cases: list[str], scores: list[str], tips: list[str],
                  model_dirs: list[str], trains: list[str], out_csv: str, figures: list[str]) -> pd.DataFrame:
    """Rule ``material_laws``: ``material_laws.csv`` (the score rows, case by case, input by input)
    and one figure per case (``report.materials.material_figure``). ``scores``, ``tips`` and
    ``model_dirs`` are ordered case-major over ``INPUTS``; ``trains`` and ``figures`` by case."""
    n = len(INPUTS)
    table = material_table(scores, out_csv)
    nominal = rod_params(cfg)
    for i, (case, train, fig) in enumerate(zip(cases, trains, figures, strict=True)):
        truth = material_case_rod(cfg, case)
        laws = {inp: read_parquet(Path(d) / LAW_TABLE) if (Path(d) / LAW_TABLE).is_file() else None
                for inp, d in zip(INPUTS, model_dirs[i * n:(i + 1) * n], strict=True)}
        tip = {inp: read_parquet(p) for inp, p in zip(INPUTS, tips[i * n:(i + 1) * n], strict=True)}
        kappa = strains(trajectory_from_frame(read_parquet(train).assign(theta0_deg=math.nan), truth).q,
                        truth)["kappa"]
        material_figure(case, laws, tip, truth, nominal, kappa, table[table["case"] == case], fig)
    return table
