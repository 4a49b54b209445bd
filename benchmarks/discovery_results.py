"""The full result of ``crgpr.discovery.discover`` on small synthetic records, as JSON files that
two code versions can be compared by, byte for byte (a refactoring must leave them equal).

    python benchmarks/discovery_results.py OUT_DIR [CASE ...]

Each CASE (a name in config.yaml's ``discovery.cases``; default: tip_mass, none,
tip_mass_and_drag, camera_tip_mass) is recorded with the rod, settings and seed of
tests/smoke_config.yaml (0.4 s at 250 Hz), written to OUT_DIR/CASE.parquet, loaded and
discovered; OUT_DIR/CASE.json holds the result dict without its timings, keys sorted, with
SHA-256 digests of the arrays the figures are drawn from (kinematics, nominal and augmented
trajectories, marker matrix). One BLAS thread, as the rules run.
"""

from __future__ import annotations

import argparse
import hashlib
import json
from pathlib import Path

import numpy as np

from crgpr.commands.discovery import case_seed, discovery_seed
from crgpr.commands.smk import limit_threads
from crgpr.config import load_config, rod_params
from crgpr.discovery import DiscoverySettings, discover
from crgpr.discovery.synthetic import find_case, make_measured
from crgpr.io import write_parquet
from crgpr.measured import ScreenSettings, load_measured

ROOT = Path(__file__).resolve().parents[1]
CASES = ("tip_mass", "none", "tip_mass_and_drag", "camera_tip_mass")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out_dir")
    ap.add_argument("cases", nargs="*", default=list(CASES))
    a = ap.parse_args()
    limit_threads()
    out = Path(a.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    smoke = load_config(ROOT / "tests" / "smoke_config.yaml")
    cases = load_config(ROOT / "config.yaml")["discovery"]["cases"]
    rod, d = rod_params(smoke), smoke["discovery"]
    st = DiscoverySettings.from_config(d, discovery_seed(smoke["seed"]))
    for name in a.cases:
        frame, _ = make_measured(rod, d, find_case(cases, name), case_seed(smoke["seed"], name))
        write_parquet(frame, out / f"{name}.parquet")
        meas = load_measured(out / f"{name}.parquet", rod.L0, rod.ds, ScreenSettings.from_config(d))
        res = discover(meas, rod, float(smoke["simulation"]["dt_s"]), st)
        result = {k: v for k, v in res["result"].items() if k != "timing_s"}
        result["measured"] = name
        arr = res["arrays"]
        result["array_sha256"] = {
            k: hashlib.sha256(np.ascontiguousarray(v).tobytes()).hexdigest()
            for k, v in (("kin_q", arr["kin"].q), ("kin_v", arr["kin"].v), ("kin_a", arr["kin"].a),
                         ("q_nom", arr["q_nom"]), ("q_aug", arr["q_aug"]), ("M", arr["M"]))}
        (out / f"{name}.json").write_text(json.dumps(result, indent=1, sort_keys=True) + "\n")
        print(f"{name}: {result['verdict']} {[e['name'] for e in result['effects']]}")


if __name__ == "__main__":
    main()
