"""Speed: CPU cost of one sampled (UQ) rollout, by function (cProfile).

Loads the stored posterior samples of a method (``results/uq/<method>/samples/*.npz``, made by
the ``uq_samples`` rule), integrates the S sampled rods for ``n_steps`` steps of the config's dt
(``crgpr.uq.rollout.rollout_samples``, the rule's own code) and prints the process CPU time per
step, its extrapolation to the full rollout (simulation.t_end_s) and the top functions.

    python benchmarks/uq_rollout_cost.py cr_gpr_objective 125 2000 [kernel_tol]

``kernel_tol`` (default: the config's ``uq.kernel_tol``): truncation of the sampled kernel sums.
"""

from __future__ import annotations

import cProfile
import pstats
import sys
import time
from pathlib import Path

from crgpr.config import load_config, rod_params
from crgpr.learning.gradient_models import MOMENTUM_MODELS
from crgpr.learning.learned import OBJECTIVE_COMPONENTS, PAPER_COMPONENTS
from crgpr.physics.params import SimSettings


def main() -> None:
    method, angle, n_steps = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
    cfg = load_config("config.yaml")
    mcfg = cfg["rollouts"]["methods"][method]
    names = (*(PAPER_COMPONENTS if mcfg["features"] == "paper" else OBJECTIVE_COMPONENTS), *MOMENTUM_MODELS)
    from crgpr.commands.uq import theta_center
    from crgpr.learning.learned import model_dir_name
    from crgpr.uq.rollout import rollout_samples
    from crgpr.uq.samples import load_samples

    tol = float(sys.argv[4]) if len(sys.argv) > 4 else float(cfg["uq"]["kernel_tol"])
    smp = load_samples({m: Path(f"results/uq/{method}/samples/{m}.npz") for m in names}, tol)
    mdir = Path("results/models") / model_dir_name(mcfg)
    center = theta_center([mdir / f"{m}.json" for m in names], mcfg["features"])
    P = rod_params(cfg)
    sim = cfg["simulation"]
    dt = float(sim["dt_s"])
    full = int(round(float(sim["t_end_s"]) / dt))
    st = SimSettings(dt=dt, t_end=n_steps * dt, record_every=int(sim["record_every"]),
                     scheme=str(sim["scheme"]))
    rollout_samples(smp, mcfg["features"], P, center, angle,
                    SimSettings(dt=dt, t_end=20 * dt, record_every=1, scheme=st.scheme))  # compile / warm up
    prof = cProfile.Profile()
    c0, w0 = time.process_time(), time.perf_counter()
    prof.enable()
    res = rollout_samples(smp, mcfg["features"], P, center, angle, st)
    prof.disable()
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    S = next(iter(smp.values())).n_samples
    print(f"{method} {angle:g} deg, S = {S}, kernel_tol {tol:g}, {n_steps} steps: "
          f"CPU {cpu:.2f} s ({1e3 * cpu / n_steps:.3f} ms/step), "
          f"wall {wall:.2f} s; full rollout ({full} steps) ~ {cpu * full / n_steps:.0f} s CPU")
    pstats.Stats(prof).sort_stats("tottime").print_stats(14)
    if tol > 0:  # the truncated sums against the dense ones, same samples and steps
        dense = load_samples({m: Path(f"results/uq/{method}/samples/{m}.npz") for m in names})
        c1 = time.process_time()
        ref = rollout_samples(dense, mcfg["features"], P, center, angle, st)
        print(f"dense sums: CPU {time.process_time() - c1:.2f} s; max |q_truncated - q_dense| = "
              f"{float(abs(res[1] - ref[1]).max()):.3g} (max |q| {float(abs(ref[1]).max()):.3g})")


if __name__ == "__main__":
    main()
