"""Benchmark: false discoveries and the detectability limit of ``crgpr discover``.

Records with one hidden effect (a case of ``discovery.cases`` with one effect) at several
magnitudes (``--scales`` times the case's coefficient), seen by cameras of several marker
counts and noise levels (markers equally spaced from 0.1 L0 to L0, no base marker), each run
through the whole workflow. Per record: the verdict, the names, the false discoveries (names
neither hidden nor a listed indistinguishable alternative of a hidden one) and whether the
answer is right (the hidden effect named, or below the limit ``none``/``unexplained``: never
a wrong name). Writes

- ``--out`` (default ``results/tables/discovery_detectability.csv``): one row per record;
- ``--limits`` (default ``results/tables/discovery_detectability_limits.csv``): per effect,
  marker count and noise, the smallest coefficient named with every larger one named too
  (empty if none), and the false-discovery count.

    python benchmarks/discovery_detectability.py [--config config.yaml]
        [--effects tip_mass stiffness_scale rest_curvature] [--scales 0.1 0.3 1]
        [--markers 6 12] [--noise-mm 1 2] [--duration-s 1.0]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.commands.discovery import case_seed, run_discovery
from crgpr.commands.smk import limit_threads
from crgpr.config import load_config, rod_params
from crgpr.discovery.synthetic import make_measured
from crgpr.io import write_csv, write_parquet


def _one_effect_case(cases: list[dict], effect: str) -> dict:
    for c in cases:
        if set(c.get("effects", {})) == {effect} and "camera" not in c and "disturbance" not in c:
            return c
    raise SystemExit(f"--effects: no one-effect case of {effect!r} in discovery.cases")


def limits(df: pd.DataFrame) -> pd.DataFrame:
    """Smallest coefficient named with every larger one named, per effect, markers and noise."""
    rows = []
    for (eff, m, nz), g in df.groupby(["effect", "markers", "noise_mm"]):
        g = g.sort_values("coefficient")
        ok = g["named_right"].to_numpy()
        # the smallest coefficient from which on every larger one is named
        tail = np.flatnonzero(~ok)
        first = 0 if tail.size == 0 else tail[-1] + 1
        lim = float(g["coefficient"].iloc[first]) if first < len(g) else None
        rows.append({"effect": eff, "markers": m, "noise_mm": nz, "smallest_named": lim,
                     "records": len(g), "false_discoveries": int(g["false_discoveries"].sum()),
                     "wrong_answers": int((~g["right"]).sum())})
    return pd.DataFrame(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--effects", nargs="+", default=["tip_mass", "stiffness_scale", "rest_curvature"])
    ap.add_argument("--scales", nargs="+", type=float, default=[0.1, 0.3, 1.0])
    ap.add_argument("--markers", nargs="+", type=int, default=[6, 12])
    ap.add_argument("--noise-mm", nargs="+", type=float, default=[1.0, 2.0])
    ap.add_argument("--duration-s", type=float, default=1.0)
    ap.add_argument("--out", default="results/tables/discovery_detectability.csv")
    ap.add_argument("--limits", default="results/tables/discovery_detectability_limits.csv")
    args = ap.parse_args()
    limit_threads()
    cfg = load_config(args.config)
    d = cfg["discovery"]
    rod = rod_params(cfg)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for eff in args.effects:
            base = _one_effect_case(d["cases"], eff)
            for m in args.markers:
                markers = np.round(np.linspace(0.1, 1.0, m) * rod.L0, 4).tolist()
                for nz in args.noise_mm:
                    for k in args.scales:
                        coef = float(base["effects"][eff]) * k
                        name = f"{eff}_{m}m_{nz:g}mm_x{k:g}"
                        case = {"name": name, "effects": {eff: coef},
                                "camera": {"markers_s": markers, "noise_std_m": nz * 1e-3,
                                           "duration_s": args.duration_s}}
                        frame, truth = make_measured(rod, d, json.loads(json.dumps(case)),
                                                     case_seed(cfg["seed"], name))
                        path = Path(tmp) / f"{name}.parquet"
                        write_parquet(frame, path)
                        res = run_discovery(path, Path(tmp) / name, rod, cfg["simulation"]["dt_s"], d,
                                            cfg["seed"])
                        named = [e["name"] for e in res["effects"]]
                        alts = {a["named"]: a["alternative"] for a in res["indistinguishable_alternatives"]}
                        false = [n for n in named if n != eff and alts.get(n) != eff]
                        named_right = eff in named or alts.get(named[0] if named else "") == eff
                        right = not false and (named_right or res["verdict"] in ("none", "unexplained"))
                        rows.append({"effect": eff, "coefficient": coef, "scale": k, "markers": m,
                                     "noise_mm": nz, "effect_size_rad": truth["effect_size_rmse_theta_rad"],
                                     "verdict": res["verdict"], "named": ";".join(named) or "none",
                                     "false_discoveries": len(false), "named_right": bool(named_right),
                                     "right": bool(right), "gap_before_rad": res["gap_before"],
                                     "gap_floor_rad": res["gap_floor"]})
                        print(rows[-1], flush=True)
    df = pd.DataFrame(rows)
    write_csv(df, args.out)
    write_csv(limits(df), args.limits)


if __name__ == "__main__":
    main()
