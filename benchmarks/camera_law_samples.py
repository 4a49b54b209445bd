"""Where a bending law learned from camera positions goes wrong: its training samples, binned.

Rebuilds the state of a camera record exactly as ``crgpr learn`` does (config ``camera.learn``,
``--n-t-out`` frames), takes the bending law's samples (curvature input, moment target;
``gradient_models.training_data``, every segment but the tip) and compares them, per bin of
|rebuilt curvature|, with the ground truth at the same frames: the rebuilt curvature over the
true one, and the moment target over the true law at the true curvature and at the rebuilt one.
A target/true ratio near 1 at the true curvature and below 1 at the rebuilt one means the
input, not the target, is off. A materials-study case (``materials_study.cases``) or a case of
``benchmarks/materials_unseen.py`` (its ``--keep`` directory holds the records) gives the true
law. The state is rebuilt with the moment prior where ``crgpr learn`` uses it
(``learning.moment_prior``; each round's law is printed); ``--curvature-prior`` rebuilds it
with the curvature prior alone.

    python benchmarks/camera_law_samples.py results/materials/exponential/camera.parquet \\
        results/materials/exponential/train.parquet exponential --n-t-out 150
    python benchmarks/camera_law_samples.py KEEP/soft_saturating/camera.parquet \\
        KEEP/soft_saturating/train.parquet soft_saturating --curvature-prior
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.commands.learn import model_params
from crgpr.config import load_config, material_case_rod
from crgpr.learning import camera
from crgpr.learning.features import segments
from crgpr.learning.gradient_models import training_data
from crgpr.measured.records import ScreenSettings, read_measured, validate_frame
from crgpr.physics.rod import segment_moment_law

sys.path.insert(0, str(Path(__file__).resolve().parent))
from materials_unseen import CASES  # noqa: E402

BINS = ((0, 10), (10, 20), (20, 30), (30, 40), (40, 60), (60, 1000))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("camera")
    ap.add_argument("ground_truth")
    ap.add_argument("case")
    ap.add_argument("--n-t-out", type=int, default=None, help="training frames (default: the config's)")
    ap.add_argument("--config", default=str(Path(__file__).resolve().parents[1] / "config.yaml"))
    ap.add_argument("--curvature-prior", action="store_true",
                    help="no moment prior (camera.learn.moment_prior)")
    a = ap.parse_args()
    cfg = load_config(a.config)
    if a.case in CASES:
        cfg["materials_study"]["cases"][a.case] = CASES[a.case][0]
    truth = material_case_rod(cfg, a.case)
    st = camera.LearnSettings.from_config(cfg["camera"]["learn"])
    if a.n_t_out:
        st = camera.LearnSettings(**{**st.__dict__, "n_t_out": a.n_t_out})
    table = read_measured(a.camera)
    params = model_params(table, cfg)
    meas = validate_frame(table, a.camera, params.L0, params.ds, ScreenSettings.from_config(cfg["discovery"]))
    arr, rep = camera.positions_to_state(meas, params, "gp", st, int(cfg["seed"]) + 3000,
                                         moment_prior=not a.curvature_prior)
    for r in rep.get("moment_prior", []):
        print(f"moment prior round: law degree {r['degree']}, used {r['used']}")
    X, m = training_data(arr, params, "obj_m", None, None)
    n_t, N = arr["x"].shape[0], params.N
    k_hat, m = X[:, 0].reshape(n_t, N)[:, :-1], m.reshape(n_t, N)[:, :-1]
    g = pd.read_parquet(a.ground_truth).sort_values(["t", "node"])
    t = np.unique(g["t"].to_numpy())
    n = int(g["node"].max()) + 1
    q = {c: g[c].to_numpy().reshape(t.size, n) for c in ("x", "y", "theta")}
    idx = np.searchsorted(t, arr["t"] - 1e-9)
    k_true = segments(q["x"][idx], q["y"][idx], q["theta"][idx], params.ds)["kappa"][:, :-1]

    def law(k: np.ndarray) -> np.ndarray:
        return np.stack([segment_moment_law(truth, k[:, j])[:, j] for j in range(k.shape[1])], axis=1)

    at_true, at_hat = law(k_true), law(k_hat)
    print(f"{a.case}: {n_t} frames x {N - 1} segments; rms(kappa^ - kappa) "
          f"{np.sqrt(np.mean((k_hat - k_true) ** 2)):.3f} /m")
    print("|kappa^| [1/m]  samples  kappa^/kappa  target/law(kappa)  target/law(kappa^)")
    for lo, hi in BINS:
        s = (np.abs(k_hat) >= lo) & (np.abs(k_hat) < hi)
        if s.any():
            print(f"{lo:5d}-{hi:<5d} {int(s.sum()):9d} {np.median(k_hat[s] / k_true[s]):13.3f} "
                  f"{np.median(m[s] / at_true[s]):18.3f} {np.median(m[s] / at_hat[s]):19.3f}")


if __name__ == "__main__":
    main()
