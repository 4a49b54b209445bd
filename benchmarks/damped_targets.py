"""Benchmark: how much of a Kelvin-Voigt rod's bending damping its moment targets hold as c dkappa/dt.

    python benchmarks/damped_targets.py [--csv benchmarks/damped_targets.csv]

For each damped rod (the study's ``viscoelastic`` case and two rods of
``benchmarks/materials_unseen.py``), the study's full-state training record is made as the study
makes it (``commands.materials.material_data``), prefiltered as ``crgpr learn`` prefilters a full
state (``materials_study.prefilter``), and its bending-moment targets (eq. (13) through the
moment balance, ``learning.features``) are compared with the true elastic law m(kappa, s_j) of
each segment (``rod.segment_moment_law``). Columns: ``c_true`` [N m^2 s]; ``c_in_targets``, the
least-squares c of (targets - true law) on dkappa/dt = (omega_j+1 - omega_j) / ds;
``residual_over_rms``, the rms of what is left over the rms of the targets; ``c_fit``, the
damping regression of ``learning.damping`` (elastic polynomial of the config's degree per
segment, true law unknown). The record fit sizes c by the motion instead
(``learning.record_fit``; docs/learned-laws.md).
"""

from __future__ import annotations

import argparse
import copy
import math
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from materials_unseen import CASES

from crgpr.commands.learn import full_state_momenta, model_params
from crgpr.commands.materials import learn_config, material_case_rod, material_data
from crgpr.config import load_config
from crgpr.learning.damping import curvature_rates, fit_bending_damping
from crgpr.learning.gradient_models import inner_segments, training_data
from crgpr.learning.prefilter import PrefilterSettings, prefilter, prefiltered_arrays
from crgpr.measured.records import ScreenSettings, read_measured, validate_frame
from crgpr.physics.rod import segment_moment_law
from crgpr.physics.simulate import Trajectory


def one(cfg: dict, case: str, root: Path) -> dict:
    d = root / case
    d.mkdir()
    material_data(cfg, case, str(d / "train.parquet"), str(d / "camera.parquet"), str(d / "test.parquet"))
    lcfg = learn_config(cfg, "full_state")
    table = read_measured(d / "train.parquet")
    params = model_params(table, lcfg)
    meas = validate_frame(table, case, params.L0, params.ds, ScreenSettings.from_config(lcfg["discovery"]))
    theta, p = full_state_momenta(table, case, meas.t.size, meas.x.shape[1])
    traj = Trajectory(math.nan, meas.t, np.stack([meas.x, meas.y, theta], axis=-1), p, params)
    df, _ = prefilter(traj, str(cfg["materials_study"]["prefilter"]), PrefilterSettings.from_config(lcfg),
                      int(cfg["seed"]) + 3000)
    arr = prefiltered_arrays(df)
    seg = inner_segments(params.N, 0)
    X, m = training_data(arr, params, "obj_m", None, seg)
    kappa = X[:, 0].reshape(-1, int(seg.sum()))
    kdot = curvature_rates(arr["dtheta_dt"], params.ds)[:, seg].reshape(-1)
    truth = material_case_rod(cfg, case)
    idx = np.flatnonzero(seg)
    law = np.stack([segment_moment_law(truth, kappa[:, j])[:, i] for j, i in enumerate(idx)], axis=1).ravel()
    r = m - law
    c_in = float(kdot @ r / (kdot @ kdot))
    bd = cfg["camera"]["learn"]["bending_damping"]
    fit = fit_bending_damping(X[:, 0], kdot, m, np.broadcast_to(idx, kappa.shape).ravel(), int(bd["degree"]),
                              int(bd["blocks"]))
    return {"case": case, "c_true": truth.internal_damping, "c_in_targets": c_in,
            "residual_over_rms": float(np.sqrt(np.mean((r - c_in * kdot) ** 2)) / np.sqrt(np.mean(m**2))),
            "c_fit": fit.c_fit}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--csv", type=Path, default=Path("benchmarks/damped_targets.csv"))
    args = ap.parse_args()
    base = load_config("config.yaml")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for case in ("viscoelastic", "stiffening_viscoelastic", "saturating_viscoelastic"):
            cfg = copy.deepcopy(base)
            if case in CASES:
                cfg["materials_study"]["cases"][case], cfg["materials_study"]["theta0_deg"] = CASES[case]
            rows.append(one(cfg, case, Path(tmp)))
            print(rows[-1])
    pd.DataFrame(rows).to_csv(args.csv, index=False)


if __name__ == "__main__":
    main()
