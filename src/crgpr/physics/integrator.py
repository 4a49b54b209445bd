"""Stormer-Verlet time integration with Strang-split dissipation (paper Sec. IV).

One step of length dt, with M the lumped masses and F(q) the generalised forces:

    p <- D(dt/2) p                      exact dissipative flow (damping, drag)
    p <- p + dt/2 F(q)                  kick
    q <- q + dt M^-1 p                  drift
    p <- p + dt/2 F(q)                  kick
    p <- D(dt/2) p

The conservative part is the symplectic Stormer-Verlet (velocity Verlet) scheme the paper
uses; the dissipation R (linear: p <- exp(-c dt/2) p, quadratic drag: v <- v / (1 + k|v| dt/2))
is applied by its exact flow, so it can only remove energy and is stable for any damping.
The scheme is symmetric and second order. The kinetic energy removed by D is accumulated as
the dissipated energy.

Two implementations share these formulas: a compiled kernel for the analytic rod
(``run_rod``) and a generic one that takes any force function (``run_generic``), used for
learned models. ``tests/test_integrator.py`` checks they agree.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit

from crgpr.physics.rod import _internal_forces

# Guard rails: a state beyond these is a diverged run, not physics.
MAX_SPEED = 1.0e3  # [m/s] or [rad/s]
MAX_COORD = 1.0e6  # [m] or [rad]


class SimulationDiverged(RuntimeError):
    """Raised when the state leaves the physical range; carries where and when."""

    def __init__(self, message: str, step: int, t: float, node: int, members: np.ndarray | None = None):
        super().__init__(message)
        self.step = step
        self.t = t
        self.node = node
        # batched runs (leading axes on the state): indices of the batch members that left the
        # physical range, (k, n_batch_axes); None for an unbatched run
        self.members = members


@dataclass
class Integration:
    """Recorded output of a run: positions q, velocities v (n_rec, N+1, 3) and energy terms."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    dissipated: np.ndarray  # cumulative energy removed by the dissipative flow [J]


@njit(cache=True)
def _damp(v, m_t, m_r, lam_t, lam_r, k_quad, free, h):
    """Exact dissipative flow over time h; returns kinetic energy removed [J]."""
    n = v.shape[0]
    lost = 0.0
    for i in range(n):
        ke0 = 0.5 * m_t[i] * (v[i, 0] ** 2 + v[i, 1] ** 2) + 0.5 * m_r[i] * v[i, 2] ** 2
        ft = math.exp(-lam_t[i] * h)
        v[i, 0] *= ft * free[i, 0]
        v[i, 1] *= ft * free[i, 1]
        v[i, 2] *= math.exp(-lam_r[i] * h) * free[i, 2]
        if k_quad[i] > 0.0:
            sp = math.sqrt(v[i, 0] ** 2 + v[i, 1] ** 2)
            fac = 1.0 / (1.0 + k_quad[i] * sp * h)
            v[i, 0] *= fac
            v[i, 1] *= fac
        ke1 = 0.5 * m_t[i] * (v[i, 0] ** 2 + v[i, 1] ** 2) + 0.5 * m_r[i] * v[i, 2] ** 2
        lost += ke0 - ke1
    return lost


@njit(cache=True)
def _rod_kernel(q, v, free, m_t, m_r, lam_t, lam_r, k_quad, grav, ds, EA, GA, EI_seg, kappa0,
                nu1_0, nu2_0, b_nl, k_base, th_base, dt, n_steps, every, out_q, out_v, out_d):
    """Compiled rollout of the analytic rod. Returns -1 on success, else the failing step."""
    n = q.shape[0]
    F = np.zeros((n, 3))
    _internal_forces(q, ds, EA, GA, EI_seg, kappa0, nu1_0, nu2_0, b_nl, k_base, th_base, F)
    diss = 0.0
    out_q[0] = q
    out_v[0] = v
    out_d[0] = 0.0
    h = 0.5 * dt
    for k in range(1, n_steps + 1):
        diss += _damp(v, m_t, m_r, lam_t, lam_r, k_quad, free, h)
        for i in range(n):
            v[i, 0] += h * F[i, 0] / m_t[i] * free[i, 0]
            v[i, 1] += h * (F[i, 1] + grav[i]) / m_t[i] * free[i, 1]
            v[i, 2] += h * F[i, 2] / m_r[i] * free[i, 2]
            q[i, 0] += dt * v[i, 0]
            q[i, 1] += dt * v[i, 1]
            q[i, 2] += dt * v[i, 2]
        _internal_forces(q, ds, EA, GA, EI_seg, kappa0, nu1_0, nu2_0, b_nl, k_base, th_base, F)
        for i in range(n):
            v[i, 0] += h * F[i, 0] / m_t[i] * free[i, 0]
            v[i, 1] += h * (F[i, 1] + grav[i]) / m_t[i] * free[i, 1]
            v[i, 2] += h * F[i, 2] / m_r[i] * free[i, 2]
        diss += _damp(v, m_t, m_r, lam_t, lam_r, k_quad, free, h)
        if k % every == 0:
            r = k // every
            bad = False
            for i in range(n):
                for c in range(3):
                    if not (abs(v[i, c]) < MAX_SPEED) or not (abs(q[i, c]) < MAX_COORD):
                        bad = True
            if bad:
                return k
            out_q[r] = q
            out_v[r] = v
            out_d[r] = diss
    return -1


def _locate_failure(q: np.ndarray, v: np.ndarray) -> int:
    bad = ~(np.isfinite(q) & np.isfinite(v) & (np.abs(v) < MAX_SPEED))
    rows = np.nonzero(bad.any(axis=1))[0]
    return int(rows[0]) if rows.size else -1


def run_rod(q0, v0, free, m_t, m_r, lam_t, lam_r, k_quad, grav_force, rod_args, dt, n_steps, every):
    """Integrate the analytic rod. ``rod_args`` are the trailing arguments of the force kernel.

    ``grav_force`` is the nodal y-force of gravity (-m_i g). Raises SimulationDiverged.
    """
    n_rec = n_steps // every + 1
    q = np.array(q0, dtype=float, order="C")
    v = np.array(v0, dtype=float, order="C") * free
    out_q = np.zeros((n_rec, q.shape[0], 3))
    out_v = np.zeros_like(out_q)
    out_d = np.zeros(n_rec)
    status = _rod_kernel(q, v, free, m_t, m_r, lam_t, lam_r, k_quad, grav_force, *rod_args,
                         dt, n_steps, every, out_q, out_v, out_d)
    if status >= 0:
        node = _locate_failure(q, v)
        t_fail = status * dt
        raise SimulationDiverged(
            f"simulation diverged at t = {t_fail:.6g} s (step {status}), first bad node {node}: "
            f"state non-finite or speed > {MAX_SPEED:g}. Reduce the time step (config key "
            f"simulation.dt_s) or check the parameters.", status, t_fail, node)
    t = np.arange(n_rec) * dt * every
    return Integration(t, out_q, out_v, out_d)


def run_generic(
    q0: np.ndarray,
    v0: np.ndarray,
    force: Callable[[np.ndarray], np.ndarray],
    free: np.ndarray,
    m_t: np.ndarray,
    m_r: np.ndarray,
    lam_t: np.ndarray,
    lam_r: np.ndarray,
    dt: float,
    n_steps: int,
    every: int,
    k_quad: np.ndarray | None = None,
    what: str = "rollout",
) -> Integration:
    """Same scheme as ``run_rod`` for any nodal force function ``force(q) -> (N+1, 3)``.

    ``force`` must include gravity and any input; used for the learned models (eq. (nonpde)).
    Raises SimulationDiverged with the time and node of the first non-finite or runaway state.
    """
    n = q0.shape[0]
    k_quad = np.zeros(n) if k_quad is None else k_quad
    q = np.array(q0, dtype=float)
    v = np.array(v0, dtype=float) * free
    minv = np.stack([1.0 / m_t, 1.0 / m_t, 1.0 / m_r], axis=1) * free
    n_rec = n_steps // every + 1
    out_q = np.zeros((n_rec, n, 3))
    out_v = np.zeros_like(out_q)
    out_d = np.zeros(n_rec)
    out_q[0], out_v[0] = q, v
    h = 0.5 * dt
    Fq = force(q)
    diss = 0.0
    for k in range(1, n_steps + 1):
        diss += _damp(v, m_t, m_r, lam_t, lam_r, k_quad, free, h)
        v += h * Fq * minv
        q += dt * v
        Fq = force(q)
        v += h * Fq * minv
        diss += _damp(v, m_t, m_r, lam_t, lam_r, k_quad, free, h)
        if k % every == 0:
            r = k // every
            if not (np.all(np.isfinite(v)) and np.all(np.abs(v) < MAX_SPEED)):
                node = _locate_failure(q, v)
                raise SimulationDiverged(
                    f"{what} diverged at t = {k * dt:.6g} s (step {k}), first bad node {node}: "
                    f"state non-finite or speed > {MAX_SPEED:g}.", k, k * dt, node)
            out_q[r], out_v[r], out_d[r] = q, v, diss
    t = np.arange(n_rec) * dt * every
    return Integration(t, out_q, out_v, out_d)


def run_hamiltonian(
    q0: np.ndarray,
    p0: np.ndarray,
    force: Callable[[np.ndarray], np.ndarray],
    velocity: Callable[[np.ndarray], np.ndarray],
    free: np.ndarray,
    zeta: float,
    dt: float,
    n_steps: int,
    every: int,
    wds: np.ndarray | None = None,
    what: str = "rollout",
    velocity_slope: Callable[[np.ndarray], np.ndarray] | None = None,
) -> Integration:
    """The same Strang-split Stormer-Verlet scheme in (q, p) for a learned H_z (eq. (nonpde)).

    ``force(q)`` -> (N+1, 3): -H_q + G u per unit length (i.e. dp/dt without damping);
    ``velocity(p)`` -> (N+1, 3): H_p, so that dq/dt = H_p and the damping R gives
    dp/dt = -zeta H_p. One step: damping half-step, kick, drift q += dt H_p(p), kick, damping
    half-step. The damping flow dp/dt = -zeta H_p(p) over h = dt/2 is taken exactly for an
    affine H_p (exponential Euler with the slope s = dH_p/dp from ``velocity_slope``, or a
    central difference): p <- p - (1 - exp(-zeta s h)) / s * H_p(p). For the analytic
    H_p = p / (rho A) this is ``run_rod``'s exact exponential, so with the analytic H_z the
    two integrators agree to round-off. Returns an ``Integration`` whose ``v`` holds the
    MOMENTA p per length; ``dissipated`` accumulates zeta sum_i w_i ds |H_p|^2 dt (trapezoid
    over each damping half-step; needs ``wds``).
    Batches: q0, p0 may carry leading axes (..., n, 3) when ``force`` and ``velocity`` do
    (e.g. a LearnedRod of posterior samples); every member is integrated independently and
    ``dissipated`` is per member (n_rec, ...).
    Raises SimulationDiverged with the time and node of the first non-finite or runaway state
    (for a batch also ``members``: the batch indices that left the physical range).
    """
    n = q0.shape[-2]
    batch = q0.shape[:-2]
    q = np.array(q0, dtype=float)
    p = np.array(p0, dtype=float) * free
    wds = np.ones(n) if wds is None else np.asarray(wds, dtype=float)
    n_rec = n_steps // every + 1
    out_q = np.zeros((n_rec, *q.shape))
    out_p = np.zeros_like(out_q)
    out_d = np.zeros((n_rec, *batch))
    out_q[0], out_p[0] = q, p
    h = 0.5 * dt
    zh = zeta * h

    def slope(p: np.ndarray) -> np.ndarray:
        if velocity_slope is not None:
            return velocity_slope(p)
        d = 1e-6 * np.maximum(np.abs(p), 1e-6)
        return (velocity(p + d) - velocity(p - d)) / (2 * d)

    def damp(p: np.ndarray) -> tuple[np.ndarray, float]:
        v0 = velocity(p)
        sl = slope(p) * zeta
        small = np.abs(sl * h) < 1e-12
        fac = np.where(small, zeta * h, -np.expm1(-sl * h) / np.where(small, 1.0, sl) * zeta)
        p1 = p - fac * v0 * free
        v1 = velocity(p1)
        return p1, 0.5 * zh * (wds[:, None] * (v0 * v0 + v1 * v1) * free).sum(axis=(-2, -1))

    f = force(q)
    diss = np.zeros(batch)
    for k in range(1, n_steps + 1):
        p, e1 = damp(p)
        p = p + h * f * free
        q = q + dt * velocity(p) * free
        f = force(q)
        p = p + h * f * free
        p, e2 = damp(p)
        diss += e1 + e2
        if k % every == 0:
            r = k // every
            v = velocity(p)
            if not (np.all(np.isfinite(v)) and np.all(np.isfinite(q)) and np.all(np.abs(v) < MAX_SPEED)
                    and np.all(np.abs(q) < MAX_COORD)):
                qb = np.where(np.abs(q) < MAX_COORD, q, np.nan)
                node = _locate_failure(qb.reshape(-1, 3), v.reshape(-1, 3)) % n
                members = None
                if batch:
                    ok = np.isfinite(qb) & np.isfinite(v) & (np.abs(v) < MAX_SPEED)
                    members = np.argwhere(~ok.all(axis=(-2, -1)))
                raise SimulationDiverged(
                    f"{what} diverged at t = {k * dt:.6g} s (step {k}), first bad node {node}: "
                    f"state non-finite or speed > {MAX_SPEED:g}.", k, k * dt, node, members)
            out_q[r], out_p[r], out_d[r] = q, p, diss
    t = np.arange(n_rec) * dt * every
    return Integration(t, out_q, out_p, out_d)
