"""Benchmark: one `crgpr discover` run on a 2 s camera record (target <= 3 min on 2 cores).

The record is the config's ``camera_tip_mass`` case stretched to 2 s (6 markers at arbitrary
s, mid-motion start, 2 mm noise at 200 Hz, drops, occlusions, outliers) plus the plain
``tip_mass`` case at the config's camera (every node, 250 Hz, 1 mm) for 2 s. Writes
``benchmarks/discovery_2s.tsv`` (case, seconds, verdict, named effects).

    python benchmarks/discovery_2s.py [--config config.yaml] [--cases tip_mass camera_tip_mass]
"""

from __future__ import annotations

import argparse
import json
import resource
import tempfile
import time
from pathlib import Path

import pandas as pd

from crgpr.commands.discovery import case_seed, run_discovery
from crgpr.commands.smk import limit_threads
from crgpr.config import load_config, rod_params
from crgpr.discovery.synthetic import find_case, make_measured
from crgpr.io import write_csv, write_parquet


def _cpu() -> float:
    """User + system CPU seconds of this process."""
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--cases", nargs="+", default=["tip_mass", "camera_tip_mass"])
    ap.add_argument("--out", default="benchmarks/discovery_2s.tsv")
    args = ap.parse_args()
    limit_threads()
    cfg = load_config(args.config)
    d = cfg["discovery"]
    rod = rod_params(cfg)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.cases:
            case = json.loads(json.dumps(find_case(d["cases"], name)))
            case.setdefault("camera", {})["duration_s"] = 2.0
            frame, _ = make_measured(rod, d, case, case_seed(cfg["seed"], name))
            path = Path(tmp) / f"{name}.parquet"
            write_parquet(frame, path)
            t0, c0 = time.perf_counter(), _cpu()
            res = run_discovery(path, Path(tmp) / name, rod, cfg["simulation"]["dt_s"], d, cfg["seed"])
            sec, cpu = time.perf_counter() - t0, _cpu() - c0
            rows.append({"case": name, "record_s": 2.0, "frames": res["n_samples"],
                         "markers": res["input"]["n_markers"], "seconds": round(sec, 1),
                         "cpu_s": round(cpu, 1),
                         "verdict": res["verdict"], "named": ";".join(e["name"] for e in res["effects"])})
            print(rows[-1], flush=True)
    write_csv(pd.DataFrame(rows), args.out, sep="\t")


if __name__ == "__main__":
    main()
