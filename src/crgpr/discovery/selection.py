"""Missing-physics workflow (``crgpr discover``): locate, name, add, and verify a missing effect.

Goes beyond the paper (issue 6). Given camera positions of a rod (``crgpr.discovery.measured``) and the
nominal model of ``config.yaml``:

1. Locate. The nominal model is simulated from the measured initial state (GP-smoothed,
   projected onto an unstretched, unsheared rod) and compared with the measurement:
   RMSE of theta per node and per time window, the state group with the largest normalised
   error, and the sign of the net work of the missing terms from the port-Hamiltonian energy
   balance dH/dt = -H_z^T R H_z + P_missing (net negative work: a missing dissipation).
2. Name. The cut-moment residual of the measured data against the nominal model
   (``crgpr.discovery.effects``) is regressed on every candidate's signature. Candidates enter by
   forward stepwise selection with the Bayesian information criterion of a heteroscedastic
   Gaussian model (one variance per segment and one for the clamp constraint), the sample size
   deflated by the integrated autocorrelation time of the residuals in time and along s; a
   candidate enters only if it lowers BIC by ``bic_min_improvement`` (10: "very strong
   evidence", Kass and Raftery 1995). Coefficient uncertainties come from the weighted least
   squares covariance with the same deflation.
3. Add. The selected coefficients are refined by fitting the simulated trajectory (theta at
   all free nodes and samples; scipy least_squares) and the augmented model is simulated.
4. Verdict. ``none`` if the nominal gap is below ``min_gap_rad``; ``effect_found`` if the
   selected effects close at least ``min_explained`` of the gap; else ``unexplained`` (no
   name is forced; the located residual is reported).
"""

from __future__ import annotations

import argparse
import logging
import math
import time
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import least_squares, lsq_linear

from crgpr.config import load_config, rod_params, sim_settings
from crgpr.discovery.effects import EFFECT_NAMES, EFFECTS, Residual, effect_params, residual
from crgpr.discovery.measured import Kinematics, Measured, camera_frame, load_measured, smooth_kinematics
from crgpr.io import atomic_path, read_parquet, write_csv, write_json, write_parquet, write_text
from crgpr.physics.integrator import SimulationDiverged, run_generic
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.rod import free_mask, internal_forces, masses, node_weights, segment_EI, straight_rod
from crgpr.physics.simulate import dissipation_coefficients, simulate

log = logging.getLogger(__name__)

STATE_GROUPS: tuple[str, ...] = ("x", "y", "theta", "p_x", "p_y", "p_theta")


# ------------------------------------------------------------------------------------------------
# settings
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DiscoverySettings:
    """Settings of the ``discovery`` config section (units in the names)."""

    min_rate_hz: float = 200.0
    min_samples: int = 50
    edge_trim_s: float = 0.02
    init_window_s: float = 0.2
    init_modes: int = 4
    window_s: float = 0.1
    min_gap_rad: float = 0.02
    min_explained: float = 0.5
    min_effect_fraction: float = 0.1
    max_confirm: int = 2
    max_effects: int = 3
    bic_min_improvement: float = 10.0
    refine_max_nfev: int = 40
    gp_max_points: int = 1500
    seed: int = 0

    @classmethod
    def from_config(cls, cfg: dict[str, Any]) -> DiscoverySettings:
        d = cfg.get("discovery", {})
        return cls(min_rate_hz=float(d.get("min_rate_hz", 200.0)),
                   min_samples=int(d.get("min_samples", 50)),
                   edge_trim_s=float(d.get("edge_trim_s", 0.02)),
                   init_window_s=float(d.get("init_window_s", 0.2)),
                   init_modes=int(d.get("init_modes", 4)),
                   window_s=float(d.get("window_s", 0.1)),
                   min_gap_rad=float(d.get("min_gap_rad", 0.02)),
                   min_explained=float(d.get("min_explained", 0.5)),
                   min_effect_fraction=float(d.get("min_effect_fraction", 0.1)),
                   max_confirm=int(d.get("max_confirm", 2)),
                   max_effects=int(d.get("max_effects", 3)),
                   bic_min_improvement=float(d.get("bic_min_improvement", 10.0)),
                   refine_max_nfev=int(d.get("refine_max_nfev", 40)),
                   gp_max_points=int(d.get("gp_max_points", 1500)),
                   seed=int(cfg.get("seed", 0)) + 6)


# ------------------------------------------------------------------------------------------------
# simulation helpers
# ------------------------------------------------------------------------------------------------
def aligned_settings(params: RodParams, dt_max: float, period: float, n_samples: int,
                     safety: float = 0.8) -> SimSettings:
    """Time step <= dt_max (and stable) that divides the sampling period exactly."""
    dt = min(dt_max, safety * params.dt_stable())
    every = max(1, math.ceil(period / dt - 1e-9))
    dt = period / every
    return SimSettings(dt=dt, t_end=(n_samples - 1) * period, record_every=every)


def rod_state(theta: np.ndarray, omega: np.ndarray, base: np.ndarray, params: RodParams
              ) -> tuple[np.ndarray, np.ndarray]:
    """Unstretched, unsheared state (q, v) from nodal angles and angular rates.

    Positions are rebuilt from the fixed base with segments of length ds nu1^0 along the
    mid-segment angles (nu1 = nu1^0, nu2 = 0) and velocities from the rates of those angles,
    so that the stiff axial and shear modes start at rest.
    """
    tb = 0.5 * (theta[1:] + theta[:-1])
    wb = 0.5 * (omega[1:] + omega[:-1])
    seg = params.ds * params.nu1_0
    q0 = np.empty((params.N + 1, 3))
    v0 = np.zeros((params.N + 1, 3))
    q0[0, :2] = base
    q0[1:, 0] = base[0] + np.cumsum(seg * np.cos(tb))
    q0[1:, 1] = base[1] + np.cumsum(seg * np.sin(tb))
    q0[:, 2] = theta
    v0[1:, 0] = np.cumsum(-seg * wb * np.sin(tb))
    v0[1:, 1] = np.cumsum(seg * wb * np.cos(tb))
    v0[:, 2] = omega
    if params.clamped:
        v0[0, 2] = 0.0
    return q0, v0


def run_model(params: RodParams, q0: np.ndarray, v0: np.ndarray, period: float, n_samples: int,
              dt_max: float) -> np.ndarray:
    """Simulate ``params`` from (q0, v0); q (n_samples, N+1, 3) on the measured time grid."""
    st = aligned_settings(params, dt_max, period, n_samples)
    tr = simulate(math.degrees(q0[0, 2]), params, st, q0=q0, v0=v0)
    return tr.q[:n_samples]


def theta_rmse(qa: np.ndarray, qb: np.ndarray) -> float:
    """RMSE of theta over the free nodes 1..N and all samples [rad]."""
    return float(np.sqrt(np.mean((qa[:, 1:, 2] - qb[:, 1:, 2]) ** 2)))


def tip_rmse_over_L(qa: np.ndarray, qb: np.ndarray, L0: float) -> float:
    d = np.hypot(qa[:, -1, 0] - qb[:, -1, 0], qa[:, -1, 1] - qb[:, -1, 1])
    return float(np.sqrt(np.mean(d**2)) / L0)


# ------------------------------------------------------------------------------------------------
# step 1: locate
# ------------------------------------------------------------------------------------------------
def _group_nrmse(kin: Kinematics, q_sim: np.ndarray, v_sim: np.ndarray, params: RodParams) -> dict:
    """Normalised RMSE (by the measured range) of the six state groups, free nodes."""
    scale = np.array([params.rhoA, params.rhoA, params.rhoI])
    meas = np.concatenate([kin.q, kin.v * scale], axis=-1)[:, 1:]
    sim = np.concatenate([q_sim, v_sim * scale], axis=-1)[:, 1:]
    out = {}
    for k, name in enumerate(STATE_GROUPS):
        rng = float(np.ptp(meas[..., k])) or 1.0
        out[name] = float(np.sqrt(np.mean((sim[..., k] - meas[..., k]) ** 2)) / rng)
    return out


def reduced_energy(kin: Kinematics, params: RodParams, theta_base: float) -> np.ndarray:
    """Nominal H of the measured states, rod taken unstretched and unsheared [J] (per t).

    Kinetic + bending (+ nominal base spring) + gravity; the stretch and shear energies are
    not resolvable from camera positions and are negligible for this rod.
    """
    m_t, m_r = masses(params)
    v = kin.v
    ke = 0.5 * (m_t * (v[..., 0] ** 2 + v[..., 1] ** 2) + m_r * v[..., 2] ** 2).sum(-1)
    dk = np.diff(kin.q[..., 2], axis=-1) / params.ds - params.kappa0
    b = params.nonlinear_stiffness
    vb = (params.ds * segment_EI(params) * (0.5 * dk**2 + 0.25 * b * dk**4)).sum(-1)
    if not params.clamped:
        vb = vb + 0.5 * params.base_spring * (kin.q[:, 0, 2] - theta_base) ** 2
    vg = (m_t * params.g * kin.q[..., 1]).sum(-1)
    return ke + vb + vg


def nominal_dissipation_rate(kin: Kinematics, params: RodParams) -> np.ndarray:
    """H_z^T R H_z of the nominal model on the measured velocities [W]."""
    w = node_weights(params.N) * params.ds
    v = kin.v
    sp2 = v[..., 0] ** 2 + v[..., 1] ** 2
    rate = ((params.zeta + params.viscous_drag) * w * sp2).sum(-1)
    rate = rate + (params.zeta * w * v[..., 2] ** 2).sum(-1)
    return rate + (params.air_drag * w * sp2**1.5).sum(-1)


def locate(kin: Kinematics, q_nom: np.ndarray, v_nom: np.ndarray, params: RodParams,
           st: DiscoverySettings, theta_base: float) -> dict[str, Any]:
    """Where, when and in which state group the nominal model departs from the data."""
    t = kin.t - kin.t[0]
    err = q_nom[..., 2] - kin.q[..., 2]
    per_node = np.sqrt(np.mean(err**2, axis=0))
    edges = np.arange(0.0, t[-1] + st.window_s, st.window_s)
    windows = []
    for a, b in zip(edges[:-1], edges[1:], strict=False):
        sel = (t >= a) & (t < b + (1e-12 if b >= t[-1] else 0.0))
        if sel.any():
            windows.append((float(a), float(min(b, t[-1])), float(np.sqrt(np.mean(err[sel, 1:] ** 2)))))
    worst = max(windows, key=lambda w: w[2])
    onset = next((w for w in windows if w[2] > st.min_gap_rad), None)
    top = np.nonzero(per_node[1:] >= 0.5 * per_node[1:].max())[0] + 1
    groups = _group_nrmse(kin, q_nom, v_nom, params)
    # energy balance: P_missing = dH/dt + H_z^T R H_z, integrated over the trimmed record
    trim = max(1, int(round(st.edge_trim_s / np.median(np.diff(t)))))
    sl = slice(trim, len(t) - trim)
    H = reduced_energy(kin, params, theta_base)
    D = nominal_dissipation_rate(kin, params)
    tt = t[sl]
    P = np.gradient(H[sl], tt) + D[sl]
    W = float(H[sl][-1] - H[sl][0] + np.trapezoid(D[sl], tt))
    absW = float(np.trapezoid(np.abs(P), tt))
    return {
        "nodes": [int(i) for i in top],
        "s_m": [float(top.min() * params.ds), float(top.max() * params.ds)],
        "worst_node": int(np.argmax(per_node)),
        "time_window_s": [worst[0], worst[1]],
        "onset_s": None if onset is None else onset[0],
        # p_theta = rho I dtheta/dt is below camera resolution: reported, not chosen
        "state_group": max((g for g in groups if g != "p_theta"), key=groups.get),
        "group_nrmse": groups,
        "character": "dissipative" if W < 0 else "conservative",
        "net_work_missing_J": W,
        "abs_work_missing_J": absW,
        "rmse_theta_per_node": [float(x) for x in per_node],
        "rmse_theta_per_window": [{"t0_s": a, "t1_s": b, "rmse": r} for a, b, r in windows],
    }


# ------------------------------------------------------------------------------------------------
# step 2: name (sparse regression with BIC)
# ------------------------------------------------------------------------------------------------
def _tau(series: np.ndarray, axis: int) -> float:
    """Integrated autocorrelation time along ``axis`` (Geyer's initial positive sequence)."""
    x = np.moveaxis(series, axis, 0)
    x = x - x.mean(axis=0, keepdims=True)
    n = x.shape[0]
    var = float(np.mean(x**2))
    if n < 3 or var <= 0:
        return 1.0
    tau = 1.0
    for k in range(1, n // 2):
        rho = float(np.mean(x[k:] * x[:-k])) / var
        if rho <= 0.0:
            break
        tau += 2.0 * rho
    return max(1.0, tau)


@dataclass
class Fit:
    names: list[str]
    coef: np.ndarray  # regression parameters (C = 1/k for base_compliance)
    std: np.ndarray
    m2ll: float  # effective -2 log likelihood
    bic: float


class Regression:
    """Weighted, bounded least squares of the residual on candidate signatures."""

    def __init__(self, res: Residual, rows: slice, candidates: tuple[str, ...] = EFFECT_NAMES,
                 first_segment: int = 1):
        # moment rows of segments first_segment..N-1 (segment 0 needs the extrapolated base
        # angle, which the base row models instead); base rows centred: the spring's rest
        # angle is a nuisance intercept
        seg = slice(first_segment, None)
        self.y_mom = -res.rho[rows, seg]  # (n_t, n_seg): what the missing terms must supply
        self.y_base = res.base_y[rows] - res.base_y[rows].mean()
        self.X_mom = {k: res.sig[k][rows, seg] for k in res.sig}
        self.X_base = res.base_sig[rows] - res.base_sig[rows].mean()
        self.candidates = candidates
        self.n_t, self.n_seg = self.y_mom.shape
        full = self.fit(list(candidates), deflate=False)
        r_mom, r_base = self._residuals(full.names, full.coef)
        z = r_mom / np.sqrt(np.mean(r_mom**2, axis=0, keepdims=True) + 1e-300)
        self.tau_t = _tau(z, 0)
        self.tau_s = _tau(z, 1)
        self.tau_b = _tau(r_base[:, None], 0)
        self.n_eff = self.n_t * self.n_seg / (self.tau_t * self.tau_s) + self.n_t / self.tau_b

    def _design(self, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
        cols_m = [self.X_mom[k] if k != "base_compliance" else np.zeros_like(self.y_mom) for k in names]
        cols_b = [self.X_base if k == "base_compliance" else np.zeros_like(self.y_base) for k in names]
        Xm = np.stack(cols_m, axis=-1) if names else np.zeros(self.y_mom.shape + (0,))
        Xb = np.stack(cols_b, axis=-1) if names else np.zeros(self.y_base.shape + (0,))
        return Xm, Xb

    def _residuals(self, names: list[str], coef: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        Xm, Xb = self._design(names)
        return self.y_mom - Xm @ coef, self.y_base - Xb @ coef

    def fit(self, names: list[str], deflate: bool = True, iters: int = 6) -> Fit:
        """Feasible GLS with one variance per segment and one for the base row."""
        Xm, Xb = self._design(names)
        coef = np.zeros(len(names))
        lo = np.array([EFFECTS[k].reg_lo for k in names])
        hi = np.array([EFFECTS[k].reg_hi for k in names])
        s2m = np.mean(self.y_mom**2, axis=0) + 1e-300
        s2b = float(np.mean(self.y_base**2)) + 1e-300
        A = None
        for _ in range(iters):
            wm = 1.0 / np.sqrt(s2m)
            wb = 1.0 / math.sqrt(s2b)
            Am = (Xm * wm[None, :, None]).reshape(self.n_t * self.n_seg, Xm.shape[-1])
            A = np.concatenate([Am, Xb * wb])
            b = np.concatenate([(self.y_mom * wm[None, :]).ravel(), self.y_base * wb])
            if names:
                coef = lsq_linear(A, b, bounds=(lo, hi), method="bvls").x
            rm, rb = self._residuals(names, coef)
            floor_m = 1e-12 * float(np.mean(self.y_mom**2)) + 1e-300
            s2m = np.maximum(np.mean(rm**2, axis=0), floor_m)
            s2b = max(float(np.mean(rb**2)), 1e-12 * float(np.mean(self.y_base**2)) + 1e-300)
        ft = (self.tau_t * self.tau_s) if deflate else 1.0
        fb = self.tau_b if deflate else 1.0
        m2ll = float(self.n_t * np.sum(np.log(s2m)) / ft + self.n_t * math.log(s2b) / fb)
        n_eff = self.n_eff if deflate else self.n_t * (self.n_seg + 1)
        std = np.zeros(len(names))
        if names:
            try:
                cov = np.linalg.inv(A.T @ A) * (ft if deflate else 1.0)
                std = np.sqrt(np.maximum(np.diag(cov), 0.0))
            except np.linalg.LinAlgError:
                std = np.full(len(names), np.inf)
        return Fit(list(names), coef, std, m2ll, m2ll + len(names) * math.log(max(n_eff, 2.0)))


# ------------------------------------------------------------------------------------------------
# step 3: refine by trajectory fitting
# ------------------------------------------------------------------------------------------------
def augmented_params(params: RodParams, names: list[str], reg: np.ndarray) -> RodParams:
    p = params
    for k, c in zip(names, reg, strict=True):
        p = EFFECTS[k].apply(p, float(c))
    return p


@dataclass
class TrajectoryFit:
    """Result of fitting the simulated theta to the measured theta."""

    names: list[str]
    coef: np.ndarray  # regression parametrisation (C = 1/k for base_compliance)
    std: np.ndarray
    init: np.ndarray  # initial-state corrections (Legendre coefficients)
    q: np.ndarray  # (n_t, N+1, 3) simulated on the measured grid
    q0: np.ndarray
    v0: np.ndarray
    rss: float
    n: int
    tau: float
    nfev: int

    @property
    def rmse(self) -> float:
        return math.sqrt(self.rss / self.n)


class TrajectoryFitter:
    """Fits effect coefficients and smooth initial-state corrections to the measured theta.

    GP time derivatives are least reliable at the ends of a record and this rod amplifies
    initial errors (a 1 rad/s error in the initial rates alone gives ~0.1 rad RMSE over 1 s),
    so every model, the nominal one included, starts from the measured initial state with
    smooth corrections of its angles and angular rates (``n_modes`` Legendre polynomials in s
    each; unstretched, unsheared state rebuilt by ``rod_state``) fitted to the measured theta
    over the first ``window_s`` only (a short shooting fit: long enough to pin the initial
    rates, too short for a missing effect to be absorbed into the initial state). Effect
    coefficients are fitted over the whole record.
    """

    def __init__(self, params: RodParams, kin: Kinematics, dt_max: float, n_modes: int = 4,
                 window_s: float = 0.1):
        self.params, self.kin, self.dt_max, self.n_modes = params, kin, dt_max, n_modes
        self.period = float(np.median(np.diff(kin.t)))
        self.n = len(kin.t)
        self.theta, self.omega, self.base = kin.q[0, :, 2], kin.v[0, :, 2], kin.q[0, 0, :2]
        xs = 2.0 * params.s / params.L0 - 1.0
        self.P = np.stack([np.polynomial.legendre.Legendre.basis(k)(xs) for k in range(n_modes)], axis=1)
        self.w_scale = 1.0 / max(window_s, 1e-3)  # rate corrections in rad per window
        self.window = int(min(self.n, max(5, round(window_s / self.period) + 1)))
        self.c_start = self._window_fit()

    def state(self, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        m = self.n_modes
        return rod_state(self.theta + self.P @ c[:m], self.omega + self.w_scale * (self.P @ c[m:]),
                         self.base, self.params)

    def simulate(self, names: list[str], coef: np.ndarray, c: np.ndarray, n: int | None = None) -> np.ndarray:
        q0, v0 = self.state(c)
        return run_model(augmented_params(self.params, names, coef), q0, v0, self.period,
                         n or self.n, self.dt_max)

    def _resid(self, names: list[str], coef: np.ndarray, c: np.ndarray, n: int) -> np.ndarray:
        try:
            q = self.simulate(names, coef, c, n)
        except SimulationDiverged:
            return np.full(n * self.params.N, 10.0)
        return (q[:, 1:, 2] - self.kin.q[:n, 1:, 2]).ravel()

    def _window_fit(self, names: list[str] | None = None, coef: np.ndarray | None = None,
                    c0: np.ndarray | None = None) -> np.ndarray:
        """Initial-state corrections of a model from its fit to the first window."""
        names = names or []
        coef = np.zeros(0) if coef is None else coef
        c0 = np.zeros(2 * self.n_modes) if c0 is None else c0
        sol = least_squares(lambda c: self._resid(names, coef, c, self.window), c0, x_scale=0.01,
                            diff_step=1e-4, max_nfev=10 * (2 * self.n_modes + 1))
        return sol.x

    def fit(self, names: list[str], x0: np.ndarray, x_std: np.ndarray, max_nfev: int,
            rounds: int = 2) -> TrajectoryFit:
        """Coefficients by least squares of theta over the whole record, the initial state by
        the window fit of the same (augmented) model; alternated ``rounds`` times."""
        k = len(names)
        lo = np.array([EFFECTS[e].reg_lo for e in names])
        hi = np.array([EFFECTS[e].reg_hi for e in names])
        # a base spring must stay integrable with a sensible step: k <= 20 N m/rad
        lo = np.where(np.array(names, dtype=object) == "base_compliance", np.maximum(lo, 0.05), lo)
        coef = np.minimum(np.maximum(np.asarray(x0, float), lo), hi)
        scale = np.where(np.isfinite(x_std) & (x_std > 0), x_std, np.maximum(np.abs(coef), 1e-6))
        scale = np.maximum(scale, 1e-3 * np.abs(coef))
        calls = [0]
        c = self.c_start
        std = np.zeros(k)
        tau = 1.0
        for _ in range(rounds if k else 0):
            c = self._window_fit(names, coef, c)

            def fun(x: np.ndarray, c=c) -> np.ndarray:
                calls[0] += 1
                return self._resid(names, x, c, self.n)

            sol = least_squares(fun, coef, bounds=(lo, hi), x_scale=scale, diff_step=1e-3,
                                max_nfev=max_nfev)
            coef = sol.x
            r = sol.fun.reshape(self.n, -1)
            tau = _tau(r, 0) * _tau(r, 1)
            try:
                cov = np.linalg.pinv(sol.jac.T @ sol.jac) * float(np.mean(sol.fun**2)) * tau
                std = np.sqrt(np.maximum(np.diag(cov), 0.0))
            except np.linalg.LinAlgError:
                std = np.full(k, np.inf)
        if k:
            c = self._window_fit(names, coef, c)
        q0, v0 = self.state(c)
        q = self.simulate(names, coef, c)
        r = (q[:, 1:, 2] - self.kin.q[:, 1:, 2]).ravel()
        if not k:
            tau = _tau(r.reshape(self.n, -1), 0) * _tau(r.reshape(self.n, -1), 1)
        return TrajectoryFit(list(names), coef, std, c, q, q0, v0, float(np.sum(r**2)), r.size, tau,
                             calls[0])


def gap_floor(q_model: np.ndarray, kin: Kinematics, params: RodParams, dt_max: float,
              st: DiscoverySettings, replicates: int = 2) -> float:
    """Gap the nominal model would show with NO missing physics (parametric bootstrap).

    The nominal trajectory is re-measured with the GP's camera-noise estimate, smoothed and
    its initial state estimated exactly as for the data; the RMS of the resulting theta gaps
    is the floor from camera noise and initial-state uncertainty. The verdict compares the
    excess sqrt(gap^2 - floor^2) with ``min_gap_rad``.
    """
    rng = np.random.default_rng(st.seed + 99)
    gaps = []
    for r in range(replicates):
        pos = q_model[..., :2] + kin.noise_std_m * rng.standard_normal(q_model[..., :2].shape)
        meas_b = Measured(kin.t, pos[..., 0], pos[..., 1], None, "bootstrap")
        kin_b = smooth_kinematics(meas_b, seed=st.seed + 100 + r, max_points=st.gp_max_points)
        fb = TrajectoryFitter(params, kin_b, dt_max, n_modes=st.init_modes, window_s=st.init_window_s)
        qb = fb.simulate([], np.zeros(0), fb.c_start)
        gaps.append(theta_rmse(qb, kin_b.q))
    return float(np.sqrt(np.mean(np.square(gaps))))


def trajectory_delta_bic(small: TrajectoryFit, big: TrajectoryFit) -> float:
    """BIC(small) - BIC(big) for theta residuals with the sample size deflated by big's tau."""
    n_eff = big.n / max(big.tau, 1.0)
    dp = len(big.names) - len(small.names)
    return n_eff * math.log(max(small.rss, 1e-300) / max(big.rss, 1e-300)) - dp * math.log(n_eff)


# ------------------------------------------------------------------------------------------------
# the whole workflow
# ------------------------------------------------------------------------------------------------
def model_params_for(meas: Measured, cfg: dict[str, Any]) -> RodParams:
    """Nominal parameters of config.yaml on the measured node grid (N = measured segments)."""
    params = rod_params(cfg)
    if meas.n_segments != params.N:
        log.info("%s: %d measured segments; the model uses N = %d instead of rod.N = %d",
                 meas.source, meas.n_segments, meas.n_segments, params.N)
        params = params.replace(N=meas.n_segments)
    seg = np.hypot(np.diff(meas.x[0]), np.diff(meas.y[0])).sum()
    if abs(seg - params.L0 * params.nu1_0) > 0.1 * params.L0:
        raise ValueError(f"{meas.source}: the measured rod is {seg:.4g} m long at t = {meas.t[0]:g} s but "
                         f"config rod.L0 = {params.L0:g} m; the nodes must span the rod (node 0 = base)")
    return params


def discover(meas: Measured, cfg: dict[str, Any], st: DiscoverySettings | None = None) -> dict[str, Any]:
    """Run the workflow on validated measured data; returns the result dict (and arrays)."""
    t_start = time.perf_counter()
    st = st or DiscoverySettings.from_config(cfg)
    params = model_params_for(meas, cfg)
    dt_max = sim_settings(cfg).dt
    kin = smooth_kinematics(meas, seed=st.seed, max_points=st.gp_max_points)
    t_smooth = time.perf_counter() - t_start
    period = float(np.median(np.diff(kin.t)))
    n = len(kin.t)
    fitter = TrajectoryFitter(params, kin, dt_max, n_modes=st.init_modes, window_s=st.init_window_s)
    nominal = fitter.fit([], np.zeros(0), np.zeros(0), st.refine_max_nfev)
    q_nom = nominal.q
    theta_b = float(nominal.q0[0, 2])
    st_nom = aligned_settings(params, dt_max, period, n)
    tr = simulate(math.degrees(theta_b), params, st_nom, q0=nominal.q0, v0=nominal.v0)
    v_nom = tr.p[:n] / np.array([params.rhoA, params.rhoA, params.rhoI])
    gap_before = theta_rmse(q_nom, kin.q)
    tip_before = tip_rmse_over_L(q_nom, kin.q, params.L0)
    floor = gap_floor(q_nom, kin, params, dt_max, st)
    excess = math.sqrt(max(gap_before**2 - floor**2, 0.0))
    where = locate(kin, q_nom, v_nom, params, st, theta_b)
    # name: port-Hamiltonian residual regression, forward stepwise. At each step the residual
    # is taken against the current (augmented) model, the remaining candidates are ranked by
    # their BIC gain and the best ones (gain >= bic_min_improvement) are confirmed in turn by
    # the trajectory fit (BIC of theta, and at least min_effect_fraction of the gap closed).
    trim = max(1, int(round(st.edge_trim_s / period)))
    rows = slice(trim, n - trim)
    theta_b0 = float(kin.q[0, 0, 2])
    cur = nominal
    accepted: list[TrajectoryFit] = []
    steps: list[dict[str, Any]] = []
    single: dict[str, Fit] = {}
    res0 = residual(kin.q, kin.v, kin.a, params, theta_b0, kin.base_segment_angle)
    reg0 = Regression(res0, rows)
    while True:
        p_cur = augmented_params(params, cur.names, cur.coef)
        reg = reg0 if not cur.names else Regression(
            residual(kin.q, kin.v, kin.a, p_cur, theta_b0, kin.base_segment_angle), rows,
            candidates=tuple(k for k in EFFECT_NAMES if k not in cur.names))
        base_fit = reg.fit([])
        ranked = []
        for k in reg.candidates:
            f = reg.fit([k])
            gain = base_fit.bic - f.bic
            if k not in single:
                single[k] = f
            ranked.append((gain, k, f))
        ranked.sort(key=lambda r: -r[0])
        step = {"model": list(cur.names), "tau_time": reg.tau_t, "tau_s": reg.tau_s, "n_eff": reg.n_eff,
                "residual_bic_gain": {k: g for g, k, _ in ranked}, "coefficients": {
                    k: float(f.coef[0]) for _, k, f in ranked}, "confirmation": []}
        steps.append(step)
        if excess <= st.min_gap_rad:
            break
        added = False
        screened = [r for r in ranked if r[0] >= st.bic_min_improvement][:st.max_confirm]
        if not screened and not cur.names:
            break  # the residual shows no candidate at all: nothing to confirm
        # the residual's best candidates first; if none holds up in the trajectory fit, the
        # remaining candidates are tried by the trajectory likelihood ratio alone
        rest = [r for r in ranked if r not in screened] if cur.names else []
        for group in (screened, rest):
            best = None
            for gain, k, f in group:
                names = cur.names + [k]
                c_reg = f.coef.copy()
                if c_reg[0] == 0.0 and EFFECTS[k].reg_lo == 0.0:  # at its bound: start inside
                    c_reg[0] = max(float(f.std[0]), 1e-6)
                x0 = np.concatenate([cur.coef, c_reg])
                xs = np.concatenate([cur.std, f.std])
                cand = fitter.fit(names, x0, xs, st.refine_max_nfev)
                dbic = trajectory_delta_bic(cur, cand)
                closes = cur.rmse - cand.rmse >= st.min_effect_fraction * gap_before
                ok = dbic >= st.bic_min_improvement and closes
                step["confirmation"].append({"effect": k, "residual_bic_gain": gain, "rmse": cand.rmse,
                                             "trajectory_delta_bic": dbic, "accepted": False,
                                             "nfev": cand.nfev})
                log.info("trajectory fit %s: RMSE %.4f, delta BIC %.1f, acceptable %s", names, cand.rmse,
                         dbic, ok)
                if ok and (best is None or cand.rss < best[0].rss):
                    best = (cand, len(step["confirmation"]) - 1)
            if best is not None:  # the best confirmed candidate of the group enters
                cur = best[0]
                accepted.append(cur)
                step["confirmation"][best[1]]["accepted"] = True
                added = True
                break
        if not added or len(cur.names) >= st.max_effects:
            break
    res, reg = res0, reg0
    result: dict[str, Any] = {
        "measured": meas.source, "n_samples": n, "n_nodes": params.N + 1,
        "sample_rate_hz": 1.0 / period, "gp_noise_std_m": kin.noise_std_m,
        "gap_before": gap_before, "tip_gap_before": tip_before, "gap_noise_floor": floor,
        "gap_excess_over_floor": excess,
        "initial_state_fit": {"modes": st.init_modes, "nominal_corrections": nominal.init.tolist()},
        "selection": {"criterion": "forward stepwise BIC on the port-Hamiltonian residual "
                                   "(heteroscedastic, autocorrelation-deflated), each step confirmed "
                                   "by the trajectory fit's BIC",
                      "bic_min_improvement": st.bic_min_improvement,
                      "tau_time": reg.tau_t, "tau_s": reg.tau_s, "tau_base": reg.tau_b,
                      "n_eff": reg.n_eff, "steps": steps},
    }
    effects: list[dict[str, Any]] = []
    best_attempt = None
    q_aug = q_nom
    if accepted:
        fit = accepted[-1]
        attempt = []
        for i, k in enumerate(fit.names):
            e = EFFECTS[k]
            nominal_val = getattr(params, e.field)
            base = 0.0 if (k == "base_compliance" or not math.isfinite(nominal_val)) else nominal_val
            rc = single.get(k)
            attempt.append({
                "name": k, "unit": e.unit, "place": e.place,
                "coefficient": base + e.to_coefficient(float(fit.coef[i])),
                # the trajectory fit's std holds the initial state fixed; the residual
                # regression's is usually larger: report the larger (conservative)
                "coefficient_std": max(e.coefficient_std(float(fit.coef[i]), float(fit.std[i])),
                                       e.coefficient_std(float(rc.coef[0]), float(rc.std[0])) if rc else 0.0),
                "trajectory_fit_std": e.coefficient_std(float(fit.coef[i]), float(fit.std[i])),
                "regression_coefficient": base + e.to_coefficient(float(rc.coef[0])) if rc else None,
                "regression_std": e.coefficient_std(float(rc.coef[0]), float(rc.std[0])) if rc else None,
            })
        frac = 1.0 - fit.rmse / gap_before
        best_attempt = {"effects": attempt, "gap_after": fit.rmse, "explained_fraction": frac}
        if frac >= st.min_explained:
            effects, q_aug = attempt, fit.q
    if excess <= st.min_gap_rad:
        verdict = "none"
    elif effects:
        verdict = "effect_found"
    else:
        verdict = "unexplained"
    gap_after = theta_rmse(q_aug, kin.q)
    result.update({
        "effects": effects, "verdict": verdict, "gap_after": gap_after,
        "tip_gap_after": tip_rmse_over_L(q_aug, kin.q, params.L0),
        "explained_fraction": 1.0 - gap_after / gap_before if gap_before > 0 else 0.0,
        "where": where, "best_attempt": best_attempt,
        "significant_but_below_tolerance": [k for k, g in steps[0]["residual_bic_gain"].items()
                                            if g >= st.bic_min_improvement] if verdict == "none" else [],
        "timing_s": {"gp_smoothing": t_smooth, "total": time.perf_counter() - t_start},
    })
    arrays = {"kin": kin, "q_nom": q_nom, "q_aug": q_aug, "residual": res, "params": params}
    return {"result": result, "arrays": arrays}


# ------------------------------------------------------------------------------------------------
# outputs: figures and report
# ------------------------------------------------------------------------------------------------
def _figures(out: Path, arrays: dict[str, Any], result: dict[str, Any]) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kin, q_nom, q_aug, params = arrays["kin"], arrays["q_nom"], arrays["q_aug"], arrays["params"]
    t = kin.t - kin.t[0]
    s = params.s
    e0 = q_nom[..., 2] - kin.q[..., 2]
    e1 = q_aug[..., 2] - kin.q[..., 2]
    vmax = float(np.max(np.abs(e0))) or 1.0
    fig, axs = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True, constrained_layout=True)
    for ax, e, title in ((axs[0], e0, f"nominal model (RMSE {result['gap_before']:.3g} rad)"),
                         (axs[1], e1, f"augmented model (RMSE {result['gap_after']:.3g} rad)")):
        im = ax.pcolormesh(t, s, e.T, cmap="RdBu_r", vmin=-vmax, vmax=vmax, shading="auto")
        ax.set_xlabel("t [s]")
        ax.set_title(title, fontsize=10)
    axs[0].set_ylabel("s [m]")
    fig.colorbar(im, ax=axs, label="theta model - measured [rad]")
    fig.suptitle(f"Where the model and the measurement disagree (verdict: {result['verdict']})")
    files = []
    with atomic_path(out / "heatmap.png", ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    files.append("heatmap.png")
    plt.close(fig)

    fig, axs = plt.subplots(1, 3, figsize=(13, 3.6), constrained_layout=True)
    for ax, i in ((axs[0], params.N // 2), (axs[1], params.N)):
        ax.plot(t, kin.q[:, i, 2], "k", lw=2, label="measured (GP-smoothed)")
        ax.plot(t, q_nom[:, i, 2], "C3--", label="nominal model")
        if result["effects"]:
            ax.plot(t, q_aug[:, i, 2], "C0", label="augmented model")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(f"theta at node {i} (s = {i * params.ds:.2f} m) [rad]")
    axs[0].legend(fontsize=8)
    axs[2].plot(s[1:], np.sqrt(np.mean(e0[:, 1:] ** 2, axis=0)), "C3o-", label="nominal")
    axs[2].plot(s[1:], np.sqrt(np.mean(e1[:, 1:] ** 2, axis=0)), "C0s-", label="augmented")
    axs[2].set_xlabel("s [m]")
    axs[2].set_ylabel("RMSE theta [rad]")
    axs[2].legend(fontsize=8)
    with atomic_path(out / "before_after.png", ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    files.append("before_after.png")
    plt.close(fig)

    res: Residual = arrays["residual"]
    rm = float(np.percentile(np.abs(res.rho), 99)) or 1.0
    fig, ax = plt.subplots(figsize=(6, 3.6), constrained_layout=True)
    im = ax.pcolormesh(t, (np.arange(params.N) + 0.5) * params.ds, res.rho.T, cmap="RdBu_r",
                       vmin=-rm, vmax=rm, shading="auto")
    fig.colorbar(im, ax=ax, label="mb_const - mb_dyn [N m]")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("s [m]")
    ax.set_title("port-Hamiltonian (cut-moment) residual of the nominal model", fontsize=10)
    with atomic_path(out / "residual.png", ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    files.append("residual.png")
    plt.close(fig)
    return files


def _report(result: dict[str, Any], files: list[str]) -> str:
    w = result["where"]
    lines = [
        "# Missing-physics discovery", "",
        f"Measured data: `{result['measured']}` ({result['n_samples']} samples at "
        f"{result['sample_rate_hz']:.0f} Hz, {result['n_nodes']} nodes; GP noise estimate "
        f"{1e3 * result['gp_noise_std_m']:.2f} mm).", "",
        f"**Verdict: `{result['verdict']}`**", "",
        "| | nominal | augmented |", "|---|---|---|",
        f"| RMSE theta [rad] | {result['gap_before']:.4f} | {result['gap_after']:.4f} |",
        f"| tip RMSE / L | {result['tip_gap_before']:.4f} | {result['tip_gap_after']:.4f} |", "",
        f"Fraction of the gap explained: {result['explained_fraction']:.1%}", "",
        "## Effects (ranked)", "",
    ]
    if result["effects"]:
        lines += ["| rank | effect | coefficient | std | unit | residual-regression estimate | place |",
                  "|---|---|---|---|---|---|---|"]
        for i, e in enumerate(result["effects"], 1):
            rc = "-" if e["regression_coefficient"] is None else \
                f"{e['regression_coefficient']:.4g} +- {e['regression_std']:.2g}"
            lines.append(f"| {i} | {e['name']} | {e['coefficient']:.4g} | {e['coefficient_std']:.2g} | "
                         f"{e['unit']} | {rc} | {e['place']} |")
    else:
        lines.append("None added.")
        if result["best_attempt"]:
            b = result["best_attempt"]
            names = ", ".join(f"{e['name']} = {e['coefficient']:.3g}" for e in b["effects"])
            lines.append(f"Best candidate set ({names}) closes only {b['explained_fraction']:.1%} of the "
                         f"gap (RMSE {b['gap_after']:.4f} rad): not accepted.")
        if result["significant_but_below_tolerance"]:
            lines.append(f"Significant in the residual but the gap is below tolerance: "
                         f"{result['significant_but_below_tolerance']}.")
    lines += ["", "## Where", "",
              f"- nodes with at least half the largest error: {w['nodes']} "
              f"(s = {w['s_m'][0]:.3f} to {w['s_m'][1]:.3f} m), worst node {w['worst_node']}",
              f"- worst time window: {w['time_window_s'][0]:.2f} to {w['time_window_s'][1]:.2f} s; "
              f"error above tolerance from t = {w['onset_s']} s",
              f"- state group with the largest normalised error: {w['state_group']}",
              f"- missing terms do net work {w['net_work_missing_J']:.3g} J "
              f"(|P| integral {w['abs_work_missing_J']:.3g} J): **{w['character']}**", "",
              "## Selection (forward stepwise)", ""]
    for st in result["selection"]["steps"]:
        gains = ", ".join(f"{k} {g:.1f}" for k, g in st["residual_bic_gain"].items())
        lines.append(f"- model {st['model'] or '(nominal)'}: residual BIC gain per candidate: {gains}")
        for c in st["confirmation"]:
            lines.append(f"  - trajectory fit with {c['effect']}: RMSE {c['rmse']:.4f} rad, BIC gain "
                         f"{c['trajectory_delta_bic']:.1f}, {'accepted' if c['accepted'] else 'rejected'}")
    lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in files]
    lines += ["", f"Run time {result['timing_s']['total']:.1f} s "
              f"(GP smoothing {result['timing_s']['gp_smoothing']:.1f} s)."]
    return "\n".join(lines) + "\n"


def run_discovery(measured: str | Path, out_dir: str | Path, cfg: dict[str, Any]) -> dict[str, Any]:
    """Load, discover and write DIR/discovery.json, DIR/report.md and the figures."""
    st = DiscoverySettings.from_config(cfg)
    meas = load_measured(measured, st.min_rate_hz, st.min_samples)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    d = discover(meas, cfg, st)
    result = d["result"]
    files = _figures(out, d["arrays"], result)
    write_text(_report(result, files), out / "report.md")
    write_json(result, out / "discovery.json")  # last: its presence marks a complete run
    return result


# ------------------------------------------------------------------------------------------------
# hidden-effect data (rule family)
# ------------------------------------------------------------------------------------------------
class _PeriodicTipForce:
    """Nodal forces of the rod plus gravity plus a horizontal tip force F0 sin(2 pi f t).

    Out-of-library disturbance for the generator: the time is tracked by counting calls
    (``run_generic`` evaluates the force once at t = 0 and once per step after the drift).
    """

    def __init__(self, params: RodParams, theta_base: float, amplitude: float, freq: float, dt: float):
        self.params, self.theta_base = params, theta_base
        self.amp, self.omega, self.dt = amplitude, 2.0 * math.pi * freq, dt
        self.m_t = masses(params)[0]
        self.calls = 0

    def __call__(self, q: np.ndarray) -> np.ndarray:
        F, _ = internal_forces(q, self.params, self.theta_base)
        F[:, 1] -= self.m_t * self.params.g
        F[-1, 0] += self.amp * math.sin(self.omega * self.calls * self.dt)
        self.calls += 1
        return F


def simulate_truth(params: RodParams, theta0_deg: float, settings: SimSettings,
                   disturbance: dict[str, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Data-generating simulation (t, q); with a disturbance via ``run_generic``."""
    if not disturbance:
        tr = simulate(theta0_deg, params, settings)
        return tr.t, tr.q
    q0 = straight_rod(math.radians(theta0_deg), params)
    m_t, m_r = masses(params)
    lam_t, lam_r, k_quad = dissipation_coefficients(params)
    force = _PeriodicTipForce(params, float(q0[0, 2]), float(disturbance["tip_force_N"]),
                              float(disturbance["frequency_hz"]), settings.dt)
    out = run_generic(q0, np.zeros_like(q0), force, free_mask(params), m_t, m_r, lam_t, lam_r,
                      settings.dt, settings.n_steps, settings.record_every, k_quad=k_quad,
                      what="disturbed truth")
    return out.t, out.q


def case_seed(cfg: dict[str, Any], case: str) -> int:
    return (int(cfg["seed"]) * 1000003 + zlib.crc32(case.encode())) % (2**32)


def find_case(cfg: dict[str, Any], case: str) -> dict[str, Any]:
    for c in cfg["discovery"]["cases"]:
        if c["name"] == case:
            return c
    raise KeyError(f"discovery.cases has no case named {case!r}; "
                   f"known: {[c['name'] for c in cfg['discovery']['cases']]}")


def make_measured(cfg: dict[str, Any], case: str) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Camera data of one hidden-effect case and its truth record (kept in a separate file).

    The data simulator differs from the model: ``truth_refine`` times more segments and its
    own time step; the camera sees every ``truth_refine``-th node at ``sample_rate_hz`` with
    Gaussian noise ``noise_std_m`` on x and y.
    """
    d = cfg["discovery"]
    c = find_case(cfg, case)
    nominal = rod_params(cfg)
    refine_n = int(d["truth_refine"])
    p_truth = effect_params(nominal.replace(N=nominal.N * refine_n), c.get("effects", {}))
    period = 1.0 / float(d["sample_rate_hz"])
    n_samples = int(round(float(d["duration_s"]) / period)) + 1
    st = aligned_settings(p_truth, float(d["truth_dt_s"]), period, n_samples)
    t, q = simulate_truth(p_truth, float(d["theta0_deg"]), st, c.get("disturbance"))
    # effect size: the same data simulator without the hidden effect
    t0, q_ref = simulate_truth(nominal.replace(N=nominal.N * refine_n), float(d["theta0_deg"]),
                               aligned_settings(nominal.replace(N=nominal.N * refine_n),
                                                float(d["truth_dt_s"]), period, n_samples))
    effect_size = theta_rmse(q[:, ::refine_n], q_ref[:, ::refine_n])
    rng = np.random.default_rng(case_seed(cfg, case))
    frame = camera_frame(t, q, float(d["noise_std_m"]), rng, node_stride=refine_n)
    truth = {"case": case, "effects": dict(c.get("effects", {})), "disturbance": c.get("disturbance"),
             "effect_size_rmse_theta_rad": effect_size, "theta0_deg": float(d["theta0_deg"]),
             "truth_N": p_truth.N, "truth_dt_s": st.dt, "noise_std_m": float(d["noise_std_m"]),
             "sample_rate_hz": float(d["sample_rate_hz"]), "seed": case_seed(cfg, case),
             "rod": p_truth.to_dict()}
    return frame, truth


# ------------------------------------------------------------------------------------------------
# Snakemake entry points
# ------------------------------------------------------------------------------------------------
def rule_data(cfg: dict[str, Any], case: str, out: str, truth_out: str) -> None:
    """Rule ``discovery_data``: measured Parquet (positions only) + truth JSON (elsewhere)."""
    frame, truth = make_measured(cfg, case)
    write_json(truth, truth_out)
    write_parquet(frame, out, {"kind": "measured", "columns": "t [s], node, x [m], y [m]"})


def rule_discover(cfg: dict[str, Any], measured: str, out: str) -> None:
    """Rule ``discovery_run``: the workflow on one measured file (never reads the truth)."""
    run_discovery(measured, Path(out).parent, cfg)


def rule_summary(cfg: dict[str, Any], cases: list[str], truths: list[str], results: list[str],
                 out_csv: str, out_fig: str) -> None:
    """Rule ``discovery_summary``: hidden vs named effect table and the gap figure."""
    import json

    rows = []
    for case, tp, rp in zip(cases, truths, results, strict=True):
        truth = json.loads(Path(tp).read_text())
        res = json.loads(Path(rp).read_text())
        hidden = list(truth["effects"]) or (["disturbance"] if truth.get("disturbance") else [])
        named = [e["name"] for e in res["effects"]]
        top = res["effects"][0] if res["effects"] else None
        true_coef = truth["effects"].get(top["name"]) if top else None
        expected = ("effect_found" if truth["effects"] else
                    "unexplained" if truth.get("disturbance") else "none")
        rows.append({
            "case": case, "hidden": ";".join(hidden) or "none", "named": ";".join(named) or "none",
            "verdict": res["verdict"], "expected_verdict": expected,
            "correct": bool(res["verdict"] == expected and (not truth["effects"] or
                                                              (named and named[0] in truth["effects"]))),
            "coefficient_true": true_coef, "coefficient_est": top["coefficient"] if top else None,
            "coefficient_std": top["coefficient_std"] if top else None,
            "effect_size_rad": truth["effect_size_rmse_theta_rad"],
            "gap_before_rad": res["gap_before"], "gap_after_rad": res["gap_after"],
            "tip_gap_before": res["tip_gap_before"], "tip_gap_after": res["tip_gap_after"],
            "explained_fraction": res["explained_fraction"], "runtime_s": res["timing_s"]["total"],
        })
    df = pd.DataFrame(rows)
    write_csv(df, out_csv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(max(6, 0.9 * len(df)), 4), constrained_layout=True)
    x = np.arange(len(df))
    ax.bar(x - 0.2, df["gap_before_rad"], 0.4, color="C3", label="nominal model")
    ax.bar(x + 0.2, df["gap_after_rad"], 0.4, color="C0", label="after discovery")
    for i, r in df.iterrows():
        ax.text(i, max(r["gap_before_rad"], r["gap_after_rad"]) * 1.15, r["verdict"], ha="center",
                fontsize=7, va="bottom")
    ax.set_yscale("log")
    lo = float(np.nanmin(np.r_[df["gap_after_rad"], df["gap_before_rad"]]))
    ax.set_ylim(0.5 * lo, 8.0 * float(np.nanmax(df["gap_before_rad"])))
    ax.set_xticks(x, df["case"], rotation=30, ha="right")
    ax.set_ylabel("RMSE theta [rad]")
    ax.axhline(float(cfg["discovery"]["min_gap_rad"]), color="k", ls=":", lw=1, label="min_gap_rad")
    ax.set_title("Missing-physics discovery: the gap before and after adding the named effect")
    ax.legend(fontsize=8, loc="upper right", ncol=3)
    with atomic_path(out_fig, ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)


# ------------------------------------------------------------------------------------------------
# CLI
# ------------------------------------------------------------------------------------------------
def add_cli(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("discover", help="find, name and add missing physics from measured positions",
                       description="Compare camera positions of the rod with the nominal model of "
                                   "config.yaml, locate the disagreement, name the missing effect "
                                   "among the candidate library, add it and report the gap.")
    p.add_argument("--measured", required=True, help="Parquet file: t [s], node, x, y [m] (theta optional)")
    p.add_argument("--out", required=True, help="output directory (discovery.json, report.md, figures)")
    p.add_argument("--config", default=None,
                   help="config.yaml with the nominal model (default ./config.yaml)")
    p.set_defaults(func=_cli)
    g = sub.add_parser("discover-data", help="camera-like data of a hidden-effect case (for tests/demos)")
    g.add_argument("--case", required=True, help="name of a case in discovery.cases of the config")
    g.add_argument("--out", required=True, help="measured Parquet file to write")
    g.add_argument("--truth-out", required=True, help="truth JSON to write (keep it away from discover)")
    g.add_argument("--config", default=None)
    g.set_defaults(func=_cli_data)


def _cfg(path: str | None) -> dict[str, Any]:
    return load_config(path or "config.yaml")


def _cli(args: argparse.Namespace) -> None:
    res = run_discovery(args.measured, args.out, _cfg(args.config))
    print(f"verdict: {res['verdict']}; effects: {[e['name'] for e in res['effects']]}; gap "
          f"{res['gap_before']:.4f} -> {res['gap_after']:.4f} rad; written to {args.out}")


def _cli_data(args: argparse.Namespace) -> None:
    rule_data(_cfg(args.config), args.case, args.out, args.truth_out)


__all__ = ["discover", "run_discovery", "make_measured", "DiscoverySettings", "read_parquet"]
