"""Benchmark: how much of a local defect's smear along s is the curvature prior's.

    python benchmarks/defect_moment_weights.py KEEP_DIR/defect

``KEEP_DIR`` is the ``--keep`` directory of ``benchmarks/materials_unseen.py``. The camera
record of a rod whose bending stiffness varies along s is rebuilt twice as ``crgpr learn``
rebuilds it (config ``camera.learn``, the materials study's ``camera_n_t_out`` frames): with the
curvature prior (``measured.kinematics.clamped_angle_fit``), and with the prior on the moment
weighted by the TRUE stiffness of each segment (``weighted_angle_fit``, weights EI_j / EI,
centre 0: the rod's law is linear). For every segment it prints the least-squares slope of the
bending samples (moment target against rebuilt curvature, with an intercept) over EI, beside
the true EI_j / EI. The second rebuild is not something ``crgpr learn`` can do (the weights are
the unknown); it bounds what a better prior along s could give.

``--iterate K`` then tries to estimate those weights from the data: K rounds, each rebuilding
with the previous round's per-segment slopes as the weights (normalised by their median; the
last three segments, whose curvature the record does not resolve, take the fourth-last's), and
prints each round's slopes and their rms error against the true EI_j / EI over the resolved
segments.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.commands.learn import model_params
from crgpr.commands.materials import learn_config
from crgpr.config import load_config, material_case_rod
from crgpr.learning import camera
from crgpr.learning.gradient_models import training_data
from crgpr.measured.kinematics import smooth_kinematics
from crgpr.measured.records import ScreenSettings, read_measured, validate_frame
from crgpr.physics.rod import segment_moment_law

sys.path.insert(0, str(Path(__file__).resolve().parent))
from materials_unseen import CASES  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("case_dir", type=Path)
    ap.add_argument("--config", default=str(Path(__file__).resolve().parents[1] / "config.yaml"))
    ap.add_argument("--iterate", type=int, default=0, metavar="K", help="rounds of estimated weights")
    a = ap.parse_args()
    case = a.case_dir.name
    cfg = load_config(a.config)
    if case in CASES:
        cfg["materials_study"]["cases"][case] = CASES[case][0]
    truth = material_case_rod(cfg, case)
    lc = learn_config(cfg, "camera")
    st = camera.LearnSettings.from_config(lc["camera"]["learn"])
    table = read_measured(a.case_dir / "camera.parquet")
    params = model_params(table, lc)
    meas = validate_frame(table, str(a.case_dir / "camera.parquet"), params.L0, params.ds,
                          ScreenSettings.from_config(lc["discovery"]))
    m1 = segment_moment_law(truth, np.array([-1.0, 1.0]))
    true_ei = (m1[1] - m1[0]) / 2.0 / params.EI  # (N,) each segment's EI over the nominal

    def slopes(weights: np.ndarray | None) -> np.ndarray:
        per_frame = None if weights is None else (np.broadcast_to(weights, (meas.t.size, params.N)), 0.0)
        kin = smooth_kinematics(meas, params, seed=int(cfg["seed"]) + 3000, max_points=st.gp_max_points,
                                hyper_points=st.hyper_points, clamp_order=st.angle_penalty_order,
                                moment_weights=per_frame)
        kin = camera.clamp_base(kin)
        arr = camera.state_arrays(kin, params, camera.kept_frames(kin.t, st.edge_trim_s, st.n_t_out))
        X, m = training_data(arr, params, "obj_m", None)
        k, m = X[:, 0].reshape(-1, params.N), m.reshape(-1, params.N)
        return np.array([np.linalg.lstsq(np.c_[k[:, j], np.ones(k.shape[0])], m[:, j], rcond=None)[0][0]
                         for j in range(params.N)]) / params.EI

    out = pd.DataFrame({"segment": np.arange(params.N), "s_over_L": (np.arange(params.N) + 0.5) / params.N,
                        "true_EI": true_ei, "curvature_prior": slopes(None),
                        "moment_prior_true_EI": slopes(true_ei)})
    print(out.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    slope = out["curvature_prior"].to_numpy()
    resolved = slice(0, params.N - 3)
    err0 = float(np.sqrt(np.mean((slope[resolved] - true_ei[resolved]) ** 2)))
    print(f"round 0 (curvature prior): rms slope error {err0:.4f}")
    for k in range(1, a.iterate + 1):
        w = slope.copy()
        w[-3:] = w[-4]
        w = np.clip(w, 0.05, None)
        slope = slopes(w / np.median(w))
        err = float(np.sqrt(np.mean((slope[resolved] - true_ei[resolved]) ** 2)))
        print(f"round {k}: rms slope error {err:.4f}; slopes", np.array2string(slope, precision=3))


if __name__ == "__main__":
    main()
