"""Diagnosis: which gradient GP's posterior makes a method's trajectory band wide.

The stored posterior samples of one component (or group) are rolled out with every other
component at its rollout mean (``LearnedRod`` with the mean evaluators of ``results/models``;
``crgpr.uq.rollout.rollout_samples``, the rule's own code); prints the theta band width and
coverage against the ground truth at the config's levels, per variant. Diagnostic only: the
truth is used to score, nothing is fitted to it.

    python benchmarks/uq_component_bands.py [--results DIR] [--t-end S] METHOD ANGLE all obj_m obj_n1 ...

A variant is ``all`` (every component sampled, the rule's band), ``none`` (all at the mean), a
component name, or several joined by '+' (e.g. ``dH_dp_x+dH_dp_y+dH_dp_theta``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from crgpr.commands.uq import theta_center
from crgpr.config import load_config, rod_params
from crgpr.gp.evaluators import KernelMean, load_model
from crgpr.io import read_parquet
from crgpr.learning.gradient_models import MOMENTUM_MODELS
from crgpr.learning.learned import OBJECTIVE_COMPONENTS, PAPER_COMPONENTS, LearnedRod, model_dir_name
from crgpr.physics.params import SimSettings
from crgpr.uq.coverage import _coverages, expected_coverage, truth_arrays
from crgpr.uq.rollout import rollout_samples
from crgpr.uq.samples import load_samples


class Broadcast:
    """A mean evaluator applied to inputs with a leading sample axis (same value for every s)."""

    def __init__(self, f, n_samples: int) -> None:
        self.f, self.n_samples = f, n_samples

    def __call__(self, X: np.ndarray) -> np.ndarray:
        return self.f(X)

    def slope(self, x: np.ndarray) -> np.ndarray:
        return self.f.slope(x)


def dtc_mean(stem: Path) -> KernelMean:
    """The DTC mean of a saved model (the mean its posterior samples are centred on)."""
    arr, meta = load_model(stem)
    return KernelMean(meta["kernel"], meta["basis"], float(meta["sigma_f_std"]), arr["lengthscales"],
                      arr["x_mean"], arr["x_scale"], float(np.ravel(arr["y_mean"])[0]),
                      float(np.ravel(arr["y_scale"])[0]), arr["dtc_Z"], arr["dtc_w"][:, 0],
                      arr["dtc_beta"][:, 0], kind="dtc")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--results", default="results")
    ap.add_argument("--t-end", type=float, default=None,
                    help="rollout length [s] (default: simulation.t_end_s)")
    ap.add_argument("method")
    ap.add_argument("angle", type=float)
    ap.add_argument("variants", nargs="+")
    a = ap.parse_args()
    cfg = load_config("config.yaml")
    res = Path(a.results)
    mcfg = cfg["rollouts"]["methods"][a.method]
    names = (*(PAPER_COMPONENTS if mcfg["features"] == "paper" else OBJECTIVE_COMPONENTS), *MOMENTUM_MODELS)
    kt = float(cfg["uq"]["kernel_tol"])
    smp = load_samples({m: res / f"uq/{a.method}/samples/{m}.npz" for m in names}, kt)
    mdir = res / "models" / model_dir_name(mcfg)
    mean = LearnedRod.from_dir(mdir, mcfg["features"], rod_params(cfg)).components
    mean.update({m: dtc_mean(mdir / m) for m in names if m not in MOMENTUM_MODELS})  # the samples' centre
    center = theta_center([mdir / f"{m}.json" for m in names], mcfg["features"])
    sim = cfg["simulation"]
    st = SimSettings(dt=float(sim["dt_s"]), t_end=float(a.t_end or sim["t_end_s"]),
                     record_every=int(sim["record_every"]), scheme=str(sim["scheme"]))
    gt = read_parquet(res / f"ground_truth/{int(a.angle)}.parquet")
    levels = [float(v) for v in cfg["uq"]["levels"]]
    S = next(iter(smp.values())).n_samples
    print(f"{a.method} {a.angle:g} deg, S = {S}, t_end {st.t_end:g} s; expected coverage "
          + " ".join(f"{expected_coverage(S, lv):.3f}" for lv in levels), flush=True)
    for var in a.variants:
        sampled = set(names) if var == "all" else (set() if var == "none" else set(var.split("+")))
        comps = {m: (smp[m] if m in sampled else Broadcast(mean[m], S)) for m in names}
        t0 = time.perf_counter()
        t, q, _, keep, div = rollout_samples(comps, mcfg["features"], rod_params(cfg), center, a.angle, st)
        g = truth_arrays(gt, t, ("x", "y", "theta"))
        cov = [_coverages(q, g, lv) for lv in levels]
        sd = float(np.mean(np.std(q[:, 1:, 1:, 2], axis=0)))
        print(f"{var:40s} theta coverage " + " ".join(f"{c['theta_coverage']:.3f}" for c in cov)
              + f" | 95% width {cov[-1]['theta_band_width_mean']:.2e} rad, mean sd {sd:.2e}, "
              f"median-sample rmse {cov[0]['theta_rmse_median']:.2e} | {len(div)} diverged "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
