"""Benchmark: the evidence behind crgpr learn's law choices on one record (docs/learned-laws.md).

    python benchmarks/law_choice_evidence.py --record benchmarks/learned_laws/saturating_full.parquet \
        --name saturating [--models benchmarks/learned_laws/saturating_full] [--config config.yaml]

For the record (a file of ``benchmarks/learned_laws.py``: full state or camera positions) the
state and the law samples are built as ``crgpr learn`` builds them (gp prefilter; the end
segments trimmed for positions), then:

* per law (n1, n2, m, the momentum maps) the held-out-block comparison of the nominal law and a
  learned stand-in (``law_choice.learned_or_nominal``, the config's choice_degree and choice_blocks);
* the arclength comparison (``law_choice.arclength_dependence``) with the config's spline in
  kappa and with a plain polynomial in kappa (``choice_knots`` = 0), to show what the spline is for;
* with ``--models`` (a model directory with a ``laws.parquet``, e.g. the benchmark's ``before``
  model), the rms deviation of each learned law from the nominal law over the covered range of
  its own strain input, relative to the nominal law's rms there.

One row per quantity is appended to ``--csv`` (benchmarks/law_choice_evidence.csv).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.commands.learn import full_state_momenta, model_params
from crgpr.config import load_config
from crgpr.learning.camera import LearnSettings, positions_to_state
from crgpr.learning.features import segment_arclength
from crgpr.learning.gradient_models import inner_segments, training_data
from crgpr.learning.law_choice import arclength_dependence, learned_or_nominal
from crgpr.learning.nominal import MOMENTUM_LAWS, NOMINAL_LAWS, NominalLaw
from crgpr.learning.prefilter import PrefilterSettings, prefilter, prefiltered_arrays
from crgpr.measured.records import ScreenSettings, read_measured, validate_frame
from crgpr.physics.simulate import Trajectory

OWN_INPUT = {"obj_n1": "nu1", "obj_n2": "nu2", "obj_m": "kappa"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--record", required=True)
    ap.add_argument("--name", required=True)
    ap.add_argument("--models")
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--csv", default="benchmarks/law_choice_evidence.csv")
    args = ap.parse_args()
    cfg = load_config(args.config)
    cam = cfg["camera"]["learn"]
    table = read_measured(args.record)
    params = model_params(table, cfg)
    screen = ScreenSettings.from_config(cfg["discovery"])
    meas = validate_frame(table, args.record, params.L0, params.ds, screen)
    full = full_state_momenta(table, args.record, meas.t.size, meas.x.shape[1])
    seed = int(cfg["seed"]) + 3000
    if full is None:
        arr, _ = positions_to_state(meas, params, "gp", LearnSettings.from_config(cam), seed)
        trim, kind = int(cam["trim_ends"]), "positions"
    else:
        theta, p = full
        traj = Trajectory(math.nan, meas.t, np.stack([meas.x, meas.y, theta], axis=-1), p, params)
        arr = prefiltered_arrays(prefilter(traj, "gp", PrefilterSettings.from_config(cfg), seed)[0])
        trim, kind = 0, "full_state"
    mask = inner_segments(params.N, trim)
    deg, blocks = int(cam["choice_degree"]), int(cam["choice_blocks"])
    rows = []
    for law, (col, stiff, ref) in {"n1": (0, params.EA, params.nu1_0), "n2": (1, params.GA, params.nu2_0),
                                   "m": (0, params.EI, params.kappa0)}.items():
        X, y = training_data(arr, params, f"obj_{law}", None, mask)
        c = learned_or_nominal(X[:, :1] if law == "m" else X, y, stiff * (X[:, col] - ref), deg, blocks,
                               pooled=True)
        rows.append({"quantity": "learned_or_nominal", "law": law, **c.to_dict()})
    for law in MOMENTUM_LAWS:  # the velocity maps H_p(p) against p / (rho A), p / (rho I)
        X, y = training_data(arr, params, NOMINAL_LAWS[law], None)
        c = learned_or_nominal(X, y, NominalLaw(law, params)(X[:, 0]), deg, blocks, pooled=False)
        rows.append({"quantity": "learned_or_nominal", "law": law, **c.to_dict()})
    X, y = training_data(arr, params, "obj_m", None, mask)
    S = np.broadcast_to(segment_arclength(params.N, params.ds), (arr["x"].shape[0], params.N))
    S = S[:, mask].ravel()
    for knots in (0, int(cam["choice_knots"])):
        s_degree, weights = cam["choice_s_tests"][kind][0]
        c = arclength_dependence(X[:, 0], S, y, deg, knots, int(s_degree), blocks, str(weights))
        rows.append({"quantity": f"arclength_dependence, {knots} knots", "law": "m", **c.to_dict()})
    if args.models:
        tab = pd.read_parquet(Path(args.models) / "laws.parquet")
        for law, inp in OWN_INPUT.items():
            d = tab[(tab["law"] == law) & (tab["input"] == inp) & tab["covered"]]
            if d.empty:
                continue
            rms = np.sqrt(np.mean((d["mean"] - d["nominal"]) ** 2))
            dev = float(rms / np.sqrt(np.mean(d["nominal"] ** 2)))
            rows.append({"quantity": f"rms deviation from nominal over covered {inp} (relative)",
                         "law": law.removeprefix("obj_"), "value": dev, "models": args.models})
    out = pd.DataFrame(rows).assign(name=args.name, input=kind, record=args.record)
    print(out.to_string())
    csv = Path(args.csv)
    pd.concat([pd.read_csv(csv), out] if csv.exists() else [out]).to_csv(csv, index=False)


if __name__ == "__main__":
    main()
