"""Trajectory fitting: the model simulated from a fitted initial state and fitted to the markers.

The measured initial state (GP-smoothed, projected onto an unstretched, unsheared rod,
``rod_state``) is corrected by smooth Legendre modes of the nodal angles and rates; effect
coefficients and corrections are fitted by least squares of theta at the markers over the
record (``TrajectoryFitter``), the corrections' Jacobian exact from one tangent-linear run.
Used to confirm a named effect (its BIC and its own size in the joint fit), for the floor and
for the gap before and after.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.optimize._numdiff import approx_derivative  # least_squares' own differences

from crgpr.discovery.effects import EFFECTS
from crgpr.discovery.synthetic import aligned_settings
from crgpr.measured.kinematics import Kinematics, marker_matrix, marker_positions
from crgpr.physics.integrator import SimulationDiverged
from crgpr.physics.params import RodParams
from crgpr.physics.simulate import simulate
from crgpr.stats import autocorrelation_time


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
        self.train: np.ndarray | None = None  # samples in the objective (None: all)
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
        r = self._weigh(q[..., 2] @ self.M.T - self.theta_m[:n])
        J = np.einsum("taj,mj->tma", dq[..., 2], self.M)
        if self.train is not None:
            J = J * self.train[:n, None, None]
        J = J.reshape(r.size, 2 * m)
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
        r = self._weigh(q[..., 2] @ self.M.T - self.theta_m[:n])
        return r if np.all(np.isfinite(r)) else np.full(r.size, 10.0)

    def _weigh(self, e: np.ndarray) -> np.ndarray:
        """Theta errors (n, markers) -> the residual vector, samples outside ``train`` zeroed."""
        if self.train is not None:
            e = e * self.train[:e.shape[0], None]
        return e.ravel()

    def masked(self, train: np.ndarray) -> TrajectoryFitter:
        """The same fitter with only the samples where ``train`` (n,) is 1 in its objective (the
        model is still simulated over the whole record; the others are held out)."""
        g = copy.copy(self)
        g.train = np.asarray(train, float)
        return g

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
        tau = autocorrelation_time(r, 0) * autocorrelation_time(r, 1)
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
