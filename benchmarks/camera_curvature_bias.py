"""How well `crgpr learn`'s state reconstruction recovers the curvature.

Makes the camera record of a ground-truth file exactly as rule ``camera_data`` does (the
config's frame rate and seed), rebuilds the state with ``learning.camera.positions_to_state``
(config ``camera.learn``; ``--order`` overrides ``angle_penalty_order``, ``none`` runs the
unclamped smoother of the discovery workflow, without the clamp-angle penalty; ``--lam-factor``
fixes the smoothing weight instead of GCV) and prints the
clamp-angle error, per segment the least-squares slope of the rebuilt curvature against the
simulator's (through the origin), its rms error and the fit's own noise estimate.

    python benchmarks/camera_curvature_bias.py results/ground_truth/85.parquet --noise-mm 1 --order 4
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.commands.camera import camera_data
from crgpr.commands.learn import model_params
from crgpr.config import load_config
from crgpr.learning import camera
from crgpr.learning.features import segments
from crgpr.measured.kinematics import smooth_kinematics
from crgpr.measured.records import ScreenSettings, read_measured, validate_frame


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("ground_truth")
    ap.add_argument("--noise-mm", type=float, default=1.0)
    ap.add_argument("--order", default=None, help="2, 3, 4 or none (default: the config's)")
    ap.add_argument("--lam-factor", type=float, default=None,
                    help="fix the clamped fit's smoothing weight at this x its scale instead of GCV")
    ap.add_argument("--config", default=str(Path(__file__).resolve().parents[1] / "config.yaml"))
    a = ap.parse_args()
    cfg = load_config(a.config)
    st = camera.LearnSettings.from_config(cfg["camera"]["learn"])
    if a.order not in (None, "none"):
        st = camera.LearnSettings(**{**st.__dict__, "angle_penalty_order": int(a.order)})
    if a.lam_factor is not None:  # a fixed smoothing weight: the bias at that weight, without GCV
        from crgpr.measured import kinematics as kin

        kin._gcv_lambda = lambda scale, fit: a.lam_factor * scale
    if a.order == "none":  # the unclamped smoother (segment angles, ends extrapolated)
        camera.gp_kinematics = lambda meas, params, s, seed: smooth_kinematics(
            meas, params, seed=seed, max_points=s.gp_max_points, hyper_points=s.hyper_points)
    with tempfile.TemporaryDirectory() as tmp:
        rec = Path(tmp) / "camera.parquet"
        rate = cfg["camera"]["data"]["sample_rate_hz"]
        camera_data(a.ground_truth, str(rec), a.noise_mm, rate, cfg["seed"])
        table = read_measured(rec)
        params = model_params(table, cfg)
        screen = ScreenSettings.from_config(cfg["discovery"])
        meas = validate_frame(table, str(rec), params.L0, params.ds, screen)
        arr, rep = camera.positions_to_state(meas, params, "gp", st, int(cfg["seed"]) + 3000)
    g = pd.read_parquet(a.ground_truth).sort_values(["t", "node"])
    t = np.unique(g["t"].to_numpy())
    n = int(g["node"].max()) + 1
    q = {c: g[c].to_numpy().reshape(t.size, n) for c in ("x", "y", "theta")}
    idx = np.searchsorted(t, arr["t"] - 1e-9)
    kt = segments(q["x"][idx], q["y"][idx], q["theta"][idx], params.ds)["kappa"]
    ke = segments(arr["x"], arr["y"], arr["theta"], params.ds)["kappa"]
    noise = rep.get("kappa_noise_per_segment") or [None] * params.N
    print(f"order {a.order or st.angle_penalty_order}, {a.noise_mm:g} mm: clamp angle error "
          f"{arr['theta'][0, 0] - q['theta'][0, 0]:+.4f} rad")
    print("segment  slope  rmse [1/m]  noise estimate [1/m]  rms kappa [1/m]")
    for j in range(params.N):
        sl = (ke[:, j] @ kt[:, j]) / (kt[:, j] @ kt[:, j])
        est = "-" if noise[j] is None else f"{noise[j]:.3f}"
        print(f"{j:7d} {sl:6.3f} {np.sqrt(np.mean((ke[:, j] - kt[:, j]) ** 2)):11.3f} {est:>21} "
              f"{np.sqrt(np.mean(kt[:, j] ** 2)):16.3f}")


if __name__ == "__main__":
    main()
