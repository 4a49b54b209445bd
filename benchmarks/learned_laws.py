"""Benchmark: learn a rod with a hidden material effect, roll out at unseen angles (docs/learned-laws.md).

    python benchmarks/learned_laws.py --name precurved --truth kappa0=2 --input camera \
        [--learn camera.learn.bending_symmetry=none] [--config config.yaml] [--out benchmarks/learned_laws]
    python benchmarks/learned_laws.py --name exponential --input full \
        --truth-set rod.material.bending_law=exponential --truth-set rod.material.bending_beta=0.1
    python benchmarks/learned_laws.py --name kelvin_voigt --truth-set rod.material.kelvin_voigt=5e-5 \
        --input full

The true rod is the config's ``rod`` with the ``--truth-set`` config overlays (dotted keys under
``rod``, YAML values: ``rod.material`` laws and profiles, docs/materials.md) and then the
``--truth`` overrides (``RodParams`` fields: kappa0, nonlinear_stiffness, stiffness_gradient,
internal_damping, stiffness_scale); the nominal rod is the config's ``rod``. Its 85 deg
release (config t_end, dt) is recorded at 250 Hz: every node's positions with 1 mm Gaussian
noise (``--input camera``, seed 0) or the noise-free full state (``--input full``). ``crgpr
learn`` (objective features, gp prefilter, the config with the ``--learn`` overrides: dotted
config keys, YAML values) trains on it; the learned rod and the nominal rod (the config's
``rod``, no learning) are rolled out at 125, 160, 225 deg and scored against the true rod
(RMSE of theta over the free nodes, ``report.metrics.accuracy``). One row is appended to
``--csv`` (benchmarks/learned_laws.csv; the learned rod's manifest decisions included); the model directory is
kept under ``OUT/<name>_<input>/``.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from crgpr.commands.camera import camera_frame
from crgpr.commands.learn import learn, load_learned
from crgpr.commands.rollout import rollout_settings
from crgpr.config import load_config, rod_params
from crgpr.io import write_parquet
from crgpr.learning.learned import rollout
from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import simulate, trajectory_frame
from crgpr.report.metrics import accuracy

ANGLES = (125.0, 160.0, 225.0)


def _set(cfg: dict, key: str, value: str) -> None:
    d = cfg
    *path, last = key.split(".")
    for k in path:
        d = d[k]
    v = yaml.safe_load(value)
    if isinstance(v, str):  # YAML 1.1 reads 5e-5 (no dot) as a string
        with contextlib.suppress(ValueError):
            v = float(v)
    d[last] = v


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--name", required=True)
    ap.add_argument("--truth", action="append", default=[], help="RodParams field=value of the true rod")
    ap.add_argument("--truth-set", action="append", default=[],
                    help="config key=value (under rod, YAML value) of the true rod, e.g. "
                    "rod.material.bending_law=saturating")
    ap.add_argument("--input", choices=("camera", "full"), default="camera")
    ap.add_argument("--learn", action="append", default=[], help="config key=value for crgpr learn")
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--out", default="benchmarks/learned_laws")
    ap.add_argument("--csv", default="benchmarks/learned_laws.csv", help="CSV the row is appended to")
    ap.add_argument("--code", default="", help="label of the code state for the CSV row")
    args = ap.parse_args()
    cfg = load_config(args.config)
    nominal = rod_params(cfg)
    tcfg = copy.deepcopy(cfg)
    for s in args.truth_set:
        if not s.startswith("rod."):
            raise SystemExit(f"--truth-set {s}: expected a key under rod")
        _set(tcfg, *s.split("=", 1))
    truth = replace(rod_params(tcfg), **{k: float(v) for k, v in (s.split("=", 1) for s in args.truth)})
    lcfg = copy.deepcopy(cfg)
    for s in args.learn:
        _set(lcfg, *s.split("=", 1))
    sim = cfg["simulation"]
    rec = SimSettings(dt=float(sim["dt_s"]), t_end=float(sim["t_end_s"]), record_every=40,
                      scheme=sim["scheme"])
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tag = f"{args.name}_{args.input}"
    tr = simulate(85.0, truth, rec)
    data = out / f"{tag}.parquet"
    if args.input == "camera":
        df = camera_frame(tr.t, tr.q, 1e-3, np.random.default_rng(0))
    else:
        df = trajectory_frame(tr)
    write_parquet(df, data)
    t0 = time.process_time()
    man = learn(data, out / tag, lcfg, "objective", "gp")
    cpu_learn = time.process_time() - t0
    model, _ = load_learned(out / tag)
    st = rollout_settings(cfg, model.params, None)
    row: dict = {"name": args.name, "input": args.input, "truth": " ".join([*args.truth_set, *args.truth]),
                 "code": args.code, "learn": " ".join(args.learn), "cpu_learn_s": round(cpu_learn, 1)}
    rl, rn = [], []
    for a in ANGLES:
        gt = trajectory_frame(simulate(a, truth, st))
        nom = gt if truth == nominal else trajectory_frame(simulate(a, nominal, st))
        try:
            lr = trajectory_frame(rollout(model, a, st))
            e = accuracy(gt, lr, nominal.L0)["rmse_theta"]
        except Exception as exc:  # noqa: BLE001 - a diverged rollout is a result, recorded as inf
            print(f"{a:g} deg: {exc}")
            e = float("inf")
        rl.append(e)
        rn.append(accuracy(gt, nom, nominal.L0)["rmse_theta"])
        row[f"rmse_theta_{a:g}"] = e
        row[f"nominal_rmse_theta_{a:g}"] = rn[-1]
    row["mean_rmse_theta"] = float(np.mean(rl))
    row["nominal_mean_rmse_theta"] = float(np.mean(rn))
    nom_mean = row["nominal_mean_rmse_theta"]
    row["ratio_to_nominal"] = row["mean_rmse_theta"] / nom_mean if nom_mean > 0 else float("nan")
    for k in ("bending_odd_about", "rest_state", "nominal_laws", "models", "law_choice", "bending_inputs",
              "bending_arclength", "bending_damping"):
        if k in man:
            row[k] = json.dumps(man[k])
    print(json.dumps(row, indent=1))
    csv = Path(args.csv)
    pd.concat([pd.read_csv(csv), pd.DataFrame([row])] if csv.exists() else [pd.DataFrame([row])]
              ).to_csv(csv, index=False)


if __name__ == "__main__":
    main()
