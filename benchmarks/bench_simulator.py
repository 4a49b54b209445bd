"""Benchmark: compute time of one 2 s ground-truth trajectory in-process (target 0.3 s).

    python benchmarks/bench_simulator.py [--repeats 20]

Reports the JIT warm-up once, then min / median / max over repeated runs of
``crgpr.physics.simulate.simulate(85)`` with the paper's settings (dt = 1e-4 s, T = 2 s).
The whole ground-truth stage is measured by Snakemake's own benchmark files:
``snakemake -j2 --forcerun ground_truth all`` then ``benchmarks/ground_truth/*.tsv``.
"""

from __future__ import annotations

import argparse
import statistics
import time

from crgpr.config import load_config, rod_params, sim_settings
from crgpr.physics.simulate import simulate


def main() -> None:
    cfg = load_config("config.yaml")  # the paper's rod and time grid
    rod = rod_params(cfg)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=20)
    args = ap.parse_args()
    p, s = rod, sim_settings(cfg)
    t0 = time.perf_counter()
    simulate(85.0, p, s)
    warm = time.perf_counter() - t0
    times = []
    for _ in range(args.repeats):
        t0 = time.process_time()
        simulate(85.0, p, s)
        times.append(time.process_time() - t0)
    print(f"first call (JIT compile or cache load): {warm:.3f} s")
    print(f"one 2 s trajectory, {s.n_steps} steps, CPU time over {args.repeats} runs: "
          f"min {min(times):.4f} s, median {statistics.median(times):.4f} s, max {max(times):.4f} s")


if __name__ == "__main__":
    main()
