"""Black-box GP baseline (paper Sec. V, "Baseline Comparisons", baseline (i), N_init = 1).

Six independent GPs map the local state features at a node straight to the six components of
dz/dt = [dx/dt, dy/dt, dtheta/dt, dp_x/dt, dp_y/dt, dp_theta/dt]. Unlike CR-GPR there is no
J - R (no kinematic identity dq/dt = p / mass, no damping R, no input G u), no force/moment
resultants and no spatial derivative of a learned flux: each output is a free function of

    f = [theta_i, theta_{i-1}, theta_{i+1}, d2theta/ds2, dx/ds, dy/ds, p_x, p_y, p_theta]_i,

the union of the local features of CR-GPR's six gradient GPs (paper GPR 1-6), computed by
CR-GPR's own ``crgpr.learning.features.paper_theta_features`` (nodal stencils, free-tip ghost
theta_{N+1} = theta_{N-1}, angles shifted into the 2 pi window centred on the training range
when ``gradient_models.theta_wrap`` is on) plus the nodal momenta, both for training (on the
prefiltered 85 deg data, the same data set E as CR-GPR) and during the rollout. Kernel family and
fitting are CR-GPR's: ARD-SE with an explicit basis, hyperparameters by maximising the log
marginal likelihood (``crgpr.gp.fit_gp``) on a seeded random subset, then conditioned on
``n_train`` points.

Rollout (eq. (nonpde) without structure): the same kick-drift-kick Stormer-Verlet layout and
dt as the ground truth, for a state whose velocity is itself learned,

    p_{n+1/2} = p_n + dt/2 F_p,   q_{n+1} = q_n + dt f_q(q_n, p_{n+1/2}),
    F_p = f_p(q_{n+1}, p_{n+1/2}),   p_{n+1} = p_{n+1/2} + dt/2 F_p,

one evaluation of each GP per step (the momentum rate is reused for the next half kick, as
``run_generic`` reuses its force), clamped base node held fixed.

Divergence: a rollout is stopped when a state is non-finite, a speed exceeds
``integrator.MAX_SPEED`` or a node leaves the disc of radius 2 L0 around the base (a rod of
length L0 cannot). The rollout file then holds the trajectory up to the last plausible
record and that state frozen afterwards (scored like that by the metrics, a bounded and
conservative error), with ``diverged``, ``t_diverged`` and ``node_diverged`` in its Parquet
metadata; the baselines table reports the count.
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numba import njit

from crgpr.config import ConfigError
from crgpr.gp import GP, basis_matrix_std, fit_gp
from crgpr.learning import features as ft
from crgpr.learning.prefilter import D1_COLUMNS
from crgpr.physics.integrator import MAX_SPEED, SimulationDiverged
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.rod import STATE_NAMES, straight_rod

log = logging.getLogger(__name__)

FEATURES: tuple[str, ...] = ("theta", "theta_prev", "theta_next", "d2theta_ds2", "dx_ds", "dy_ds",
                             "p_x", "p_y", "p_theta")
TARGETS: tuple[str, ...] = D1_COLUMNS  # dx_dt, ..., dp_theta_dt


def blackbox_settings(cfg: dict[str, Any]) -> dict[str, Any]:
    try:
        return dict(cfg["baselines"]["blackbox_gp"])
    except KeyError as exc:
        raise ConfigError("config: missing section baselines.blackbox_gp") from exc


def node_features(q: np.ndarray, p: np.ndarray, ds: float, center: float | None) -> np.ndarray:
    """Local features (..., N, 9) of the free nodes 1..N from nodal q, p (..., N+1, 3)."""
    geo = ft.paper_theta_features(q[..., 0], q[..., 1], q[..., 2], ds, center)
    return np.concatenate([geo, p[..., 1:, :]], axis=-1)


def theta_center(cfg: dict[str, Any], theta: np.ndarray) -> float | None:
    """CR-GPR's angle window centre (middle of the training range of theta), if wrapping is on."""
    wrap = bool(cfg.get("gradient_models", {}).get("theta_wrap", False))
    th = theta[:, 1:]
    return 0.5 * (float(th.min()) + float(th.max())) if wrap else None


def training_set(prefiltered: pd.DataFrame, params: RodParams, cfg: dict[str, Any] | None = None
                 ) -> tuple[np.ndarray, np.ndarray, float | None]:
    """Features (n, 9), dz/dt targets (n, 6) of the free nodes of a prefilter table; angle centre."""
    df = prefiltered.sort_values(["t", "node"])
    t = np.unique(df["t"].to_numpy())
    n_nodes = int(df["node"].max()) + 1
    if n_nodes != params.N + 1 or len(df) != t.size * n_nodes:
        raise ConfigError(f"prefilter table has {n_nodes} nodes / {len(df)} rows; expected a full grid "
                          f"with rod.N + 1 = {params.N + 1} nodes")
    arr = {c: df[c].to_numpy().reshape(t.size, n_nodes) for c in (*STATE_NAMES, *TARGETS)}
    q = np.stack([arr["x"], arr["y"], arr["theta"]], -1)
    p = np.stack([arr["p_x"], arr["p_y"], arr["p_theta"]], -1)
    center = theta_center(cfg or {}, arr["theta"])
    F = node_features(q, p, params.ds, center).reshape(-1, len(FEATURES))
    Y = np.stack([arr[c] for c in TARGETS], -1)[:, 1:].reshape(-1, 6)
    return F, Y, center


def fit_blackbox(F: np.ndarray, Y: np.ndarray, settings: dict[str, Any], seed: int) -> list[GP]:
    """Six independent GPs features -> dz/dt component (ARD-SE + basis, LML-fitted)."""
    rng = np.random.default_rng(seed)
    n = min(int(settings["n_train"]), len(F))
    idx = np.sort(rng.choice(len(F), size=n, replace=False))
    gps = []
    for k, name in enumerate(TARGETS):
        y = Y[idx, k]
        t0 = time.perf_counter()
        gp = fit_gp(F[idx], y, kernel=str(settings["kernel"]), basis=str(settings["basis"]),
                    ard=bool(settings["ard"]), sigma_n_min=float(settings["sigma_n_min"]) * float(y.std()),
                    n_restarts=int(settings["restarts"]), seed=seed + k,
                    hyper_subset=int(settings["n_hyper"]))
        gp.info["fit_seconds"] = time.perf_counter() - t0
        log.info("black-box GP %s: n = %d, lml %.4g, %.1f s", name, gp.n, gp.lml, gp.info["fit_seconds"])
        gps.append(gp)
    return gps


# --------------------------------------------------------------------------------------
# fast posterior mean for the rollout
# --------------------------------------------------------------------------------------
@njit(cache=True)
def _se_mean(U, Ut, alpha, sf2, out):
    """out[i] = sum_j alpha_j sf2 exp(-|U_i - Ut_j|^2 / 2), inputs already divided by ell."""
    m, d = U.shape
    n = Ut.shape[0]
    for i in range(m):
        acc = 0.0
        for j in range(n):
            r2 = 0.0
            for k in range(d):
                diff = U[i, k] - Ut[j, k]
                r2 += diff * diff
            acc += alpha[j] * math.exp(-0.5 * r2)
        out[i] = sf2 * acc


class FastMean:
    """Posterior means of several SE GPs fitted on the same inputs, at many query points."""

    def __init__(self, gps: list[GP]):
        for gp in gps:
            if gp.kernel != "se":
                raise ConfigError("baselines.blackbox_gp.kernel: the rollout supports 'se' only")
        for gp in gps:
            gp.ensure_factorised()  # loaded models factorise lazily
        self.gps = gps
        self.ell = [np.broadcast_to(gp.lengthscales, (gp.dim,)).astype(float) for gp in gps]
        self.Ut = [np.ascontiguousarray(gp.standardise_x(gp.X) / e)
                   for gp, e in zip(gps, self.ell, strict=True)]
        self.alpha = [np.ascontiguousarray(gp.alpha[:, 0]) for gp in gps]

    def __call__(self, X: np.ndarray, which: range) -> np.ndarray:
        out = np.empty((X.shape[0], len(which)))
        buf = np.empty(X.shape[0])
        for c, k in enumerate(which):
            gp = self.gps[k]
            U = gp.standardise_x(X)
            _se_mean(np.ascontiguousarray(U / self.ell[k]), self.Ut[k], self.alpha[k], gp.sigma_f**2, buf)
            mean = buf + (basis_matrix_std(gp.basis, U) @ gp.beta)[:, 0]
            out[:, c] = mean * gp.y_scale[0] + gp.y_mean[0]
        return out


def rollout(gps: list[GP], theta0_deg: float, params: RodParams, settings: SimSettings,
            center: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    """Integrate the black-box model from the straight rod at rest; (t, q, p, info).

    On divergence the remaining records repeat the last plausible state (see module doc).
    """
    fm = FastMean(gps)
    q = straight_rod(math.radians(theta0_deg), params)
    p = np.zeros_like(q)
    dt, every, n_steps = settings.dt, settings.record_every, settings.n_steps
    n_rec = n_steps // every + 1
    out_q = np.empty((n_rec, *q.shape))
    out_p = np.empty_like(out_q)
    out_q[0], out_p[0] = q, p
    vmax = np.array([params.rhoA, params.rhoA, params.rhoI]) * MAX_SPEED
    h = 0.5 * dt
    free = slice(1, None)
    Fp = fm(node_features(q, p, params.ds, center), range(3, 6))
    info: dict[str, Any] = {"diverged": False, "t_diverged": None, "node_diverged": None,
                            "step_diverged": None}
    r_last = 0
    for k in range(1, n_steps + 1):
        p[free] += h * Fp
        q[free] += dt * fm(node_features(q, p, params.ds, center), range(0, 3))
        Fp = fm(node_features(q, p, params.ds, center), range(3, 6))
        p[free] += h * Fp
        if k % every == 0:
            r = k // every
            bad = ~(np.isfinite(q).all(1) & np.isfinite(p).all(1) & (np.abs(p) < vmax).all(1)
                    & (np.hypot(q[:, 0] - q[0, 0], q[:, 1] - q[0, 1]) <= 2.0 * params.L0))
            if bad.any():
                node = int(np.nonzero(bad)[0][0])
                info.update(diverged=True, t_diverged=k * dt, node_diverged=node, step_diverged=k)
                log.warning("black-box GP rollout at %s deg diverged at t = %.4g s, node %d", theta0_deg,
                            k * dt, node)
                out_q[r:] = out_q[r_last]
                out_p[r:] = out_p[r_last]
                break
            out_q[r], out_p[r] = q, p
            r_last = r
    t = np.arange(n_rec) * dt * every
    return t, out_q, out_p, info


def load_models(model_dir: str | Path) -> list[GP]:
    return [GP.load(Path(model_dir) / name) for name in TARGETS]


__all__ = ["FEATURES", "TARGETS", "SimulationDiverged", "fit_blackbox", "node_features", "rollout",
           "training_set"]
