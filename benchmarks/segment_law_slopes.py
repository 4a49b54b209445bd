"""Benchmark: a learned bending law against the true law, segment by segment.

    python benchmarks/segment_law_slopes.py KEEP_DIR/graded_precurved camera
    python benchmarks/segment_law_slopes.py KEEP_DIR/defect camera --csv /some/file.csv

``KEEP_DIR`` is the ``--keep`` directory of ``benchmarks/materials_unseen.py`` (a case's folder
holds its training record ``train.parquet`` and ``model_<input>``). For every segment j the
model's bending law (learned or nominal, with its record-fit warp and profile along s, as
``crgpr learn`` wrote it: ``learning.law_tables.bending_law_at_segments``) and the true law of
the case's rod (``physics.rod.segment_moment_law``) are compared over the curvatures the
segment reached in the training record: the least-squares line learned = slope x true + offset
and the rms error over the rms of the true law. A slope of 1.06 is a law 6 % too stiff there.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from materials_unseen import CASES  # noqa: E402

from crgpr.commands.learn import read_manifest  # noqa: E402
from crgpr.config import load_config, material_case_rod  # noqa: E402
from crgpr.io import read_parquet  # noqa: E402
from crgpr.learning.law_tables import bending_law_at_segments  # noqa: E402
from crgpr.learning.warp import manifest_warp, manifest_warp_cov  # noqa: E402
from crgpr.physics.params import RodParams  # noqa: E402
from crgpr.physics.rod import segment_moment_law, strains  # noqa: E402
from crgpr.physics.simulate import trajectory_from_frame  # noqa: E402


def slopes(case_dir: Path, source: str, config: str, n_grid: int = 201) -> pd.DataFrame:
    """One row per segment: j, s/L, covered curvature range, slope, offset [N m], rel_rms_error."""
    case = case_dir.name
    cfg = load_config(config)
    cfg["materials_study"]["cases"][case] = CASES[case][0]
    truth = material_case_rod(cfg, case)
    train = trajectory_from_frame(read_parquet(str(case_dir / "train.parquet")).assign(theta0_deg=math.nan),
                                  truth)
    kappa = strains(train.q, truth)["kappa"]
    model = case_dir / f"model_{source}"
    man = read_manifest(model)
    x = np.linspace(float(kappa.min()), float(kappa.max()), n_grid)
    lt = cfg["camera"]["learn"]["law_table"]
    mean, _ = bending_law_at_segments(model, list(man["models"]), RodParams.from_dict(man["rod"]), x,
                                      int(lt["max_points"]), int(cfg["seed"]), int(lt["band_blocks"]),
                                      manifest_warp(man.get("record_fit")),
                                      manifest_warp_cov(man.get("record_fit")))
    true = segment_moment_law(truth, x)
    rows = []
    for j in range(true.shape[1]):
        w = (x >= kappa[:, j].min()) & (x <= kappa[:, j].max())
        a, b = true[w, j], mean[w, j]
        slope, offset = np.linalg.lstsq(np.stack([a, np.ones_like(a)], 1), b, rcond=None)[0]
        rows.append({"segment": j, "s_over_L": (j + 0.5) / true.shape[1], "kappa_lo": kappa[:, j].min(),
                     "kappa_hi": kappa[:, j].max(), "slope": slope, "offset": offset,
                     "rel_rms_error": float(np.sqrt(np.mean((b - a) ** 2)) / np.sqrt(np.mean(a**2)))})
    return pd.DataFrame(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("case_dir", type=Path)
    ap.add_argument("input", choices=["full_state", "camera"])
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--csv", default=None)
    args = ap.parse_args()
    out = slopes(args.case_dir, args.input, args.config)
    print(out.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    if args.csv:
        out.to_csv(args.csv, index=False, float_format="%.6g")


if __name__ == "__main__":
    main()
