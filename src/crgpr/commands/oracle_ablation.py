"""Rule ``oracle_ablation``: which learned component breaks the paper's CR-GPR?

Variants of the paper's model (features 'paper', Sec. III-B step 3, GPR 1-6), each rolled out
by ``learned.LearnedRod`` + ``integrator.run_hamiltonian`` on every test angle:
* ``all_oracle``: every component is its oracle (``learning.oracle``: the constitutive law
  written in the same features);
* ``learned_<c>``: component ``c`` is the fitted GP as the ``cr_gpr`` rollout evaluates it
  (``gp.load_evaluator``: the model's saved rollout mean, exact or DTC), the other five are oracles;
* ``all_learned``: the six fitted GPs, i.e. the ``cr_gpr`` model: its rollouts (rule
  ``rollout``) are scored here, not integrated a second time.
The angles of one variant are integrated as one batch (leading batch axis; a batch that
diverges is rerun angle by angle and the diverged angles are recorded with NaN metrics).
Whether the learned components are the exact posterior means or an approximation is the
models' ``rollout_mean`` (its error against the exact mean: ``table2_hyperparameters.csv``).

Pointwise table: on the ground-truth training trajectory (exact simulator states), the RMS
error of each oracle and of each learned component against the true discrete H_z
(``rod.variational_derivative``; q_x, q_y as tip-to-base sums), next to the target's std.
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.config import rod_params, sim_settings
from crgpr.gp import load_evaluator
from crgpr.io import read_metadata, read_parquet, write_csv
from crgpr.learning import features as ft
from crgpr.learning.learned import LearnedRod
from crgpr.learning.oracle import ORACLE_COMPONENTS, mixed_components, oracle_components
from crgpr.physics.integrator import SimulationDiverged, run_hamiltonian
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.rod import free_mask, straight_rod, variational_derivative
from crgpr.physics.simulate import Trajectory, trajectory_frame, trajectory_from_frame
from crgpr.report.figures import oracle_ablation_figure
from crgpr.report.metrics import accuracy

log = logging.getLogger(__name__)


def variants() -> dict[str, tuple[str, ...]]:
    """Variant name -> names of the LEARNED components (the rest are oracles); ``all_learned`` aside."""
    out: dict[str, tuple[str, ...]] = {"all_oracle": ()}
    out.update({f"learned_{c}": (c,) for c in ORACLE_COMPONENTS})
    return out


class Flat:
    """Evaluate a 2-D-only component on feature arrays with leading batch axes."""

    def __init__(self, comp: Any):
        self.comp = comp
        if hasattr(comp, "slope"):
            self.slope = comp.slope

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        if X.ndim <= 2:
            return self.comp(X)
        return np.asarray(self.comp(X.reshape(-1, X.shape[-1]))).reshape(X.shape[:-1])


def _rollout_batch(model: LearnedRod, angles: list[float], settings: SimSettings) -> list[Trajectory]:
    P = model.params
    q0 = np.stack([straight_rod(math.radians(a), P) for a in angles])
    out = run_hamiltonian(q0, np.zeros_like(q0), model.force, model.velocity, free_mask(P), P.zeta,
                          settings.dt, settings.n_steps, settings.record_every, model.wds,
                          f"oracle ablation at {angles} deg", velocity_slope=model.velocity_slope)
    return [Trajectory(float(a), out.t, out.q[:, b], out.v[:, b], P) for b, a in enumerate(angles)]


def pointwise_errors(gt_train: Trajectory, params: RodParams, learned: dict[str, Any],
                     center: float | None, theta_closure: str) -> pd.DataFrame:
    """RMS error of each oracle and learned component against the true discrete H_z."""
    P = params
    q, p = gt_train.q[1:], gt_train.p[1:]  # t > 0
    hz = np.array([variational_derivative(a, b, P) for a, b in zip(q, p, strict=True)])
    x, y, th = q[..., 0], q[..., 1], q[..., 2]
    Xq = ft.paper_q_features(x, y, th, P.ds, center)
    Xt = ft.paper_theta_features(x, y, th, P.ds, center)
    cases = {"q_x": (Xq, ft.q_from_hz(hz[..., 0], P)), "q_y": (Xq, ft.q_from_hz(hz[..., 1], P)),
             "dH_dtheta": (Xt, hz[:, 1:, 2])}
    for k, c in enumerate(("dH_dp_x", "dH_dp_y", "dH_dp_theta")):
        cases[c] = (p[:, 1:, k][..., None], hz[:, 1:, 3 + k])
    oracles = oracle_components(P, theta_closure)
    rows = []
    for name, (X, tgt) in cases.items():
        o = np.asarray(oracles[name](X))
        lrn = np.asarray(Flat(learned[name])(X)).reshape(tgt.shape)
        std = float(np.std(tgt))
        e_o = float(np.sqrt(np.mean((o.reshape(tgt.shape) - tgt) ** 2)))
        e_l = float(np.sqrt(np.mean((lrn - tgt) ** 2)))
        row = {"component": name, "target_std": std, "oracle_rmse": e_o, "oracle_rmse_over_std": e_o / std,
               "learned_rmse": e_l, "learned_rmse_over_std": e_l / std}
        if name == "dH_dtheta":  # where the closure's error lives: interior nodes vs the free tip
            ei = o.reshape(tgt.shape)[:, :-1] - tgt[:, :-1]
            row["oracle_rmse_interior"] = float(np.sqrt(np.mean(ei**2)))
            row["oracle_rmse_tip"] = float(np.sqrt(np.mean((o.reshape(tgt.shape)[:, -1] - tgt[:, -1]) ** 2)))
        rows.append(row)
    return pd.DataFrame(rows)


def run_variant(variant: str, names: tuple[str, ...], sources: dict[str, Any], P: RodParams, S: SimSettings,
                center: float | None, theta_closure: str, gts: dict[float, pd.DataFrame],
                evaluator: str) -> list[dict[str, Any]]:
    """Roll out one variant (``names`` from ``sources``, the rest oracles) on every test angle."""
    angles = sorted(gts)
    model = LearnedRod(mixed_components(sources, P, names, theta_closure), "paper", P, center)
    t0 = time.perf_counter()
    status: dict[float, str] = {}
    try:
        trajs = dict(zip(angles, _rollout_batch(model, angles, S), strict=True))
    except SimulationDiverged:
        trajs = {}
        for a in angles:
            try:
                trajs[a] = _rollout_batch(model, [a], S)[0]
            except SimulationDiverged as exc:
                status[a] = f"diverged at t = {exc.t:.4g} s"
    secs = time.perf_counter() - t0
    log.info("%s: %.1f s for %d angles", variant, secs, len(angles))
    rows = []
    for a in angles:
        row: dict[str, Any] = {"variant": variant, "learned": " ".join(names) or "none", "theta0_deg": a}
        if a in trajs:
            row.update(accuracy(gts[a], trajectory_frame(trajs[a]), P.L0, f"ground truth {a:g}",
                                f"{variant} {a:g}"))
            row["status"] = "ok"
        else:
            row.update({"rmse_theta": math.nan, "r2_theta": math.nan, "tip_rmse_over_L": math.nan,
                        "group_nrmse": math.nan, "status": status[a]})
        row["seconds_batch"] = secs
        row["learned_evaluator"] = evaluator if names else "none"
        rows.append(row)
    return rows


def learned_rows(rollouts: list[str], gts: dict[float, pd.DataFrame], L0: float) -> list[dict[str, Any]]:
    """Variant ``all_learned``: the ``cr_gpr`` rollouts (rule ``rollout``) scored like the others."""
    rows = []
    for path in rollouts:
        df = read_parquet(path)
        a = float(df["theta0_deg"].iloc[0])
        row: dict[str, Any] = {"variant": "all_learned", "learned": " ".join(ORACLE_COMPONENTS),
                               "theta0_deg": a}
        row.update(accuracy(gts[a], df, L0, f"ground truth {a:g}", f"cr_gpr {a:g}"))
        row["status"] = "ok"
        row["seconds_batch"] = float(read_metadata(path).get("seconds", math.nan))
        row["learned_evaluator"] = f"cr_gpr rollout {Path(path).name}"
        rows.append(row)
    return rows


def oracle_ablation(cfg: dict[str, Any], theta_closure: str, model_dir: str, gt_train: str,
                    gt_tests: list[str], learned_rollouts: list[str], out_csv: str, out_pointwise: str,
                    out_fig: str) -> pd.DataFrame:
    """Run every variant on every test angle; write the two tables and the figure."""
    P, S = rod_params(cfg), sim_settings(cfg)
    mdir = Path(model_dir)
    learned = {c: Flat(load_evaluator(mdir / c)) for c in ORACLE_COMPONENTS}
    center = learned["q_x"].comp.meta.get("theta_center")
    gts = {}
    for path in gt_tests:
        df = read_parquet(path)
        gts[float(df["theta0_deg"].iloc[0])] = df
    learned_all = learned_rows(learned_rollouts, gts, P.L0)
    if sorted(r["theta0_deg"] for r in learned_all) != sorted(gts):
        raise ValueError(f"oracle ablation: cr_gpr rollouts {learned_rollouts} not at the test angles")
    rows = []
    for variant, names in variants().items():
        rows += run_variant(variant, names, learned, P, S, center, theta_closure, gts,
                            f"{learned['dH_dtheta'].comp.kind} mean (load_evaluator)")
    rows += learned_all
    table = pd.DataFrame(rows)
    table["theta_closure"] = theta_closure
    write_csv(table, out_csv)
    train = trajectory_from_frame(read_parquet(gt_train), P)
    pw = pointwise_errors(train, P, learned, center, theta_closure)
    pw["trajectory"] = f"ground truth {train.theta0_deg:g} deg (exact simulator states, t > 0)"
    write_csv(pw, out_pointwise)
    oracle_ablation_figure(table, pw, out_fig)
    return table
