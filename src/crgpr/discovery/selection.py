"""Missing-physics workflow: locate, name, add and verify a missing effect (beyond the paper).

Given screened camera markers (``crgpr.discovery.measured``), the rod kinematics they imply on
the model's grid (``crgpr.discovery.kinematics``) and the nominal model of config.yaml:

1. Locate. The nominal model is simulated from the measured initial state (GP-smoothed,
   projected onto an unstretched, unsheared rod, corrected by a short shooting fit; the
   record may start mid-motion) and compared with the data at the marker positions: RMSE of
   theta per marker and per time window, the state group with the largest normalised error,
   the sign of the net work of the missing terms from the port-Hamiltonian energy balance
   dH/dt = -H_z^T R H_z + P_missing (paper eq. (7)-(9)), and where along s the cut-moment
   residual sits.
2. Floor. The gap the nominal model shows with nothing missing: camera noise and initial-
   state uncertainty (parametric bootstrap: the nominal trajectory re-measured at the same
   markers, with the same missing samples and the GP's noise level, and fitted exactly as the
   data are) and the model's own
   discretisation error (the model fitted to the data on its grid and time step and on a
   grid twice as fine with half the step, each with its own initial state; the difference
   of the two fitted trajectories, Richardson-scaled by 4/3 for a second-order scheme), added
   in quadrature.
3. Name. The cut-moment residual of the data against the current model
   (``crgpr.discovery.residual``) is regressed on every candidate's signature; candidates enter
   by forward stepwise selection with the Bayesian information criterion of a heteroscedastic
   Gaussian model (one variance per segment and one for the clamp constraint), the sample
   size deflated by the integrated autocorrelation time of the residuals in time and along s;
   a candidate must lower BIC by ``bic_min_improvement`` (10: "very strong evidence", Kass and
   Raftery 1995) or rank high by its linearised trajectory evidence, and be confirmed by the
   joint trajectory fit of all named effects and the initial state (its BIC; its own effect
   size in that fit, the RMSE between the model with and without it, at least
   ``min_effect_fraction`` of the gap; and the same sign of its coefficient in the joint
   residual regression and in the trajectory fit). After each entry the other named effects
   are tested again in the joint model (backward elimination with the same BIC and size
   tests): an effect that entered as a proxy leaves. At the end each named effect is tried
   replaced by the candidates of its own place in the structure (``swap``): an effect that
   entered in place of a correlated one while the model was incomplete is exchanged.
   A model within ``min_gap_rad`` of its floor is "hidden" (``entry_threshold``): its fitted
   initial state may mimic an effect on a short record, so the search goes on with the
   candidates the initial-state-free cut-moment residual shows, each of which must be large
   enough to have put the gap over the "none" threshold by itself.
4. Verdict. ``effect_found`` if effects were named that close at least ``min_explained`` of
   the gap (of its excess over the floor when the nominal gap was hidden) AND leave no excess
   over the floor above ``max(min_gap_rad, max_remaining * excess)``; else ``none`` if the
   nominal gap's excess over the floor is below ``min_gap_rad``; otherwise ``unexplained``
   (no name is forced: a global effect that absorbs part of a disturbance it does not
   describe is reported as a partial attempt, with where the disturbance sits).
"""

from __future__ import annotations

import copy
import logging
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares, lsq_linear
from scipy.optimize._numdiff import approx_derivative  # least_squares' own differences

from crgpr.discovery.effects import EFFECT_NAMES, EFFECTS
from crgpr.discovery.kinematics import Kinematics, marker_matrix, marker_positions, smooth_kinematics
from crgpr.discovery.measured import Measured
from crgpr.discovery.residual import Residual, residual
from crgpr.discovery.synthetic import aligned_settings
from crgpr.physics.integrator import SimulationDiverged
from crgpr.physics.params import RodParams
from crgpr.physics.rod import masses, node_weights, segment_EI
from crgpr.physics.simulate import simulate

log = logging.getLogger(__name__)

STATE_GROUPS: tuple[str, ...] = ("x", "y", "theta", "p_x", "p_y", "p_theta")


@dataclass(frozen=True)
class DiscoverySettings:
    """Selection settings of the ``discovery`` config section (units in the names; the values
    live in config.yaml and its schema only)."""

    edge_trim_s: float
    init_window_s: float
    init_modes: int
    window_s: float
    min_gap_rad: float
    min_explained: float
    max_remaining: float
    min_effect_fraction: float
    max_confirm: int
    max_effects: int
    bic_min_improvement: float
    refine_max_nfev: int
    gp_max_points: int
    bootstrap_replicates: int
    seed: int

    @classmethod
    def from_config(cls, d: dict[str, Any], seed: int) -> DiscoverySettings:
        """From the ``discovery`` section ``d``; ``seed`` is the workflow's seed."""
        return cls(edge_trim_s=float(d["edge_trim_s"]), init_window_s=float(d["init_window_s"]),
                   init_modes=int(d["init_modes"]), window_s=float(d["window_s"]),
                   min_gap_rad=float(d["min_gap_rad"]), min_explained=float(d["min_explained"]),
                   max_remaining=float(d["max_remaining"]),
                   min_effect_fraction=float(d["min_effect_fraction"]), max_confirm=int(d["max_confirm"]),
                   max_effects=int(d["max_effects"]), bic_min_improvement=float(d["bic_min_improvement"]),
                   refine_max_nfev=int(d["refine_max_nfev"]), gp_max_points=int(d["gp_max_points"]),
                   bootstrap_replicates=int(d["bootstrap_replicates"]), seed=int(seed))


# ------------------------------------------------------------------------------------------------
# simulation helpers
# ------------------------------------------------------------------------------------------------
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


def rod_state_tangent(theta: np.ndarray, omega: np.ndarray, dtheta: np.ndarray, domega: np.ndarray,
                      params: RodParams) -> tuple[np.ndarray, np.ndarray]:
    """Derivatives (dq0, dv0) (m, N+1, 3) of ``rod_state`` at (theta, omega) along m directions
    (dtheta, domega) (m, N+1) of the nodal angles and rates."""
    tb = 0.5 * (theta[1:] + theta[:-1])
    wb = 0.5 * (omega[1:] + omega[:-1])
    dtb = 0.5 * (dtheta[:, 1:] + dtheta[:, :-1])
    dwb = 0.5 * (domega[:, 1:] + domega[:, :-1])
    seg = params.ds * params.nu1_0
    c, s = np.cos(tb), np.sin(tb)
    m = dtheta.shape[0]
    dq0 = np.zeros((m, params.N + 1, 3))
    dv0 = np.zeros((m, params.N + 1, 3))
    dq0[:, 1:, 0] = np.cumsum(-seg * s * dtb, axis=1)
    dq0[:, 1:, 1] = np.cumsum(seg * c * dtb, axis=1)
    dq0[:, :, 2] = dtheta
    dv0[:, 1:, 0] = np.cumsum(-seg * (dwb * s + wb * c * dtb), axis=1)
    dv0[:, 1:, 1] = np.cumsum(seg * (dwb * c - wb * s * dtb), axis=1)
    dv0[:, :, 2] = domega
    if params.clamped:
        dv0[:, 0, 2] = 0.0
    return dq0, dv0


def run_model(params: RodParams, q0: np.ndarray, v0: np.ndarray, period: float, n_samples: int,
              dt_max: float) -> np.ndarray:
    """Simulate ``params`` from (q0, v0); q (n_samples, N+1, 3) on the measured time grid."""
    st = aligned_settings(params, dt_max, period, n_samples)
    tr = simulate(math.degrees(q0[0, 2]), params, st, q0=q0, v0=v0)
    return tr.q[:n_samples]


def run_model_tangent(params: RodParams, q0: np.ndarray, v0: np.ndarray, dq0: np.ndarray, dv0: np.ndarray,
                      period: float, n_samples: int, dt_max: float) -> tuple[np.ndarray, np.ndarray]:
    """``run_model`` (the same q to the last bit) and the derivatives dq (n_samples, m, N+1, 3)
    of its records along the m initial-state directions (dq0, dv0) (tangent-linear scheme)."""
    st = aligned_settings(params, dt_max, period, n_samples)
    tr = simulate(math.degrees(q0[0, 2]), params, st, q0=q0, v0=v0, dq0=dq0, dv0=dv0)
    return tr.q[:n_samples], tr.dq[:n_samples]


def theta_rmse(qa: np.ndarray, qb: np.ndarray, M: np.ndarray) -> float:
    """RMSE of theta at the markers (interpolation matrix M) over all samples [rad]."""
    return float(np.sqrt(np.mean((qa[..., 2] @ M.T - qb[..., 2] @ M.T) ** 2)))


def tip_rmse_over_L(qa: np.ndarray, qb: np.ndarray, s_last: float, params: RodParams) -> float:
    """RMSE of the position of the outermost marker, over L0 [-]."""
    pa = marker_positions(qa, np.array([s_last]), params)[:, 0]
    pb = marker_positions(qb, np.array([s_last]), params)[:, 0]
    return float(np.sqrt(np.mean(np.sum((pa - pb) ** 2, axis=-1))) / params.L0)


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
    rate = rate + params.internal_damping / params.ds * (np.diff(v[..., 2], axis=-1) ** 2).sum(-1)
    return rate + (params.air_drag * w * sp2**1.5).sum(-1)


def time_windows(t: np.ndarray, window_s: float) -> list[tuple[float, float, np.ndarray]]:
    """Consecutive windows of about ``window_s`` covering t[0]..t[-1] (t from 0), each with its
    sample mask; the record is split into round(T / window_s) equal windows, so no window
    holds only the last sample (an arange of edges past t[-1] made a window [T, T] whose single
    end sample, where the GP derivatives are least reliable, was reported as the worst)."""
    n_win = max(1, int(round(float(t[-1]) / window_s)))
    edges = np.linspace(0.0, float(t[-1]), n_win + 1)
    out = []
    for i, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        sel = (t >= a) & ((t < b) if i < n_win - 1 else (t <= b))
        if sel.any():
            out.append((float(a), float(b), sel))
    return out


def local_stiffness_error(res: Residual, q_model: np.ndarray, params: RodParams, rows: slice
                          ) -> dict[str, Any]:
    """Where along s the bending law departs from the nominal one: a relative stiffness error
    d_j per segment (nominal EI_j too large by the fraction d_j), with its z-score.

    Per segment, the cut-moment residual rho_j = EI_j dk_j - mb_j^dyn is regressed on the
    measured elastic moment EI_j dk_j (a local version of ``stiffness_scale``'s signature).
    The measured curvature carries camera noise (errors in variables: near the free tip, where
    the true curvature vanishes, ordinary least squares returns d ~ 1 on effect-free data), so
    the regression uses the model's own curvature as the instrument (noise-free and
    independent of the camera noise): d_j = sum_t rho_j z_j / sum_t X_j z_j, z_j = EI_j k_j^model.
    Its standard error is deflated by the residual's autocorrelation time. Segment 0 (which
    needs the extrapolated base angle) is left out, as in the selection's regression. The
    peak is the segment of largest |d_j| / std_j; the extent, the segments above half of it.
    """
    y = res.rho[rows]
    X = res.sig["stiffness_scale"][rows]
    Z = segment_EI(params) * np.diff(q_model[rows, :, 2], axis=-1) / params.ds
    zx = np.sum(Z * X, axis=0)
    zx = np.where(np.abs(zx) > 0.0, zx, np.inf)
    d = np.sum(Z * y, axis=0) / zx
    r = y - X * d
    tau = _tau(r[:, 1:], 0)
    std = np.sqrt(np.mean(r**2, axis=0) * np.sum(Z * Z, axis=0) * tau) / np.abs(zx)
    z = np.where(std > 0, d / np.where(std > 0, std, 1.0), 0.0)
    z[0] = 0.0
    s_mid = (np.arange(params.N) + 0.5) * params.ds
    peak = int(np.argmax(np.abs(z)))
    strong = np.nonzero(np.abs(z) >= 0.5 * abs(z[peak]))[0]
    return {"s_mid_m": [float(v) for v in s_mid], "relative_error": [float(v) for v in d],
            "std": [float(v) for v in std], "z": [float(v) for v in z],
            "peak_s_m": float(s_mid[peak]), "peak_relative_error": float(d[peak]), "peak_z": float(z[peak]),
            "extent_s_m": [float(s_mid[strong].min()), float(s_mid[strong].max())]}


def locate(kin: Kinematics, q_nom: np.ndarray, v_nom: np.ndarray, params: RodParams,
           st: DiscoverySettings, theta_base: float, res: Residual, rows: slice) -> dict[str, Any]:
    """Where (markers, and the residual moment along s), when and in which state group the
    nominal model departs from the data."""
    t = kin.t - kin.t[0]
    M = marker_matrix(kin.s_markers, params)
    s_cmp = kin.s_markers[kin.s_markers > 1e-9]
    err = q_nom[..., 2] @ M.T - kin.q[..., 2] @ M.T
    per_marker = np.sqrt(np.mean(err**2, axis=0))
    windows = [(a, b, float(np.sqrt(np.mean(err[sel] ** 2)))) for a, b, sel in time_windows(t, st.window_s)]
    worst = max(windows, key=lambda w: w[2])
    onset = next((w for w in windows if w[2] > st.min_gap_rad), None)
    top = np.nonzero(per_marker >= 0.5 * per_marker.max())[0]
    groups = _group_nrmse(kin, q_nom, v_nom, params)
    # energy balance: P_missing = dH/dt + H_z^T R H_z, integrated over the trimmed record
    H = reduced_energy(kin, params, theta_base)
    D = nominal_dissipation_rate(kin, params)
    tt = t[rows]
    P = np.gradient(H[rows], tt) + D[rows]
    W = float(H[rows][-1] - H[rows][0] + np.trapezoid(D[rows], tt))
    absW = float(np.trapezoid(np.abs(P), tt))
    # the residual moment along s (where a disturbance acts, not where its effect shows)
    s_mid = (np.arange(params.N) + 0.5) * params.ds
    rho_rms = np.sqrt(np.mean(res.rho[rows] ** 2, axis=0))
    peak = int(np.argmax(rho_rms))
    strong = np.nonzero(rho_rms >= 0.5 * rho_rms[peak])[0]
    local = local_stiffness_error(res, q_nom, params, rows)
    return {
        "markers_s_m": [float(s_cmp[i]) for i in top],
        "s_m": [float(s_cmp[top].min()), float(s_cmp[top].max())],
        "worst_marker_s_m": float(s_cmp[int(np.argmax(per_marker))]),
        "time_window_s": [worst[0], worst[1]],
        "onset_s": None if onset is None else onset[0],
        "residual_moment_peak_s_m": float(s_mid[peak]),
        "residual_moment_s_m": [float(s_mid[strong].min()), float(s_mid[strong].max())],
        "residual_moment_rms_Nm": [float(v) for v in rho_rms],
        "local_stiffness_error": local,
        "local_stiffness_peak_s_m": local["peak_s_m"],
        # p_theta = rho I dtheta/dt is below camera resolution: reported, not chosen
        "state_group": max((g for g in groups if g != "p_theta"), key=groups.get),
        "group_nrmse": groups,
        "character": "dissipative" if W < 0 else "conservative",
        "net_work_missing_J": W,
        "abs_work_missing_J": absW,
        "rmse_theta_per_marker": [float(x) for x in per_marker],
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

    def __init__(self, params: RodParams, kin: Kinematics, dt_max: float, n_modes: int,
                 window_s: float):
        self.kin, self.dt_max, self.n_modes = kin, dt_max, n_modes
        self._set_grid(params)
        self.theta_m = kin.q[..., 2] @ self.M.T
        self.period = float(np.median(np.diff(kin.t)))
        self.n = len(kin.t)
        self.theta, self.omega, self.base = kin.q[0, :, 2], kin.v[0, :, 2], kin.q[0, 0, :2]
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

    def _init_jacobian(self, names: list[str], coef: np.ndarray, c: np.ndarray, n: int
                       ) -> tuple[np.ndarray, np.ndarray] | None:
        """Residual of ``_resid`` and its exact Jacobian with respect to the 2 n_modes initial-
        state corrections c, from one tangent-linear run (the derivative of this discrete
        model's theta at the markers; it replaces 2 n_modes finite-difference simulations,
        which were most of a fit's cost). None if the model diverges or is not finite."""
        m = self.n_modes
        theta = self.theta + self.P @ c[:m]
        omega = self.omega + self.w_scale * (self.P @ c[m:])
        q0, v0 = rod_state(theta, omega, self.base, self.params)
        zero = np.zeros((m, self.params.N + 1))
        dth = np.concatenate([self.P.T, zero])
        dom = np.concatenate([zero, self.w_scale * self.P.T])
        dq0, dv0 = rod_state_tangent(theta, omega, dth, dom, self.params)
        try:
            q, dq = run_model_tangent(augmented_params(self.params, names, coef), q0, v0, dq0, dv0,
                                      self.period, n, self.dt_max)
        except SimulationDiverged:
            return None
        r = (q[..., 2] @ self.M.T - self.theta_m[:n]).ravel()
        J = np.einsum("taj,mj->tma", dq[..., 2], self.M).reshape(r.size, 2 * m)
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(J))):
            return None
        return r, J

    def _jacobian(self, names: list[str], x: np.ndarray, n_coef: int, bounds: tuple[np.ndarray, np.ndarray],
                  n: int, rel_step: float) -> np.ndarray:
        """Jacobian of the theta residual at x = [coefficients (n_coef), corrections]: the
        coefficient columns by the same forward differences ``least_squares`` takes (same
        steps, bounds and base residual, so the same numbers), the correction columns exact
        (``_init_jacobian``). Falls back to differences for all columns if the model
        diverges."""
        coef, c = x[:n_coef], x[n_coef:]
        tan = self._init_jacobian(names, coef, c, n)
        if tan is None:
            return approx_derivative(lambda y: self._resid(names, y[:n_coef], y[n_coef:], n), x,
                                     method="2-point", rel_step=rel_step,
                                     bounds=(np.concatenate([bounds[0], np.full(c.size, -np.inf)]),
                                             np.concatenate([bounds[1], np.full(c.size, np.inf)])))
        r0, Jc = tan
        if not n_coef:
            return Jc
        Jk = approx_derivative(lambda y: self._resid(names, y, c, n), coef, method="2-point",
                               rel_step=rel_step, f0=r0, bounds=bounds)
        return np.concatenate([np.atleast_2d(Jk).reshape(r0.size, n_coef), Jc], axis=1)

    def _resid(self, names: list[str], coef: np.ndarray, c: np.ndarray, n: int) -> np.ndarray:
        try:
            q = self.simulate(names, coef, c, n)
        except SimulationDiverged:
            return np.full(n * self.M.shape[0], 10.0)
        r = (q[..., 2] @ self.M.T - self.theta_m[:n]).ravel()
        return r if np.all(np.isfinite(r)) else np.full(r.size, 10.0)

    def score(self, base: TrajectoryFit, k: str) -> float:
        """Linearised trajectory evidence for adding candidate ``k`` to the model ``base``:
        the Gauss-Newton decrease of the theta residual sum of squares, (J^T r)^2 / J^T J,
        with J the finite-difference sensitivity to a small step of k (``Effect.probe``; 0 if
        the step that would help points out of k's admissible range)."""
        e = EFFECTS[k]
        names = base.names + [k]
        try:
            q1 = self.simulate(names, np.concatenate([base.coef, [e.probe]]), base.init)
        except SimulationDiverged:
            return 0.0
        J = ((q1[..., 2] - base.q[..., 2]) @ self.M.T).ravel() / e.probe
        r = (self.theta_m - base.q[..., 2] @ self.M.T).ravel()
        jj = float(J @ J)
        if jj <= 0.0:
            return 0.0
        step = float(J @ r) / jj
        if (step < 0.0 and e.reg_lo >= 0.0) or (step > 0.0 and e.reg_hi <= 0.0):
            return 0.0
        return float(J @ r) ** 2 / jj

    def _window_fit(self, names: list[str] | None = None, coef: np.ndarray | None = None,
                    c0: np.ndarray | None = None, n: int | None = None) -> np.ndarray:
        """Initial-state corrections of a model (coefficients fixed) from its fit to the first
        window, or to the first ``n`` samples."""
        names = names or []
        coef = np.zeros(0) if coef is None else coef
        c0 = np.zeros(2 * self.n_modes) if c0 is None else c0
        n = self.window if n is None else n
        def jac(c: np.ndarray) -> np.ndarray:
            tan = self._init_jacobian(names, coef, c, n)
            if tan is None:
                return approx_derivative(lambda y: self._resid(names, coef, y, n), c,
                                         method="2-point", rel_step=1e-4)
            return tan[1]

        sol = least_squares(lambda c: self._resid(names, coef, c, n), c0, x_scale=0.01, jac=jac,
                            max_nfev=10 * (2 * self.n_modes + 1))
        return sol.x

    def on_grid(self, grid: RodParams, theta: np.ndarray, omega: np.ndarray,
                dt_max: float) -> TrajectoryFitter:
        """The same fit (markers, measured theta, time grid, correction modes) of the rod
        ``grid`` (another N) with time step at most ``dt_max``, from the initial nodal angles
        and rates ``theta``, ``omega`` (N_grid + 1) instead of the measured ones."""
        g = copy.copy(self)
        g._set_grid(grid)
        g.theta, g.omega, g.dt_max = np.asarray(theta, float), np.asarray(omega, float), dt_max
        return g

    def _set_grid(self, params: RodParams) -> None:
        """The rod and what depends on its grid: the marker matrix (the model is compared at
        the markers) and the Legendre modes of the initial-state corrections."""
        self.params = params
        self.M = marker_matrix(self.kin.s_markers, params)
        xs = 2.0 * params.s / params.L0 - 1.0
        self.P = np.stack([np.polynomial.legendre.Legendre.basis(k)(xs) for k in range(self.n_modes)], axis=1)

    def fit(self, names: list[str], x0: np.ndarray, x_std: np.ndarray, max_nfev: int,
            rounds: int = 1) -> TrajectoryFit:
        """Coefficients and initial-state corrections by least squares of theta over the whole
        record (full shooting, the maximum-likelihood estimate for white theta errors).

        Start: the window fit of the initial state and the coefficient fit over the record,
        alternated ``rounds`` times; then both are polished jointly over the whole record. The
        window fit alone pins the initial rates poorly (GP derivatives at the record start,
        few markers): on a tapered rod it left 0.060 rad with the true taper's model and 0.047
        rad on effect-free data seen by 7 markers, where the joint fit leaves 0.016 and 0.026.
        Every model (the nominal one and the bootstrap's included) is fitted the same way, so
        an effect that an initial state can mimic lowers the gap and the floor alike.
        """
        k = len(names)
        m2 = 2 * self.n_modes
        lo = np.array([EFFECTS[e].reg_lo for e in names])
        hi = np.array([EFFECTS[e].reg_hi for e in names])
        # a base spring must stay integrable with a sensible step: k <= 20 N m/rad
        lo = np.where(np.array(names, dtype=object) == "base_compliance", np.maximum(lo, 0.05), lo)
        coef = np.minimum(np.maximum(np.asarray(x0, float), lo), hi)
        scale = np.where(np.isfinite(x_std) & (x_std > 0), x_std, np.maximum(np.abs(coef), 1e-6))
        scale = np.maximum(scale, 1e-3 * np.abs(coef))
        # an ill-determined start (huge std) must not send the first step out of the physical range
        probe = np.array([EFFECTS[e].probe for e in names])
        scale = np.minimum(scale, 10.0 * np.maximum(np.abs(coef), probe))
        calls = [0]
        c = self.c_start
        for _ in range(rounds if k else 0):
            c = self._window_fit(names, coef, c)

            def fun(x: np.ndarray, c=c) -> np.ndarray:
                calls[0] += 1
                return self._resid(names, x, c, self.n)

            sol = least_squares(fun, coef, bounds=(lo, hi), x_scale=scale, diff_step=1e-3,
                                max_nfev=max_nfev)
            coef = sol.x
        if k:
            c = self._window_fit(names, coef, c)

        def joint(x: np.ndarray) -> np.ndarray:
            calls[0] += 1
            return self._resid(names, x[:k], x[k:], self.n)

        x_init = np.concatenate([coef, c])
        with np.errstate(invalid="ignore"):  # strictly inside finite bounds (trf needs it)
            lo_in = np.where(np.isfinite(lo), lo + 1e-9 * np.maximum(np.abs(lo), 1e-6), lo)
            hi_in = np.where(np.isfinite(hi), hi - 1e-9 * np.maximum(np.abs(hi), 1e-6), hi)
        x_init[:k] = np.clip(x_init[:k], lo_in, hi_in)
        def joint_jac(x: np.ndarray) -> np.ndarray:
            calls[0] += 1 + k  # one tangent-linear run and k coefficient differences
            return self._jacobian(names, x, k, (lo, hi), self.n, 1e-4)

        sol = least_squares(joint, x_init, bounds=(np.concatenate([lo, np.full(m2, -np.inf)]),
                                                   np.concatenate([hi, np.full(m2, np.inf)])),
                            x_scale=np.concatenate([scale, np.full(m2, 0.01)]), jac=joint_jac,
                            max_nfev=max(3, max_nfev // 4))  # each step: 1 + k simulations, 1 tangent run
        coef, c = sol.x[:k], sol.x[k:]
        r = sol.fun.reshape(self.n, -1)
        tau = _tau(r, 0) * _tau(r, 1)
        std = np.zeros(k)
        if k:
            try:  # covariance of the joint estimate (initial state included), deflated sample
                cov = np.linalg.pinv(sol.jac.T @ sol.jac) * float(np.mean(sol.fun**2)) * tau
                std = np.sqrt(np.maximum(np.diag(cov)[:k], 0.0))
            except np.linalg.LinAlgError:
                std = np.full(k, np.inf)
        q0, v0 = self.state(c)
        q = self.simulate(names, coef, c)
        r = (q[..., 2] @ self.M.T - self.theta_m).ravel()
        return TrajectoryFit(list(names), coef, std, c, q, q0, v0, float(np.sum(r**2)), r.size, tau,
                             calls[0])

    def effect_size(self, fit: TrajectoryFit, k: str) -> float:
        """RMSE of theta at the markers between a fitted model and the same model without
        effect ``k`` (same initial state, the other coefficients unchanged) [rad]: the effect's
        own size in the joint fit, which a marginal RMSE decrease understates when candidates
        are correlated (a stiffer rod and a lighter tip mass both shift the frequency)."""
        i = fit.names.index(k)
        try:
            q = self.simulate([n for n in fit.names if n != k], np.delete(fit.coef, i), fit.init)
        except SimulationDiverged:
            return math.inf
        return theta_rmse(q, fit.q, self.M)


# ------------------------------------------------------------------------------------------------
# step 2b: the floor (noise, initial state, discretisation)
# ------------------------------------------------------------------------------------------------
def noise_floor(q_model: np.ndarray, meas: Measured, kin: Kinematics, params: RodParams, dt_max: float,
                st: DiscoverySettings) -> float:
    """Gap the nominal model would show from camera noise and initial-state uncertainty.

    Parametric bootstrap: the nominal trajectory re-measured at the same markers with the
    GP's noise estimate and the same missing samples, smoothed, and the nominal model fitted
    exactly as to the data (``TrajectoryFitter.fit``); the RMS of the resulting theta gaps.
    """
    rng = np.random.default_rng(st.seed + 99)
    valid = meas.valid
    pos = marker_positions(q_model, meas.s, params)
    gaps = []
    for r in range(st.bootstrap_replicates):
        noisy = pos + kin.noise_std_m * rng.standard_normal(pos.shape)
        x = np.where(valid, noisy[..., 0], np.nan)
        y = np.where(valid, noisy[..., 1], np.nan)
        mb = Measured(meas.t, meas.s, x, y, "bootstrap", meas.missing_fraction, np.zeros_like(valid))
        kin_b = smooth_kinematics(mb, params, seed=st.seed + 100 + r, max_points=st.gp_max_points)
        fb = TrajectoryFitter(params, kin_b, dt_max, n_modes=st.init_modes, window_s=st.init_window_s)
        gaps.append(fb.fit([], np.zeros(0), np.zeros(0), st.refine_max_nfev).rmse)
    return float(np.sqrt(np.mean(np.square(gaps)))) if gaps else 0.0


def discretisation_error(fitter: TrajectoryFitter, dt_max: float, names: tuple[str, ...] = (),
                         coef: np.ndarray | None = None, c0: np.ndarray | None = None,
                         degree: int = 5) -> float:
    """Estimated theta error of the model's own discretisation (grid and time step), as it
    shows in the gap after fitting [rad].

    The model (``names``, ``coef``) is fitted to the measured theta at the markers twice: on
    its grid N with its time step, and on a grid 2N with half that step, each with its own
    initial state: the same smooth base state (the measured nodal angles and rates at the
    first sample projected on polynomials of ``degree`` in s, so that camera noise does not
    excite grid-dependent high modes) and its own initial-state corrections fitted over the
    whole record (coefficients fixed, start ``c0``, e.g. the model's fitted corrections).
    The difference of the two fitted trajectories is what refining the discretisation changes
    in the best fit; for a scheme of second order in space and time (variational
    discretisation, Strang-split Verlet) e ~ (4/3) |q_(N,dt) - q_(2N,dt/2)| (Richardson). Both
    grids see the same data, so an initial rate that a fit invented to mimic a missing effect
    is not propagated into the estimate (one fitted state run on both grids gave 6-10x the
    error from the exact release on tip mass plus drag). The time step matters where the
    model is stiff (Kelvin-Voigt damping, full config: 0.0078 rad with the step halved,
    0.0025 with the grid alone; 0.0077 from the noise-free data-generating simulation)."""
    coef = np.zeros(0) if coef is None else np.asarray(coef, float)
    c0 = np.zeros(2 * fitter.n_modes) if c0 is None else np.asarray(c0, float)
    s = fitter.params.s
    deg = min(degree, fitter.params.N - 1)
    th = np.polynomial.Polynomial.fit(s, fitter.theta, deg)
    om = np.polynomial.Polynomial.fit(s, fitter.omega, deg)
    runs = []
    dt_model = aligned_settings(augmented_params(fitter.params, list(names), coef), dt_max, fitter.period,
                                fitter.n).dt
    for n_grid, dt_grid in ((fitter.params.N, dt_max), (2 * fitter.params.N, 0.5 * dt_model)):
        grid = fitter.params.replace(N=n_grid)
        g = fitter.on_grid(grid, th(grid.s), om(grid.s), dt_grid)
        try:
            c = g._window_fit(list(names), coef, c0, n=fitter.n)
            runs.append(g.simulate(list(names), coef, c)[..., 2] @ g.M.T)
        except SimulationDiverged:
            return 0.0
    return float(4.0 / 3.0 * np.sqrt(np.mean((runs[0] - runs[1]) ** 2)))


def trajectory_delta_bic(small: TrajectoryFit, big: TrajectoryFit) -> float:
    """BIC(small) - BIC(big) for theta residuals with the sample size deflated by big's tau."""
    n_eff = big.n / max(big.tau, 1.0)
    dp = len(big.names) - len(small.names)
    return n_eff * math.log(max(small.rss, 1e-300) / max(big.rss, 1e-300)) - dp * math.log(n_eff)


def entry_threshold(rmse: float, floor: float, gap_before: float, st: DiscoverySettings
                    ) -> tuple[bool, float]:
    """(hidden, least effect size [rad]) for a candidate entering a model with theta RMSE
    ``rmse`` and floor ``floor``.

    ``hidden``: the model, with its own fitted initial state, is within ``min_gap_rad`` of its
    floor. On a short record the initial state mimics much of an effect (0.8 s of viscous drag:
    0.099 rad from the true release, 0.018 rad from the fitted initial state), so a small gap
    does not show that nothing is missing; the cut-moment residual, which needs no initial
    state, still does. A hidden effect must be large enough that it alone would have put the
    gap over the "none" threshold: its own size (with vs without it, same initial state)
    >= hypot(floor, min_gap_rad). Otherwise an effect's size must be >= min_effect_fraction of
    the nominal gap ``gap_before``."""
    hidden = math.sqrt(max(rmse**2 - floor**2, 0.0)) <= st.min_gap_rad
    return hidden, (math.hypot(floor, st.min_gap_rad) if hidden else st.min_effect_fraction * gap_before)


def eliminate(fitter: TrajectoryFitter, cur: TrajectoryFit, keep: str, gap_before: float,
              st: DiscoverySettings) -> tuple[TrajectoryFit, list[dict[str, Any]]]:
    """Backward elimination after a candidate entered (nested-model test on the joint fit).

    Every other named effect is tested in the model that now holds them all: the model is
    refitted without it (all remaining coefficients and the initial state free) and the effect
    stays only if it still lowers BIC by ``bic_min_improvement`` and its own size in the joint
    fit is at least ``min_effect_fraction`` of the gap, the tests it had to pass to enter. The
    weakest failing effect is dropped first and the test repeated. An effect that entered early
    as a proxy for two true ones (a rest curvature for a tip mass plus drag) leaves once both
    are named. ``keep`` (the effect that just entered) is not tested again."""
    records: list[dict[str, Any]] = []
    while len(cur.names) > 1:
        worst = None
        for k in cur.names:
            if k == keep:
                continue
            i = cur.names.index(k)
            size = fitter.effect_size(cur, k)
            red = fitter.fit([n for n in cur.names if n != k], np.delete(cur.coef, i), np.delete(cur.std, i),
                             st.refine_max_nfev)
            dbic = trajectory_delta_bic(red, cur)
            stays = dbic >= st.bic_min_improvement and size >= st.min_effect_fraction * gap_before
            rec = {"effect": k, "model": list(cur.names), "trajectory_delta_bic": dbic,
                   "effect_size_rad": size,
                   "rmse_without": red.rmse, "dropped": False}
            records.append(rec)
            log.info("elimination %s from %s: delta BIC %.1f, size %.4f, stays %s", k, cur.names, dbic, size,
                     stays)
            if not stays and (worst is None or dbic < worst[0]):
                worst = (dbic, red, rec)
        if worst is None:
            break
        worst[2]["dropped"] = True
        cur = worst[1]
    return cur, records


def swap(fitter: TrajectoryFitter, cur: TrajectoryFit, reg0: Regression, excluded: set[str],
         size_min: float, st: DiscoverySettings) -> tuple[TrajectoryFit, list[dict[str, Any]]]:
    """Replacement step of stepwise selection (Miller, Subset Selection in Regression, 2002,
    Sec. 3.5): each named effect is tried replaced by every candidate of the same place in the
    structure (``Effect.place``: the dissipative R terms among themselves, the H terms among
    themselves), all coefficients and the initial state refitted. Forward selection fixes the
    order of entry while the model is still incomplete: three_effects' drag entered as air_drag
    beside a tip mass at half its value, when viscous_drag's linearised score was lower; once
    the stiffness and the tip mass are named, the right drag fits better. The best replacement
    that lowers the trajectory BIC by ``bic_min_improvement`` (same number of parameters: the
    RSS ratio alone) and passes the entry tests (own size >= ``size_min``, the same sign in the
    joint residual regression) is made, and the search repeated; an effect replaced is not
    offered again."""
    records: list[dict[str, Any]] = []
    gone = set(excluded)
    fitted: dict[frozenset[str], tuple[TrajectoryFit, float, float]] = {}  # a model is fitted once
    while True:
        best = None
        for i, k in enumerate(cur.names):
            for j in EFFECT_NAMES:
                if j in cur.names or j in gone or EFFECTS[j].place != EFFECTS[k].place:
                    continue
                names = cur.names[:i] + [j] + cur.names[i + 1:]
                if frozenset(names) not in fitted:
                    jr = reg0.fit(names)  # initial-state-free start for the newcomer
                    c_j = float(jr.coef[i])
                    if c_j == 0.0 and EFFECTS[j].reg_lo == 0.0:
                        c_j = max(float(jr.std[i]), 1e-6)
                    x0 = cur.coef.copy()
                    x0[i] = c_j
                    xs = cur.std.copy()
                    xs[i] = float(jr.std[i])
                    cand = fitter.fit(names, x0, xs, st.refine_max_nfev)
                    fitted[frozenset(names)] = (cand, fitter.effect_size(cand, j), float(jr.coef[i]))
                cand, size, c_reg = fitted[frozenset(names)]
                i_c = cand.names.index(j)
                dbic = trajectory_delta_bic(cur, cand)
                agrees = c_reg * float(cand.coef[i_c]) > 0.0
                ok = dbic >= st.bic_min_improvement and size >= size_min and agrees
                records.append({"out": k, "in": j, "model": list(cur.names), "rmse": cand.rmse,
                                "trajectory_delta_bic": dbic, "effect_size_rad": size,
                                "joint_residual_coefficient": c_reg,
                                "trajectory_coefficient": float(cand.coef[i_c]), "signs_agree": agrees,
                                "swapped": False})
                log.info("swap %s -> %s in %s: RMSE %.4f, delta BIC %.1f, size %.4f, acceptable %s", k, j,
                         cur.names, cand.rmse, dbic, size, ok)
                if ok and (best is None or cand.rss < best[0].rss):
                    best = (cand, records[-1], k)
        if best is None:
            return cur, records
        best[1]["swapped"] = True
        gone.add(best[2])
        cur = best[0]


def alternatives(swaps: list[dict[str, Any]], names: list[str], size_min: float, st: DiscoverySettings
                 ) -> list[dict[str, Any]]:
    """Replacements (``swap`` records) that the data do not tell apart from the named model
    ``names``: tried in that model, passing the entry tests (own size >= ``size_min``, signs
    agree) with |delta BIC| < ``bic_min_improvement``. Reported beside the named effects, not
    instead of them (three_effects, full config: viscous_drag for air_drag at RMSE 0.0134 vs
    0.0128 rad, delta BIC -9.6, both below the floor 0.0226)."""
    return [{"named": w["out"], "alternative": w["in"], "trajectory_delta_bic": w["trajectory_delta_bic"],
             "rmse": w["rmse"]} for w in swaps
            if names and w["model"] == list(names) and not w["swapped"] and w["signs_agree"]
            and abs(w["trajectory_delta_bic"]) < st.bic_min_improvement and w["effect_size_rad"] >= size_min]


# ------------------------------------------------------------------------------------------------
# the whole workflow
# ------------------------------------------------------------------------------------------------
def check_extent(meas: Measured, params: RodParams) -> None:
    """The markers must lie on a rod of the configured length (raises ValueError)."""
    if meas.s[-1] < 0.25 * params.L0:
        raise ValueError(f"{meas.source}: the outermost marker is at s = {meas.s[-1]:.3g} m; markers must "
                         f"cover at least a quarter of rod.L0 = {params.L0:g} m")


def discover(meas: Measured, params: RodParams, dt_max: float, st: DiscoverySettings) -> dict[str, Any]:
    """Run the workflow on screened measured data; returns the result dict (and arrays).

    ``params`` is the nominal model (its own grid), ``dt_max`` its time step [s]."""
    t_start = time.perf_counter()
    check_extent(meas, params)
    kin = smooth_kinematics(meas, params, seed=st.seed, max_points=st.gp_max_points)
    t_smooth = time.perf_counter() - t_start
    period = float(np.median(np.diff(kin.t)))
    n = len(kin.t)
    fitter = TrajectoryFitter(params, kin, dt_max, n_modes=st.init_modes, window_s=st.init_window_s)
    M = fitter.M
    nominal = fitter.fit([], np.zeros(0), np.zeros(0), st.refine_max_nfev)
    q_nom = nominal.q
    theta_b = float(nominal.q0[0, 2])
    tr = simulate(math.degrees(theta_b), params, aligned_settings(params, dt_max, period, n),
                  q0=nominal.q0, v0=nominal.v0)
    v_nom = tr.p[:n] / np.array([params.rhoA, params.rhoA, params.rhoI])
    gap_before = theta_rmse(q_nom, kin.q, M)
    s_last = float(kin.s_markers[-1])
    tip_before = tip_rmse_over_L(q_nom, kin.q, s_last, params)
    f_noise = noise_floor(q_nom, meas, kin, params, dt_max, st)
    f_disc = discretisation_error(fitter, dt_max, c0=nominal.init)
    floor = math.hypot(f_noise, f_disc)
    floors: dict[tuple[str, ...], float] = {(): floor}  # by names and coefficients

    def floor_of(fit: TrajectoryFit) -> float:
        """Floor of a named model: the same noise part, its own discretisation error."""
        key = tuple(fit.names) + tuple(f"{c:.4g}" for c in fit.coef)
        if key not in floors:
            disc = discretisation_error(fitter, dt_max, tuple(fit.names), fit.coef, fit.init)
            floors[key] = math.hypot(f_noise, disc)
        return floors[key]
    excess = math.sqrt(max(gap_before**2 - floor**2, 0.0))
    hidden_nominal = excess <= st.min_gap_rad
    trim = max(1, int(round(st.edge_trim_s / period)))
    rows = slice(trim, n - trim)
    theta_b0 = float(kin.q[0, 0, 2])
    res0 = residual(kin.q, kin.v, kin.a, params, theta_b0, kin.base_segment_angle)
    where = locate(kin, q_nom, v_nom, params, st, theta_b, res0, rows)
    # name: forward stepwise on the port-Hamiltonian residual; at each step the residual is
    # taken against the current (augmented) model, the remaining candidates are ranked and
    # the best ones are confirmed in turn by the joint trajectory fit (BIC of theta, effect
    # size >= min_effect_fraction of the gap, signs), then backward elimination
    cur = nominal
    accepted: list[TrajectoryFit] = []
    steps: list[dict[str, Any]] = []
    single: dict[str, Fit] = {}
    dropped: set[str] = set()  # removed by backward elimination: not offered again
    reg0 = Regression(res0, rows)
    while True:
        p_cur = augmented_params(params, cur.names, cur.coef)
        reg = reg0 if not cur.names else Regression(
            residual(kin.q, kin.v, kin.a, p_cur, theta_b0, kin.base_segment_angle), rows,
            candidates=tuple(k for k in EFFECT_NAMES if k not in cur.names and k not in dropped))
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
        # a model at its floor (hidden: the fitted initial state may mimic an effect) tries only
        # the candidates the initial-state-free cut-moment residual shows (BIC gain >=
        # bic_min_improvement), the best max_confirm by trajectory score
        hidden, size_min = entry_threshold(cur.rmse, floor_of(cur) if cur.names else floor, gap_before, st)
        step["hidden_by_initial_state"] = hidden
        pool = [r for r in ranked if r[0] >= st.bic_min_improvement] if hidden else ranked
        if not pool:
            break
        step["min_effect_size_rad"] = size_min
        added = False
        # order: the candidates the residual shows (BIC gain >= bic_min_improvement) ranked
        # together with all others by their linearised trajectory evidence (the residual of
        # noisy accelerations can misrank correlated stiffness candidates); the first
        # max_confirm are confirmed by full trajectory fits, the rest only if none holds up
        scores = {k: fitter.score(cur, k) for _, k, _ in pool}
        step["trajectory_score"] = scores
        order = sorted(pool, key=lambda r: -scores[r[1]])
        screened = order[:st.max_confirm]
        # all others are fitted if the screened ones fail: the linearised score is local (a
        # frequency-changing effect's response is far from linear once the phase error is
        # large: on the mid-motion camera record tip_mass scored 0, pointing out of range,
        # and was the effect); not when hidden (the gap is small, the linearisation holds)
        rest = [] if hidden else order[st.max_confirm:]
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
                if cand.rmse >= cur.rmse:  # a poor regression start: start from the current model
                    x1 = np.concatenate([cur.coef, [0.0 if EFFECTS[k].reg_lo < 0.0 else 1e-6]])
                    retry = fitter.fit(names, x1, xs, st.refine_max_nfev)
                    cand = retry if retry.rss < cand.rss else cand
                dbic = trajectory_delta_bic(cur, cand)
                # practical significance: the effect's own size in the joint fit (its marginal
                # RMSE decrease understates it when candidates are correlated)
                size = fitter.effect_size(cand, k)
                closes = size >= size_min
                # the two independent estimates of the same joint model must agree in sign:
                # a candidate whose cut-moment regression coefficient (all named effects
                # regressed jointly on the nominal residual) is opposite, or at its bound,
                # while the trajectory fit wants it is a global effect absorbing a disturbance
                # it does not describe
                joint_reg = reg0.fit(names)
                agrees = float(joint_reg.coef[-1]) * float(cand.coef[-1]) > 0.0
                ok = dbic >= st.bic_min_improvement and closes and agrees
                step["confirmation"].append({"effect": k, "residual_bic_gain": gain, "rmse": cand.rmse,
                                             "trajectory_delta_bic": dbic, "accepted": False,
                                             "effect_size_rad": size,
                                             "residual_coefficient": float(f.coef[0]),
                                             "joint_residual_coefficient": float(joint_reg.coef[-1]),
                                             "trajectory_coefficient": float(cand.coef[-1]),
                                             "signs_agree": agrees, "nfev": cand.nfev})
                log.info("trajectory fit %s: RMSE %.4f, delta BIC %.1f, size %.4f, acceptable %s", names,
                         cand.rmse, dbic, size, ok)
                if ok and (best is None or cand.rss < best[0].rss):
                    best = (cand, len(step["confirmation"]) - 1)
            if best is not None:  # the best confirmed candidate of the group enters
                cur = best[0]
                step["confirmation"][best[1]]["accepted"] = True
                added = True
                break
        if added:
            cur, step["elimination"] = eliminate(fitter, cur, cur.names[-1], gap_before, st)
            dropped.update(e["effect"] for e in step["elimination"] if e["dropped"])
            accepted.append(cur)
        if not added or len(cur.names) >= st.max_effects:
            break
    swaps: list[dict[str, Any]] = []
    size_min_final = entry_threshold(gap_before, floor, gap_before, st)[1]
    if accepted:
        cur, swaps = swap(fitter, cur, reg0, dropped, size_min_final, st)
        if cur is not accepted[-1]:
            accepted.append(cur)
    result: dict[str, Any] = {
        "measured": meas.source, "input": meas.summary(), "n_samples": n,
        "n_markers_compared": int(M.shape[0]), "model_N": params.N,
        "sample_rate_hz": 1.0 / period, "gp_noise_std_m": kin.noise_std_m,
        "gap_before": gap_before, "tip_gap_before": tip_before, "gap_floor": floor,
        "gap_floor_noise": f_noise, "gap_floor_discretisation": f_disc,
        "gap_excess_over_floor": excess,
        "hidden_by_initial_state": hidden_nominal,
        "initial_state_fit": {"modes": st.init_modes, "nominal_corrections": nominal.init.tolist()},
        "selection": {"criterion": "forward stepwise BIC on the port-Hamiltonian residual "
                                   "(heteroscedastic, autocorrelation-deflated), each step confirmed "
                                   "by the trajectory fit's BIC",
                      "bic_min_improvement": st.bic_min_improvement,
                      "tau_time": reg0.tau_t, "tau_s": reg0.tau_s, "tau_base": reg0.tau_b,
                      "n_eff": reg0.n_eff, "steps": steps, "swaps": swaps},
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
        remaining = math.sqrt(max(fit.rmse**2 - floor_of(fit) ** 2, 0.0))
        excess_frac = 1.0 - remaining / excess if excess > 0 else (1.0 if remaining == 0.0 else 0.0)
        best_attempt = {"effects": attempt, "gap_after": fit.rmse, "explained_fraction": frac,
                        "explained_excess_fraction": excess_frac,
                        "remaining_excess": remaining, "gap_floor": floor_of(fit)}
        # an effect hidden by the initial state (nominal gap within min_gap_rad of the floor)
        # cannot close half of a gap that is mostly floor: there it must close half the excess
        closes = excess_frac >= st.min_explained if hidden_nominal else frac >= st.min_explained
        if closes and remaining <= max(st.min_gap_rad, st.max_remaining * excess):
            effects, q_aug = attempt, fit.q
    if effects:
        verdict = "effect_found"
    elif hidden_nominal:
        verdict = "none"
    else:
        verdict = "unexplained"
    gap_after = theta_rmse(q_aug, kin.q, M)
    result.update({
        "effects": effects, "verdict": verdict, "gap_after": gap_after,
        "tip_gap_after": tip_rmse_over_L(q_aug, kin.q, s_last, params),
        "explained_fraction": 1.0 - gap_after / gap_before if gap_before > 0 else 0.0,
        # share of the excess over the floor closed (floor, excess and remainder in quadrature)
        "explained_excess_fraction": (1.0 - math.sqrt(max(gap_after**2 - floor**2, 0.0)) / excess
                                      if excess > 0 else 0.0),
        "where": where, "best_attempt": best_attempt,
        "indistinguishable_alternatives": alternatives(swaps, [e["name"] for e in effects], size_min_final,
                                                       st),
        "significant_but_below_tolerance": [k for k, g in steps[0]["residual_bic_gain"].items()
                                            if g >= st.bic_min_improvement] if verdict == "none" else [],
        "timing_s": {"gp_smoothing": t_smooth, "total": time.perf_counter() - t_start},
    })
    arrays = {"kin": kin, "q_nom": q_nom, "q_aug": q_aug, "residual": res0, "params": params, "M": M}
    return {"result": result, "arrays": arrays}
