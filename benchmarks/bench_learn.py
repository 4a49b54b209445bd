"""Benchmark: one ``crgpr learn`` on a 2 s, 250 Hz, 26-node camera record (target 2 min).

    python benchmarks/bench_learn.py [--features objective] [--prefilter gp] [--noise-mm 1]
        [--config config.yaml] [--t-end 2.0] [--seed 0]

Simulates the 85 deg trajectory with the config, keeps positions only at 250 Hz with Gaussian
noise (seeded), writes it to a temporary Parquet file and times ``crgpr.commands.learn.learn``
(wall and process CPU time; on a shared machine the CPU time is the figure to compare), and
the record fit's share (the manifest's ``record_fit.seconds``).
The workflow's own figure is the Snakemake benchmark file
``benchmarks/camera/learn_main_1mm_gp_objective.tsv``. With ``--config tests/smoke_config.yaml
--t-end 0.4 --seed 5`` it is the camera learn of the test suite's smoke fixtures
(``tests/test_camera_nominal.py``, the laws chosen by the data).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from crgpr.commands.camera import camera_frame
from crgpr.commands.learn import learn
from crgpr.config import load_config, rod_params
from crgpr.io import write_parquet
from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import simulate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--features", default="objective", choices=("objective", "paper"))
    ap.add_argument("--prefilter", default="gp", choices=("gp", "fd"))
    ap.add_argument("--noise-mm", type=float, default=1.0)
    ap.add_argument("--t-end", type=float, default=2.0, help="record length [s]")
    ap.add_argument("--seed", type=int, default=0, help="seed of the position noise")
    args = ap.parse_args()
    cfg = load_config(args.config)
    tr = simulate(85.0, rod_params(cfg), SimSettings(dt=1e-4, t_end=args.t_end, record_every=40,
                                                     scheme=cfg["simulation"]["scheme"]))
    df = camera_frame(tr.t, tr.q, args.noise_mm * 1e-3, np.random.default_rng(args.seed))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "camera.parquet"
        write_parquet(df, path)
        w0, c0 = time.perf_counter(), time.process_time()
        man = learn(path, Path(d) / "models", cfg, args.features, args.prefilter)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    print(f"crgpr learn ({args.features}, {args.prefilter}, {args.noise_mm:g} mm, {len(tr.t)} frames x "
          f"{tr.q.shape[1]} nodes): wall {wall:.1f} s, CPU {cpu:.1f} s, record fit "
          f"{(man.get('record_fit') or {}).get('seconds', float('nan')):.1f} s; estimated noise "
          f"{(man['state']['noise_std_m_estimated'] or float('nan')) * 1e3:.3g} mm")


if __name__ == "__main__":
    main()
