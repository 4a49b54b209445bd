"""Benchmark: false discoveries and the detectability limit of ``crgpr discover``.

Records with one hidden effect (a case of ``discovery.cases`` with one effect) at several
magnitudes (``--scales`` times the case's coefficient; for ``base_compliance`` times its
compliance 1/k; ``--coefficients EFFECT=c1,c2`` gives an effect's coefficients instead),
released at several angles (``--angles``, default ``discovery.theta0_deg``), seen by cameras
of several marker counts and noise levels (markers equally spaced from 0.1 L0 to L0, no base
marker), each run through the whole workflow. Per record: the verdict, the names, the false
names (neither hidden nor a listed indistinguishable alternative of the hidden one), whether
a false name was invented beside the hidden one or named instead of it, and whether the
answer is right (the hidden effect named, or below the limit ``none``/``unexplained``: never
a wrong name). Writes

- ``--out`` (default ``results/tables/discovery_detectability.csv``): one row per record;
- ``--limits`` (default ``results/tables/discovery_detectability_limits.csv``): per effect,
  angle, marker count and noise, the smallest |coefficient| named with every larger one named
  too (empty if none), and the false-discovery count;
- ``--fdr`` (optional): per effect, the records, the records with an invented second effect,
  with a wrong effect instead of the hidden one, and with the hidden one named.

    python benchmarks/discovery_detectability.py [--config config.yaml]
        [--effects tip_mass stiffness_scale rest_curvature] [--scales 0.1 0.3 1]
        [--coefficients stiffness_scale=-0.3,0.4] [--angles 85 60]
        [--markers 6 12] [--noise-mm 1 2] [--duration-s 1.0] [--fdr FILE] [--keep DIR]
    python benchmarks/discovery_detectability.py --from-records A.csv B.csv [--out ...] [--fdr ...]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.commands.discovery import case_seed, run_discovery
from crgpr.commands.smk import limit_threads
from crgpr.config import load_config, rod_params
from crgpr.discovery.effects import EFFECT_NAMES
from crgpr.discovery.synthetic import make_measured
from crgpr.io import write_csv, write_parquet
from crgpr.physics.params import RodParams


def _one_effect_case(cases: list[dict], effect: str) -> dict:
    for c in cases:
        if set(c.get("effects", {})) == {effect} and "camera" not in c and "disturbance" not in c:
            return c
    raise SystemExit(f"--effects: no one-effect case of {effect!r} in discovery.cases")


def _coefficients(effect: str, base: float, scales: list[float], given: dict[str, list[float]]
                  ) -> list[tuple[float, float]]:
    """(coefficient, scale) pairs: the given coefficients (scale = coefficient / base), else the
    scales times the case's coefficient (times its compliance 1/k for base_compliance)."""
    if effect in given:
        return [(c, c / base) for c in given[effect]]
    if effect == "base_compliance":
        return [(base / k, k) for k in scales]
    return [(base * k, k) for k in scales]


def _parse_coefficients(items: list[str]) -> dict[str, list[float]]:
    out = {}
    for it in items:
        name, _, vals = it.partition("=")
        if name not in EFFECT_NAMES or not vals:
            raise SystemExit(f"--coefficients {it!r}: expected EFFECT=c1,c2, EFFECT one of {EFFECT_NAMES}")
        out[name] = [float(v) for v in vals.split(",")]
    return out


def limits(df: pd.DataFrame) -> pd.DataFrame:
    """Smallest |coefficient| named with every larger one named, per effect, angle, markers, noise.

    For base_compliance the effect grows with the compliance 1/k: the coefficients are ordered
    by it, and the limit is the largest k named."""
    rows = []
    for (eff, ang, m, nz), g in df.groupby(["effect", "angle_deg", "markers", "noise_mm"]):
        size = 1.0 / g["coefficient"] if eff == "base_compliance" else g["coefficient"].abs()
        g = g.assign(_size=size.to_numpy()).sort_values("_size")
        ok = g["named_right"].to_numpy()
        # the smallest magnitude from which on every larger one is named
        tail = np.flatnonzero(~ok)
        first = 0 if tail.size == 0 else tail[-1] + 1
        lim = float(g["coefficient"].iloc[first]) if first < len(g) else None
        rows.append({"effect": eff, "angle_deg": ang, "markers": m, "noise_mm": nz, "smallest_named": lim,
                     "records": len(g), "false_discoveries": int(g["false_discoveries"].sum()),
                     "wrong_answers": int((~g["right"]).sum())})
    return pd.DataFrame(rows)


def fdr(df: pd.DataFrame) -> pd.DataFrame:
    """Per effect (and all together): records, invented second effects, wrong effects, named."""
    def row(eff: str, g: pd.DataFrame) -> dict:
        return {"effect": eff, "records": len(g), "invented": int(g["invented"].sum()),
                "wrong_effect": int(g["wrong_effect"].sum()), "named_right": int(g["named_right"].sum()),
                "none_or_unexplained": int(g["verdict"].isin(["none", "unexplained"]).sum()),
                "coefficients": ";".join(f"{c:g}" for c in sorted(g["coefficient"].unique())),
                "angles_deg": ";".join(f"{a:g}" for a in sorted(g["angle_deg"].unique()))}
    rows = [row(eff, g) for eff, g in df.groupby("effect")]
    rows.append(row("all", df))
    return pd.DataFrame(rows)


def run_record(cfg: dict, rod: RodParams, tmp: Path, eff: str, coef: float, k: float, ang: float, m: int,
               nz: float, duration_s: float) -> dict:
    """One record with ``eff`` at ``coef`` released at ``ang`` deg, ``m`` markers, ``nz`` mm noise,
    through the whole workflow: its row of ``--out``."""
    d = cfg["discovery"]
    markers = np.round(np.linspace(0.1, 1.0, m) * rod.L0, 4).tolist()
    name = f"{eff}_{m}m_{nz:g}mm_x{k:g}" + ("" if ang == float(d["theta0_deg"]) else f"_{ang:g}deg")
    case = {"name": name, "effects": {eff: coef},
            "camera": {"markers_s": markers, "noise_std_m": nz * 1e-3, "duration_s": duration_s}}
    frame, truth = make_measured(rod, {**d, "theta0_deg": ang}, case, case_seed(cfg["seed"], name))
    path = tmp / f"{name}.parquet"
    write_parquet(frame, path)
    shutil.rmtree(tmp / name, ignore_errors=True)
    t0 = time.perf_counter()
    res = run_discovery(path, tmp / name, rod, cfg["simulation"]["dt_s"], d, cfg["seed"])
    named = [e["name"] for e in res["effects"]]
    alts = {a["named"]: a["alternative"] for a in res["indistinguishable_alternatives"]}
    false = [n for n in named if n != eff and alts.get(n) != eff]
    named_right = any(n == eff or alts.get(n) == eff for n in named)
    right = not false and (named_right or res["verdict"] in ("none", "unexplained"))
    return {"effect": eff, "coefficient": coef, "scale": k, "angle_deg": ang, "markers": m, "noise_mm": nz,
            "effect_size_rad": truth["effect_size_rmse_theta_rad"], "verdict": res["verdict"],
            "named": ";".join(named) or "none", "false_discoveries": len(false),
            "invented": bool(false and named_right), "wrong_effect": bool(false and not named_right),
            "named_right": bool(named_right), "right": bool(right),
            "gap_before_rad": res["gap_before"], "gap_floor_rad": res["gap_floor"],
            "rejected_out_of_sample": ";".join(r["effect"] for r in res["rejected_out_of_sample"]) or "none",
            "runtime_s": round(time.perf_counter() - t0, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--effects", nargs="+", default=["tip_mass", "stiffness_scale", "rest_curvature"])
    ap.add_argument("--scales", nargs="+", type=float, default=[0.1, 0.3, 1.0])
    ap.add_argument("--coefficients", nargs="*", default=[])
    ap.add_argument("--angles", nargs="+", type=float, default=None)
    ap.add_argument("--markers", nargs="+", type=int, default=[6, 12])
    ap.add_argument("--noise-mm", nargs="+", type=float, default=[1.0, 2.0])
    ap.add_argument("--duration-s", type=float, default=1.0)
    ap.add_argument("--out", default="results/tables/discovery_detectability.csv")
    ap.add_argument("--limits", default="results/tables/discovery_detectability_limits.csv")
    ap.add_argument("--fdr", default=None)
    ap.add_argument("--keep", default=None, help="keep each record's data and discover output here")
    ap.add_argument("--from-records", nargs="+", default=None,
                    help="no runs: concatenate these --out files of earlier runs into --out and summarise")
    args = ap.parse_args()
    if args.from_records:
        df = pd.concat([pd.read_csv(f) for f in args.from_records], ignore_index=True)
        write_csv(df, args.out)
        summarise(df, args.limits, args.fdr)
        return
    limit_threads()
    cfg = load_config(args.config)
    d = cfg["discovery"]
    rod = rod_params(cfg)
    given = _parse_coefficients(args.coefficients)
    angles = args.angles or [float(d["theta0_deg"])]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.keep or tmp)
        work.mkdir(parents=True, exist_ok=True)
        for eff in args.effects:
            base = float(_one_effect_case(d["cases"], eff)["effects"][eff])
            for ang in angles:
                for m in args.markers:
                    for nz in args.noise_mm:
                        for coef, k in _coefficients(eff, base, args.scales, given):
                            rows.append(run_record(cfg, rod, work, eff, coef, k, ang, m, nz,
                                                   args.duration_s))
                            print(rows[-1], flush=True)
                            write_csv(pd.DataFrame(rows), args.out)  # after every record
    summarise(pd.DataFrame(rows), args.limits, args.fdr)


def summarise(df: pd.DataFrame, limits_out: str, fdr_out: str | None) -> None:
    """Write the limits table and, if asked, the false-discovery summary of the records ``df``."""
    write_csv(limits(df), limits_out)
    if fdr_out:
        write_csv(fdr(df), fdr_out)


if __name__ == "__main__":
    main()
