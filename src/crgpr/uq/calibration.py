"""Function-level calibration of the gradient GPs where the test rollouts go (a diagnostic of
the trajectory bands; paper Sec. III-B steps 3-4).

At ground-truth states of the test angles the analytic rod gives the exact value of every
gradient-GP target (``true_targets``: the same H_z -> target maps as training, features.py).
z = (truth - rollout mean) / posterior sd with the sampler's predictive sd (DTC on the rollout's
inducing inputs for the multi-input GPs, exact for the 1D momentum GPs); a calibrated GP has
|z| < 1.96 for 95 % of the points. A trajectory band cannot cover the truth when the functions'
bands do not, whatever S and D. Nothing is fitted to this table.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.gp.sampling import exact_posterior, se_kernel, sparse_posterior
from crgpr.learning import features as ft
from crgpr.learning.gradient_models import MOMENTUM_MODELS
from crgpr.physics.params import RodParams
from crgpr.physics.rod import internal_forces, node_weights
from crgpr.uq.samples import load_gp_spec

log = logging.getLogger(__name__)


def true_targets(q: np.ndarray, p: np.ndarray, params: RodParams) -> dict[str, np.ndarray]:
    """The analytic rod's value of every gradient-GP target at states q, p (n_t, N+1, 3).

    H_q = -F / (w ds) from the rod's nodal forces, H_p = p / mass per length; then the training
    maps (features.py): q_x, q_y (segments), dH_dtheta (nodes 1..N), obj_n1, obj_n2 (q rotated
    into the segment frame), obj_m (moment balance), dH_dp_* (nodes 1..N)."""
    wds = node_weights(params.N) * params.ds
    F = np.array([internal_forces(qq, params, float(q[0, 0, 2]))[0] for qq in q])
    hq = -F / wds[:, None]
    qx, qy = ft.q_from_hz(hq[..., 0], params), ft.q_from_hz(hq[..., 1], params)
    sg = ft.segments(q[..., 0], q[..., 1], q[..., 2], params.ds)
    n1 = qx * sg["cos"] + qy * sg["sin"]
    n2 = -qx * sg["sin"] + qy * sg["cos"]
    c = sg["nu1"] * n2 - sg["nu2"] * n1
    return {"q_x": qx, "q_y": qy, "dH_dtheta": hq[:, 1:, 2],
            "obj_n1": n1, "obj_n2": n2, "obj_m": ft.moments_from_htheta(hq[..., 2], c, params),
            "dH_dp_x": p[:, 1:, 0] / params.rhoA, "dH_dp_y": p[:, 1:, 1] / params.rhoA,
            "dH_dp_theta": p[:, 1:, 2] / params.rhoI}


def model_features(q: np.ndarray, p: np.ndarray, params: RodParams, center: float | None
                   ) -> dict[str, np.ndarray]:
    """Inputs of every gradient GP at states q, p (n_t, N+1, 3), as in the rollout."""
    x, y, th = q[..., 0], q[..., 1], q[..., 2]
    feats = {"q_x": ft.paper_q_features(x, y, th, params.ds, center),
             "dH_dtheta": ft.paper_theta_features(x, y, th, params.ds, center),
             "obj_n1": ft.objective_n_features(x, y, th, params.ds),
             "obj_m": ft.objective_m_features(x, y, th, params.ds)}
    feats["q_y"], feats["obj_n2"] = feats["q_x"], feats["obj_n1"]
    for j, m in enumerate(MOMENTUM_MODELS):
        feats[m] = p[:, 1:, j:j + 1]
    return feats


def function_calibration(model_stems: Mapping[str, str | Path], trajectories: Mapping[int, tuple],
                         params: RodParams, center: float | None, n_times: int = 200) -> pd.DataFrame:
    """One row per (angle, model): coverage of the 95 % predictive interval of the gradient GP
    (|z| < 1.96), median |z|, RMSE of the rollout's mean, median predictive sd, target std.

    ``trajectories``: angle -> (q, p) ground-truth arrays (n_t, N+1, 3); ``n_times`` evenly
    spaced times per angle (t > 0) are used."""
    preds = {}
    for m, stem in model_stems.items():
        spec, Z, _ = load_gp_spec(stem, m)
        preds[m] = (spec, sparse_posterior(spec, Z) if Z is not None else exact_posterior(spec))
    rows = []
    for angle, (q_all, p_all) in sorted(trajectories.items()):
        k = np.unique(np.linspace(1, len(q_all) - 1, n_times).round().astype(int))
        q, p = q_all[k], p_all[k]
        feats = model_features(q, p, params, center)
        truth = true_targets(q, p, params)
        for m, (spec, post) in preds.items():
            X = feats[m].reshape(-1, feats[m].shape[-1])
            mean, var = post.mean_var(X)
            ra = getattr(spec, "rollout_arrays", {})
            if "dtc_w" in ra:  # the centre is the rollout's mean model
                xs = spec.standardise(X)
                mean = spec.to_output(se_kernel(xs, ra["dtc_Z"], spec.sigma_f, spec.ell)
                                      @ np.ravel(ra["dtc_w"]) + spec.basis_fn(xs) @ np.ravel(ra["dtc_beta"]))
            sd = np.sqrt(np.maximum(var, 1e-300))
            err = truth[m].reshape(-1) - mean
            z = err / sd
            rows.append({"theta0_deg": angle, "model": m, "n_points": int(z.size),
                         "coverage_95": float(np.mean(np.abs(z) < 1.959964)),
                         "median_abs_z": float(np.median(np.abs(z))),
                         "rmse": float(np.sqrt(np.mean(err**2))),
                         "median_sd": float(np.median(sd)),
                         "sigma_n": float(spec.sigma_n * spec.out_scale),
                         "target_std": float(np.std(truth[m]))})
    df = pd.DataFrame(rows)
    log.info("function-level calibration:\n%s", df.to_string())
    return df
