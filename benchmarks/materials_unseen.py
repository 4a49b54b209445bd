"""Benchmark: the materials study's path on rods the study does not hold.

    python benchmarks/materials_unseen.py --csv benchmarks/materials_unseen.csv
    python benchmarks/materials_unseen.py --cases defect,softvisco --csv /some/other.csv

(docs/materials.md, "Rods outside the study"). Each case below is a true material the study's
six cases do not contain (another law parameter, a local defect, a combination of laws, another
release angle). For each, the study's own rules run on it as they run on a study case
(``commands.materials.material_data`` at the case's release angle, then ``material_learn`` and
``material_score`` for the full state and the 1 mm camera record, the config's
``materials_study`` settings otherwise); one row per (case, input) goes to ``--csv``: the mean
and worst RMSE(theta) over the study's six test angles, the worst ``ratio_to_nominal``,
``law_rmse`` and ``law_band_coverage``, which laws stayed nominal, the rest curvature used, the
damping's c, whether the record fit kept its warp, and the learn wall time. ``--keep DIR`` keeps
the records and models there.
"""

from __future__ import annotations

import argparse
import copy
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import pandas as pd

from crgpr.commands.materials import material_data, material_learn, material_score
from crgpr.config import load_config

# case -> (rod.material overlay of the true rod, release angle of the training record [deg])
CASES: dict[str, tuple[dict[str, Any], float]] = {
    "defect": ({"defect_start": 0.3, "defect_end": 0.45, "defect_factor": 0.5}, 70.0),
    "stiff_precurved": ({"bending_law": "exponential", "bending_beta": 0.08,
                         "rest_curvature_profile": [[0.0, -2.0], [1.0, -2.0]]}, 100.0),
    "soft_saturating": ({"bending_law": "saturating", "saturation_moment": 0.05}, 70.0),
    "stiffening_viscoelastic": ({"bending_law": "exponential", "bending_beta": 0.03, "kelvin_voigt": 2.0e-4},
                                85.0),
    "saturating_viscoelastic": ({"bending_law": "saturating", "saturation_moment": 0.06,
                                 "kelvin_voigt": 1.5e-4}, 70.0),
    "graded_precurved": ({"stiffness_profile": [[0.0, 0.7], [1.0, 1.4]],
                          "rest_curvature_profile": [[0.0, 1.0], [1.0, 3.0]]}, 110.0),
}


def run_case(cfg: dict[str, Any], case: str, root: Path) -> list[dict[str, Any]]:
    """The study's rules on one case in ``root``: its records, then both inputs learned and scored."""
    material, theta0 = CASES[case]
    c = copy.deepcopy(cfg)
    c["materials_study"]["cases"][case] = material
    c["materials_study"]["theta0_deg"] = theta0
    d = root / case
    d.mkdir(parents=True, exist_ok=True)
    material_data(c, case, str(d / "train.parquet"), str(d / "camera.parquet"), str(d / "test.parquet"))
    rows = []
    for source in ("full_state", "camera"):
        t0 = time.perf_counter()
        material_learn(c, source, str(d / ("train.parquet" if source == "full_state" else "camera.parquet")),
                       str(d / f"model_{source}"))
        seconds = time.perf_counter() - t0
        material_score(c, case, source, str(d / f"model_{source}"), str(d / "train.parquet"),
                       str(d / "test.parquet"), str(d / f"scores_{source}.parquet"),
                       str(d / f"tips_{source}.parquet"))
        sc = pd.read_parquet(d / f"scores_{source}.parquet")
        man = json.loads((d / f"model_{source}" / "manifest.json").read_text())
        fit, damp = man.get("record_fit") or {}, man.get("bending_damping") or {}
        rest = man.get("rest_state") or {}
        rows.append({"case": case, "input": source, "theta0_deg": theta0, "material": json.dumps(material),
                     "rmse_theta_mean": sc["rmse_theta"].mean(), "rmse_theta_max": sc["rmse_theta"].max(),
                     "nominal_rmse_theta_mean": sc["nominal_rmse_theta"].mean(),
                     "worst_ratio_to_nominal": sc["ratio_to_nominal"].max(),
                     "law_rmse": sc["law_rmse"].iloc[0], "law_band_coverage": sc["law_band_coverage"].iloc[0],
                     "nominal_laws": " ".join(man["nominal_laws"]),
                     "bending_odd_about": man.get("bending_odd_about"), "rest_degree": rest.get("degree"),
                     "damping_c": damp.get("coefficient"), "warp_kept": fit.get("kept"),
                     "learn_seconds": seconds})
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--csv", default="benchmarks/materials_unseen.csv")
    ap.add_argument("--keep", default=None, help="directory to keep the records and models in")
    args = ap.parse_args()
    cfg = load_config(args.config)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(args.keep or tmp)
        for case in args.cases.split(","):
            rows += run_case(cfg, case, root)
    pd.DataFrame(rows).to_csv(args.csv, index=False, float_format="%.6g")


if __name__ == "__main__":
    main()
