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

Rollout (eq. (17) of Sec. III-B without its structure): the generic form of the one
Stormer-Verlet integrator (``crgpr.physics.integrator.run_verlet``) with the ground truth's dt,
for a state whose velocity is itself learned,

    p_{n+1/2} = p_n + dt/2 F_p,   q_{n+1} = q_n + dt f_q(q_n, p_{n+1/2}),
    F_p = f_p(q_{n+1}, p_{n+1/2}),   p_{n+1} = p_{n+1/2} + dt/2 F_p,

one evaluation of each GP per step (the momentum rate is reused for the next half kick),
clamped base node held fixed.

Inputs (docs/ports.md, the actuated study): a record driven by actuation inputs u(t) appends
the input channels u(t) (``physics.ports.CHANNELS``, all of them, in that order) to every node's
features, ``INPUT_FEATURES``; the rollout evaluates them at every step time. The black box is
told nothing of G: where and how an input acts on the rod it must learn from the record (a
channel the training record never drives is a constant feature it cannot learn). Without
inputs the features and the rollout are unchanged.

Divergence: the integrator's one policy (non-finite state, |dq/dt| >= ``integrator.MAX_SPEED``,
a node farther than ``integrator.REACH`` L0 from the base). The rollout file then holds the
trajectory up to the last plausible record and that state frozen afterwards (scored like that
by the metrics, a bounded and conservative error), with ``diverged``, ``t_diverged`` and
``node_diverged`` in its Parquet metadata; the baselines table reports the count.
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.config import ConfigError
from crgpr.gp import GP, KernelMean, fit_gp
from crgpr.io import frame_to_grid
from crgpr.learning import features as ft
from crgpr.learning.prefilter import D1_COLUMNS
from crgpr.physics.integrator import SimulationDiverged, run_verlet
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.ports import CHANNELS
from crgpr.physics.rod import STATE_NAMES, straight_rod
from crgpr.physics.signals import Inputs

log = logging.getLogger(__name__)

FEATURES: tuple[str, ...] = ("theta", "theta_prev", "theta_next", "d2theta_ds2", "dx_ds", "dy_ds",
                             "p_x", "p_y", "p_theta")
TARGETS: tuple[str, ...] = D1_COLUMNS  # dx_dt, ..., dp_theta_dt
INPUT_FEATURES: tuple[str, ...] = tuple(f"u_{c}" for c in CHANNELS)  # appended when trained with inputs


def blackbox_settings(cfg: dict[str, Any]) -> dict[str, Any]:
    try:
        return dict(cfg["baselines"]["blackbox_gp"])
    except KeyError as exc:
        raise ConfigError("config: missing section baselines.blackbox_gp") from exc


def node_features(q: np.ndarray, p: np.ndarray, ds: float, center: float | None,
                  u: np.ndarray | None = None) -> np.ndarray:
    """Local features (..., N, 9) of the free nodes 1..N from nodal q, p (..., N+1, 3); with
    inputs u (..., n_channels) at the same time, (..., N, 9 + n_channels)."""
    geo = ft.paper_theta_features(q[..., 0], q[..., 1], q[..., 2], ds, center)
    F = np.concatenate([geo, p[..., 1:, :]], axis=-1)
    if u is None:
        return F
    u = np.broadcast_to(np.asarray(u, dtype=float)[..., None, :], (*F.shape[:-1], np.shape(u)[-1]))
    return np.concatenate([F, u], axis=-1)


def training_set(prefiltered: pd.DataFrame, params: RodParams, theta_wrap: bool,
                 inputs: Inputs | None = None) -> tuple[np.ndarray, np.ndarray, float | None]:
    """Features (n, 9), dz/dt targets (n, 6) of the free nodes of a prefilter table; the angle
    window centre (``features.theta_center``, None unless ``theta_wrap``). With ``inputs``, their
    channels at the table's times are features too (n, 9 + len(CHANNELS))."""
    cols = (*STATE_NAMES, *TARGETS)
    try:
        t, g = frame_to_grid(prefiltered, cols, "prefilter table")
    except ValueError as exc:
        raise ConfigError(str(exc)) from exc
    if g.shape[1] != params.N + 1:
        raise ConfigError(f"prefilter table has {g.shape[1]} nodes; expected rod.N + 1 = {params.N + 1}")
    arr = {c: np.ascontiguousarray(g[..., k]) for k, c in enumerate(cols)}
    q = np.stack([arr["x"], arr["y"], arr["theta"]], -1)
    p = np.stack([arr["p_x"], arr["p_y"], arr["p_theta"]], -1)
    center = ft.theta_center(arr["theta"]) if theta_wrap else None
    u = None if inputs is None else inputs.values(t)
    F = node_features(q, p, params.ds, center, u)
    Y = np.stack([arr[c] for c in TARGETS], -1)[:, 1:].reshape(-1, 6)
    return F.reshape(-1, F.shape[-1]), Y, center


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
# rollout
# --------------------------------------------------------------------------------------
def rollout(gps: list[GP], theta0_deg: float, params: RodParams, settings: SimSettings,
            center: float | None = None, inputs: Inputs | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    """Integrate the black-box model from the straight rod at rest; (t, q, p, info).

    The generic form of the one integrator (``run_verlet``), with the learned velocity
    f_q(q, p) and momentum rate f_p(q, p) evaluated by the exact posterior means
    (``KernelMean.exact``); a model trained with inputs sees ``inputs`` at every step time
    (module doc). On divergence the remaining records repeat the last plausible state (see
    module doc), and ``info`` says when and where.
    """
    means = [KernelMean.exact(gp) for gp in gps]
    q0 = straight_rod(math.radians(theta0_deg), params)
    zero = np.zeros((1, 3))
    free = np.ones_like(q0)
    free[0] = 0.0  # the base node is held (the black box has no clamp condition of its own)

    dt, every, n_steps = settings.dt, settings.record_every, settings.n_steps
    n_rec = n_steps // every + 1
    u = None if inputs is None else inputs.values(np.arange(n_steps + 1) * dt)
    step = [0]  # force evaluation j (the j-th, from 0) sees u(j dt); a velocity, the latest step's

    def rates(q: np.ndarray, p: np.ndarray, which: range) -> np.ndarray:
        X = node_features(q, p, params.ds, center, None if u is None else u[min(step[0], n_steps)])
        return np.vstack([zero, np.stack([means[k](X) for k in which], axis=1)])

    def force(q: np.ndarray, p: np.ndarray) -> np.ndarray:
        out = rates(q, p, range(3, 6))
        step[0] += 1
        return out

    info: dict[str, Any] = {"diverged": False, "t_diverged": None, "node_diverged": None,
                            "step_diverged": None}
    try:
        out = run_verlet(q0, np.zeros_like(q0), force, lambda q, p: rates(q, p, range(0, 3)), free, dt,
                         n_steps, every, length=params.L0, what=f"black-box GP rollout at {theta0_deg:g} deg")
        return out.t, out.q, out.v, info
    except SimulationDiverged as exc:
        info.update(diverged=True, t_diverged=exc.t, node_diverged=exc.node, step_diverged=exc.step)
        log.warning("%s", exc)
        part = exc.partial
        r = part.q.shape[0]
        q = np.concatenate([part.q, np.repeat(part.q[-1:], n_rec - r, axis=0)])
        p = np.concatenate([part.v, np.repeat(part.v[-1:], n_rec - r, axis=0)])
        return np.arange(n_rec) * dt * every, q, p, info


def load_models(model_dir: str | Path) -> list[GP]:
    return [GP.load(Path(model_dir) / name) for name in TARGETS]


__all__ = ["FEATURES", "INPUT_FEATURES", "TARGETS", "SimulationDiverged", "fit_blackbox", "node_features",
           "rollout", "training_set"]
