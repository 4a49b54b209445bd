"""Benchmark: wall time per step of a learned-rod rollout (``learning.learned.rollout``), one rod
and a batch of eight, for model directories of a complete run.

    python benchmarks/learned_rollout_step.py RESULTS [--out benchmarks/learned_rollout_step.csv]

RESULTS: the ``results/`` folder of a complete ``snakemake -j2 all``. Models: the materials
study's viscoelastic camera model (nominal laws, a linear momentum map, a learned bending
damping), its exponential camera model (a learned bending law, a linear momentum map) and its
exponential full-state model (a learned bending law, learned momentum maps), plus the pipeline's
camera model (learned momentum maps). Each is rolled out from the straight rod at 85 deg for
0.3 s (dt = 1e-4 s, every 10th step recorded) after a short warm-up; the figure is the median of
three runs. The records of the runs are checked for equality with the first (``same``), so the
figure is of one computation. In-process times of one function: no Snakemake, no I/O.
The committed ``benchmarks/learned_rollout_step.csv`` adds ``us_per_step_before``: this script
run on the same models, right before, with the code before the compiled momentum maps
(``physics.momentum_maps``, commit d2cf40d), and ``speedup`` = before / now.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.commands.learn import load_learned
from crgpr.learning.learned import rollout
from crgpr.physics.params import SimSettings

MODELS = ("materials/viscoelastic/models/camera", "materials/exponential/models/camera",
          "materials/exponential/models/full_state", "camera/models/main/1mm_gp_objective")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", type=Path)
    ap.add_argument("--out", type=Path, default=Path("benchmarks/learned_rollout_step.csv"))
    args = ap.parse_args()
    st = SimSettings(dt=1e-4, t_end=0.3, record_every=10, scheme="variational")
    warm = SimSettings(dt=1e-4, t_end=0.002, record_every=10, scheme="variational")
    rows = []
    for rel in MODELS:
        rod, _ = load_learned(args.results / rel)
        for batch in (None, 8):
            rollout(rod, 85.0, warm, n_batch=batch)
            times, first, same = [], None, True
            for _ in range(3):
                t0 = time.perf_counter()
                tr = rollout(rod, 85.0, st, n_batch=batch)
                times.append(time.perf_counter() - t0)
                first = tr.q if first is None else first
                same = same and bool(np.array_equal(first, tr.q))
            us = statistics.median(times) / st.n_steps * 1e6
            rows.append({"model": rel, "batch": 1 if batch is None else batch,
                         "us_per_step": round(us, 1), "same": same})
            print(f"{rel:45s} batch {rows[-1]['batch']}: {us:7.1f} us/step")
    pd.DataFrame(rows).to_csv(args.out, index=False)


if __name__ == "__main__":
    main()
