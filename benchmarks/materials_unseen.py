"""Benchmark: the materials study's path on rods the study does not hold.

    python benchmarks/materials_unseen.py --csv benchmarks/materials_unseen.csv
    python benchmarks/materials_unseen.py --cases defect,softvisco --csv /some/other.csv
    python benchmarks/materials_unseen.py --cases soft_saturating \
        --set "camera.learn.record_fit.warp_terms=[4]" --csv benchmarks/materials_unseen_variants.csv --append

(docs/materials.md, "Rods outside the study"). Each case below is a true material the study's
six cases do not contain (another law parameter, a local defect, a combination of laws, another
release angle). For each, the study's own rules run on it as they run on a study case
(``commands.materials.material_data`` at the case's release angle, then ``material_learn`` and
``material_score`` for the full state, under the study's caps, and the 1 mm camera record, with
``crgpr learn``'s own settings as in the study's ``sweeps`` table; the config's
``materials_study`` settings otherwise); one row per (case, input) goes to ``--csv``: the mean
and worst RMSE(theta) over the study's six test angles, the worst ``ratio_to_nominal``,
``law_rmse`` and ``law_band_coverage``, which laws stayed nominal, the rest curvature used, the
damping's c, whether the record fit kept its warp (and with how many terms), whether it fell
back to the nominal rod, whether a damped rod's bending law was taken nominal (warped), the
terms of the profile along the rod it kept (``profile_terms`` of the stiffness factor v(s),
``rest_terms`` of the rest-curvature shift, its stored c_0.., c_0 = 0 where the level is the
law's own estimate; 0: none kept or not offered), the least tangent
stiffness of the bending law as rolled out over its covered curvatures in units of EI
(``min_tangent_over_ei``, the manifest's ``bending_tangent``; empty for a nominal law unwarped),
and the learn wall time. ``--keep DIR`` keeps
the records and models there (``--rescore``: score the kept ones again after a change of the
scoring, learning nothing; ``learn_seconds`` then comes from the rows already in ``--csv``).
``--capped``: the camera records learned under the study's run-time caps (as ``all`` learns
them) instead of ``crgpr learn``'s own settings. ``--set KEY=VALUE`` (repeatable; a dotted key
of the config, the
value read as YAML) runs a variant of the config; its rows carry the overrides in a column
``overrides``, and ``--append`` adds them to an existing ``--csv``. ``--case NAME MATERIAL
THETA0`` (repeatable) runs a rod of your own through the same rules: ``MATERIAL`` a
``rod.material`` overlay as YAML or JSON, ``THETA0`` the training release angle [deg]; without
``--cases`` only those run. ``--truth-refine K`` (K > 1) makes the records with another
discretisation than the model's: the true rod with K N segments and a K^2 times shorter step
(the same record interval); the camera sees all K N + 1 nodes (markers at s = i L0 / (K N), an
``s`` column: the model keeps the config's N), the full-state record and the test records keep
every K-th node (the model's grid); rows carry ``truth_refine`` and ``grid_floor_rmse_theta``, the
mean RMSE(theta) at the test angles of the true rod on the model's grid (the true law, no
learning) against the finer one: the discretisation's share of every model's error.
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from crgpr.commands.camera import camera_frame
from crgpr.commands.materials import (
    LEARN_DEFAULTS,
    camera_seed,
    material_data,
    material_learn,
    material_score,
    study_settings,
)
from crgpr.config import load_config, material_case_rod
from crgpr.io import write_parquet
from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import Trajectory, simulate, trajectory_frame, trajectory_from_frame

INPUTS: tuple[str, ...] = ("full_state", "camera")

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


def _fine(cfg: dict[str, Any], case: str, theta0: float, t_end: float, refine: int) -> Trajectory:
    """The true rod of ``case`` with ``refine`` times more segments, released at ``theta0``."""
    st = study_settings(cfg, t_end)
    fine = material_case_rod(cfg, case)
    fine = fine.replace(N=fine.N * refine)
    return simulate(theta0, fine, SimSettings(dt=st.dt / refine**2, t_end=st.t_end,
                                              record_every=st.record_every * refine**2, scheme=st.scheme))


def _coarse(tr: Trajectory, refine: int) -> Trajectory:
    """Every ``refine``-th node of a fine trajectory: the model's grid (momenta per length)."""
    params = tr.params.replace(N=tr.params.N // refine)
    return Trajectory(tr.theta0_deg, tr.t, tr.q[:, ::refine], tr.p[:, ::refine], params)


def refined_data(cfg: dict[str, Any], case: str, refine: int, d: Path) -> float:
    """``material_data``'s three records from a ``refine`` times finer true rod, and the grid's
    floor (module docstring)."""
    ms = cfg["materials_study"]
    tr = _fine(cfg, case, float(ms["theta0_deg"]), float(ms["t_end_s"]), refine)
    every = int(round(1.0 / (float(ms["camera_rate_hz"]) * float(np.median(np.diff(tr.t))))))
    meta = {"kind": "material_record", "case": case, "truth_refine": refine}
    cam = camera_frame(tr.t[::every], tr.q[::every], float(ms["camera_noise_m"]),
                       camera_seed(int(cfg["seed"]), case))
    cam.insert(1, "s", cam.pop("node") * tr.params.ds)  # markers at arc lengths: the config's N
    write_parquet(cam, str(d / "camera.parquet"),
                  {**meta, "kind": "measured", "noise_std_m": float(ms["camera_noise_m"])})
    write_parquet(trajectory_frame(_coarse(tr, refine)).drop(columns=["theta0_deg", "s"]),
                  str(d / "train.parquet"), meta)
    st = study_settings(cfg, float(ms["rollout_t_end_s"]))
    tests = [_coarse(_fine(cfg, case, float(a), st.t_end, refine), refine) for a in ms["test_deg"]]
    write_parquet(pd.concat([trajectory_frame(t) for t in tests], ignore_index=True), str(d / "test.parquet"),
                  meta)
    return _floor(cfg, case, tests)


def _floor(cfg: dict[str, Any], case: str, tests: list[Trajectory]) -> float:
    """The grid's floor (module docstring): the true rod on the model's grid against the refined
    test records ``tests`` (on the model's nodes), mean RMSE(theta) over them."""
    st = study_settings(cfg, float(cfg["materials_study"]["rollout_t_end_s"]))
    rod = material_case_rod(cfg, case)
    return float(np.mean([np.sqrt(np.mean((simulate(t.theta0_deg, rod, st).q[:, 1:, 2] - t.q[:, 1:, 2])**2))
                          for t in tests]))


def grid_floor(cfg: dict[str, Any], case: str, test: Path) -> float:
    """The grid's floor (``_floor``) from kept test records of a refined true rod."""
    rod = material_case_rod(cfg, case)
    tests = [trajectory_from_frame(g, rod) for _, g in pd.read_parquet(test).groupby("theta0_deg")]
    return _floor(cfg, case, tests)


def run_case(cfg: dict[str, Any], case: str, root: Path, refine: int = 1,
             inputs: tuple[str, ...] = INPUTS, reuse: bool = False,
             rescore: dict[tuple[str, str], float] | None = None,
             capped: bool = False) -> list[dict[str, Any]]:
    """The study's rules on one case in ``root``: its records (from a ``refine`` times finer true
    rod where > 1; ``reuse``: the records kept in ``root`` from an earlier run, where all three
    are there), then ``inputs`` learned and scored. ``rescore``: the models kept in ``root`` are
    scored again, not learned; the mapping (case, input) -> learn seconds of the earlier run
    (NaN where absent) fills ``learn_seconds``. ``capped``: the camera record under the study's
    run-time caps (the source ``camera`` of ``all``), not ``crgpr learn``'s own settings."""
    material, theta0 = CASES[case]
    c = copy.deepcopy(cfg)
    c["materials_study"]["cases"][case] = material
    c["materials_study"]["theta0_deg"] = theta0
    d = root / case
    d.mkdir(parents=True, exist_ok=True)
    extra = {}
    kept = reuse and all((d / f).is_file() for f in ("train.parquet", "camera.parquet", "test.parquet"))
    if kept:
        if refine > 1:
            extra = {"truth_refine": refine, "grid_floor_rmse_theta": grid_floor(c, case, d / "test.parquet")}
    elif refine > 1:
        extra = {"truth_refine": refine, "grid_floor_rmse_theta": refined_data(c, case, refine, d)}
    else:
        material_data(c, case, str(d / "train.parquet"), str(d / "camera.parquet"), str(d / "test.parquet"))
    rows = []
    for source in inputs:
        t0 = time.perf_counter()
        if rescore is None:
            record = d / ("train.parquet" if source == "full_state" else "camera.parquet")
            # the camera record as crgpr learn learns it by default (the study's source camera_defaults)
            learned = LEARN_DEFAULTS if source == "camera" and not capped else source
            material_learn(c, learned, str(record), str(d / f"model_{source}"))
        seconds = time.perf_counter() - t0 if rescore is None else rescore.get((case, source), float("nan"))
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
                     "warp_terms": fit.get("warp_terms"), "nominal_fallback": fit.get("nominal_fallback"),
                     "bending_nominal": bool(fit.get("bending_nominal")),
                     "profile_terms": len(fit.get("profile_coefficients") or []),
                     "rest_terms": len(fit.get("rest_coefficients") or []),
                     "min_tangent_over_ei": (man.get("bending_tangent") or {}).get("min_over_EI"),
                     "learn_seconds": seconds, **extra})
        print(rows[-1], flush=True)
    return rows


def overridden(cfg: dict[str, Any], sets: list[str]) -> tuple[dict[str, Any], dict[str, Any]]:
    """The config with ``KEY=VALUE`` overrides (dotted keys that exist in it) and the overrides;
    a malformed or unknown key exits with one line (exit code 2)."""
    c, done = copy.deepcopy(cfg), {}
    for item in sets:
        key, sep, raw = item.partition("=")
        *path, last = key.split(".")
        d = c
        for k in path:
            d = d.get(k) if isinstance(d, dict) else None
        if not sep or not isinstance(d, dict) or last not in d:
            print(f"materials_unseen.py: --set {item!r}: not KEY=VALUE with a dotted key of the config",
                  file=sys.stderr)
            sys.exit(2)
        d[last] = done[key] = yaml.safe_load(raw)
    return c, done


def extra_case(name: str, material: str, theta0: str) -> tuple[dict[str, Any], float]:
    """A ``--case``'s (material overlay, release angle); a malformed one exits with one line
    (exit code 2)."""
    try:
        overlay, angle = yaml.safe_load(material), float(theta0)
    except (yaml.YAMLError, ValueError) as exc:
        print(f"materials_unseen.py: --case {name}: {exc}".splitlines()[0], file=sys.stderr)
        sys.exit(2)
    if not isinstance(overlay, dict):
        print(f"materials_unseen.py: --case {name}: MATERIAL must be a mapping of rod.material keys",
              file=sys.stderr)
        sys.exit(2)
    return overlay, angle


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default=None, help="comma-separated names of the cases above")
    ap.add_argument("--case", nargs=3, action="append", default=[], metavar=("NAME", "MATERIAL", "THETA0"),
                    help="another case: its rod.material overlay (YAML or JSON) and release angle [deg]")
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--csv", default="benchmarks/materials_unseen.csv")
    ap.add_argument("--keep", default=None, help="directory to keep the records and models in")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config override")
    ap.add_argument("--append", action="store_true", help="add the rows to an existing --csv")
    ap.add_argument("--capped", action="store_true",
                    help="camera records under the study's run-time caps, as `all` learns them")
    ap.add_argument("--truth-refine", type=int, default=1, metavar="K",
                    help="records from a true rod with K times more segments (module docstring)")
    ap.add_argument("--inputs", default=",".join(INPUTS), help="comma-separated inputs to learn from")
    ap.add_argument("--reuse", action="store_true", help="the records kept in --keep from an earlier run")
    ap.add_argument("--rescore", action="store_true",
                    help="score the records and models kept in --keep again, learning nothing (their "
                         "learn seconds from the rows of --csv)")
    args = ap.parse_args()
    inputs = tuple(args.inputs.split(","))
    if not inputs or any(i not in INPUTS for i in inputs) or ((args.reuse or args.rescore) and not args.keep):
        print(f"materials_unseen.py: --inputs: a comma-separated subset of {list(INPUTS)}; "
              "--reuse and --rescore need --keep", file=sys.stderr)
        sys.exit(2)
    for name, material, theta0 in args.case:
        CASES[name] = extra_case(name, material, theta0)
    names = args.cases.split(",") if args.cases else [c[0] for c in args.case] or list(CASES)
    unknown = [c for c in names if c not in CASES]
    if unknown:
        print(f"materials_unseen.py: --cases: unknown case(s) {unknown}; known: {list(CASES)}",
              file=sys.stderr)
        sys.exit(2)
    if args.truth_refine < 1:
        print("materials_unseen.py: --truth-refine: a whole number >= 1", file=sys.stderr)
        sys.exit(2)
    cfg, sets = overridden(load_config(args.config), args.set)
    rescore = None
    if args.rescore:
        need = [Path(args.keep) / c / f for c in names
                for f in ("train.parquet", "test.parquet", *(f"model_{i}/manifest.json" for i in inputs))]
        missing = [p for p in need if not p.is_file()]
        if missing:
            print(f"materials_unseen.py: --rescore: {missing[0]} not kept", file=sys.stderr)
            sys.exit(2)
        old = pd.read_csv(args.csv) if Path(args.csv).is_file() else pd.DataFrame()
        rescore = {} if old.empty else {(r.case, r.input): float(r.learn_seconds) for r in old.itertuples()}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(args.keep or tmp)
        for case in names:
            rows += run_case(cfg, case, root, args.truth_refine, inputs, args.reuse or args.rescore, rescore,
                             args.capped)
    out = pd.DataFrame(rows)
    if sets:
        out["overrides"] = json.dumps(sets, sort_keys=True)
    if args.append and Path(args.csv).is_file():
        out = pd.concat([pd.read_csv(args.csv), out], ignore_index=True)
    out.to_csv(args.csv, index=False, float_format="%.6g")


if __name__ == "__main__":
    main()
