"""Dissipative flows of the rod: the R of eq. (8) and the Kelvin-Voigt bending damping.

dz/dt = (J - R) dH/dz + G u (eqs. (7)-(9), Sec. III-A) with R >= 0. Two dissipations act on
the momenta, both integrated exactly in the scheme of ``physics.integrator`` (so they only
remove energy, whatever the time step):

* the nominal damping dp/dt = -zeta H_p (eq. (8)), rates lam_t, lam_r per node, plus the
  quadratic drag of the missing-physics library (``_damp_factors``): exact flows, Strang-split
  around the kicks;
* the Kelvin-Voigt bending damping, a segment moment m_d,j = c dkappa_j/dt with c >= 0
  (``rod.material.kelvin_voigt`` of the simulator, or the coefficient ``crgpr learn`` learned,
  ``learning.damping``). On the angular rates omega = H_p_theta it is the linear map
  K = (c / ds) D^T D (D the (N, N+1) difference matrix): nodal couples -K omega, dissipated
  power omega^T K omega = sum_j ds c (dkappa_j/dt)^2 >= 0 (``bending_power``), so the R it adds
  is positive semi-definite for every state. Its damping rates reach c / (rho I ds^2) dt >> 1
  at the model's step, and a Strang split of so stiff a damping around the kick is only first
  order in dt (its overdamped short modes respond to the kick's impulse, not to the balance of
  the couples); so where it is present the rotational kick and both rotational dampings are
  one exact affine flow over each half-step, ``kelvin_voigt_flow`` (second order again; tests/
  test_integrator.py measures both).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _damp_exponentials(lam_t, lam_r, h):
    """The factors ft = exp(-lam_t h), fr = exp(-lam_r h) of the linear damping flow over time
    h, computed once per run (``math.exp``, as the kernels always did)."""
    n = lam_t.shape[0]
    ft = np.empty(n)
    fr = np.empty(n)
    for i in range(n):
        ft[i] = math.exp(-lam_t[i] * h)
        fr[i] = math.exp(-lam_r[i] * h)
    return ft, fr


@njit(cache=True)
def _damp_factors(v, m_t, m_r, ft, fr, k_quad, free, h):
    """Exact dissipative flow over time h with the factors of ``_damp_exponentials`` (linear
    rates) and the quadratic drag k_quad; returns kinetic energy removed [J]."""
    n = v.shape[0]
    lost = 0.0
    for i in range(n):
        ke0 = 0.5 * m_t[i] * (v[i, 0] ** 2 + v[i, 1] ** 2) + 0.5 * m_r[i] * v[i, 2] ** 2
        v[i, 0] *= ft[i] * free[i, 0]
        v[i, 1] *= ft[i] * free[i, 1]
        v[i, 2] *= fr[i] * free[i, 2]
        if k_quad[i] > 0.0:
            sp = math.sqrt(v[i, 0] ** 2 + v[i, 1] ** 2)
            fac = 1.0 / (1.0 + k_quad[i] * sp * h)
            v[i, 0] *= fac
            v[i, 1] *= fac
        ke1 = 0.5 * m_t[i] * (v[i, 0] ** 2 + v[i, 1] ** 2) + 0.5 * m_r[i] * v[i, 2] ** 2
        lost += ke0 - ke1
    return lost


@njit(cache=True)
def _damp_tangent(v, dv, ft, fr, k_quad, free, h):
    """Tangent of ``_damp_factors`` for directions dv (m, N+1, 3), taken at the velocities v
    BEFORE the flow (call it before ``_damp_factors``): the linear decay, and the derivative of
    the quadratic-drag factor 1 / (1 + k |v| h) along the direction."""
    n = v.shape[0]
    m = dv.shape[0]
    for i in range(n):
        a0 = ft[i] * free[i, 0]
        a1 = ft[i] * free[i, 1]
        a2 = fr[i] * free[i, 2]
        vl0 = v[i, 0] * a0
        vl1 = v[i, 1] * a1
        sp = math.sqrt(vl0 * vl0 + vl1 * vl1)
        drag = k_quad[i] > 0.0
        fac = 1.0 / (1.0 + k_quad[i] * sp * h) if drag else 1.0
        for a in range(m):
            d0 = dv[a, i, 0] * a0
            d1 = dv[a, i, 1] * a1
            dv[a, i, 2] *= a2
            if drag:
                dfac = 0.0
                if sp > 0.0:
                    dfac = -k_quad[i] * h * fac * fac * (vl0 * d0 + vl1 * d1) / sp
                d0, d1 = d0 * fac + vl0 * dfac, d1 * fac + vl1 * dfac
            dv[a, i, 0] = d0
            dv[a, i, 1] = d1


# --- Kelvin-Voigt bending damping -------------------------------------------------------------
def _phi(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """exp(-x), phi1(-x) = (1 - exp(-x)) / x and phi2(-x) = (x - 1 + exp(-x)) / x^2 for x >= 0
    (their series where x is small)."""
    x = np.maximum(x, 0.0)
    small = x < 1e-4
    xs = np.where(small, 1.0, x)
    e = np.exp(-x)
    phi1 = np.where(small, 1.0 - x / 2 + x**2 / 6, -np.expm1(-xs) / xs)
    phi2 = np.where(small, 0.5 - x / 6 + x**2 / 24, (xs + np.expm1(-xs)) / xs**2)
    return e, phi1, phi2


def kelvin_voigt_flow(c: float, ds: float, m_r: np.ndarray, lam_r: np.ndarray | float, free_rot: np.ndarray,
                      h: float) -> np.ndarray:
    """The exact flow over a time h of the rotational half-kick with its dissipation,
    d omega/dt = a - A omega with A = M_r^-1 K + diag(lam_r), for a force a = F / m_r frozen
    over the half-step (the kick of eq. (17)'s Stormer-Verlet scheme, ``physics.integrator``):

        omega(h) = P omega + Phi a,   int_0^h omega dt = Phi omega + Psi a,

    P = exp(-A h), Phi = h phi1(-A h), Psi = h^2 phi2(-A h). K = (c / ds) D^T D with D the
    (N, N+1) difference matrix: the nodal couples of the segment moments m_j = c (omega_{j+1} -
    omega_j) / ds (Rayleigh dissipation sum_j ds c kappa_dot_j^2 >= 0); lam_r the diagonal
    rotational damping rates of eq. (8) (zeta / rho I). Restricted to the free rotational DOFs
    (a clamped base rate stays 0): with S = M^-1/2 K M^-1/2 + diag(lam_r) = U L U^T, each matrix
    is M^-1/2 U f(L h) U^T M^1/2, so P is a contraction in the kinetic-energy norm for any h.
    Returns the stack (3, N+1, N+1) [P, Phi, Psi]; an empty (0, N+1, N+1) one for c = 0 (no
    Kelvin-Voigt damping: the Stormer-Verlet kick with the diagonal flow is then used).
    """
    n = m_r.size
    if c <= 0.0:
        return np.zeros((0, n, n))
    D = np.diff(np.eye(n), axis=0)
    K = (c / ds) * D.T @ D
    f = np.nonzero(np.asarray(free_rot) > 0)[0]
    ms = np.sqrt(m_r[f])
    S = K[np.ix_(f, f)] / np.outer(ms, ms) + np.diag(np.broadcast_to(np.asarray(lam_r, dtype=float), (n,))[f])
    lam, U = np.linalg.eigh(0.5 * (S + S.T))
    out = np.zeros((3, n, n))
    for k, (g, scale) in enumerate(zip(_phi(lam * h), (1.0, h, h * h), strict=True)):
        out[k][np.ix_(f, f)] = scale * (U * g) @ U.T / ms[:, None] * ms[None, :]
    return out


@njit(cache=True)
def _kv_flow(v, F, moment, tip, m_r, free, flow):
    """The rotational half-kick by the exact flow ``flow`` = [P, Phi, Psi] of
    ``kelvin_voigt_flow``: omega <- P omega + Phi a, a = (F[:, 2] + a tip ``moment``) / m_r.
    Returns the energy dissipated over it, int omega^T (K + M_r lam_r) omega dt = the work of
    the frozen couples, sum_i m_r a . int omega dt, less the kinetic-energy gain (exact)."""
    n = v.shape[0]
    a = np.empty(n)
    for i in range(n):
        a[i] = F[i, 2] * free[i, 2] / m_r[i]
    a[tip] += moment * free[tip, 2] / m_r[tip]
    lost = 0.0
    w = np.empty(n)
    for i in range(n):
        acc = 0.0
        integral = 0.0
        for k in range(n):
            acc += flow[0, i, k] * v[k, 2] + flow[1, i, k] * a[k]
            integral += flow[1, i, k] * v[k, 2] + flow[2, i, k] * a[k]
        w[i] = acc
        lost += m_r[i] * a[i] * integral
    for i in range(n):
        lost += 0.5 * m_r[i] * (v[i, 2] ** 2 - w[i] ** 2)
        v[i, 2] = w[i]
    return lost


@njit(cache=True)
def _kv_flow_tangent(dv, dF, m_r, free, flow):
    """Tangent of ``_kv_flow`` (affine in omega and F): omega_a <- P omega_a + Phi dF_a / m_r
    for every direction a (the tip moment's tangent is not propagated, as in the kick's)."""
    n = dv.shape[1]
    w = np.empty(n)
    for a in range(dv.shape[0]):
        for i in range(n):
            acc = 0.0
            for k in range(n):
                acc += flow[0, i, k] * dv[a, k, 2] + flow[1, i, k] * dF[a, k, 2] * free[k, 2] / m_r[k]
            w[i] = acc
        for i in range(n):
            dv[a, i, 2] = w[i]


def kv_flow_step(flow: np.ndarray, x: np.ndarray, a: np.ndarray, m: np.ndarray, book: bool = True
                 ) -> tuple[np.ndarray, np.ndarray | float]:
    """``_kv_flow`` on arrays: rotational rates or momenta x (..., n) with the frozen
    dx/dt-without-damping a (..., n) over the flow ``flow`` (``kelvin_voigt_flow`` in these
    units): x <- P x + Phi a, and the energy dissipated, sum_i m_i (a_i int x_i dt) less the gain
    of sum_i m_i x_i^2 / 2 (per leading index; 0.0 when not ``book``)."""
    x1 = x @ flow[0].T + a @ flow[1].T
    if not book:
        return x1, 0.0
    integral = x @ flow[1].T + a @ flow[2].T
    return x1, (m * (a * integral + 0.5 * (x * x - x1 * x1))).sum(axis=-1)


def bending_power(omega: np.ndarray, c: float, ds: float) -> np.ndarray:
    """Power dissipated by the bending damping, sum_j ds c (dkappa_j/dt)^2 with dkappa_j/dt =
    (omega_{j+1} - omega_j) / ds, for angular rates omega (..., N+1) [W]; >= 0 for c >= 0."""
    if c < 0:
        raise ValueError(f"bending damping c = {c!r}: must be >= 0 (a passive R)")
    return (c / ds) * (np.diff(omega, axis=-1) ** 2).sum(axis=-1)
