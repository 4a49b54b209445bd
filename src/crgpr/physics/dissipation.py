"""Dissipative flows of the rod: the R of eq. (8) and the Kelvin-Voigt bending damping.

dz/dt = (J - R) dH/dz + G u (eqs. (7)-(9), Sec. III-A) with R >= 0. Two dissipations act on
the momenta, both integrated by their exact flow in the Strang-split scheme of
``physics.integrator`` (so they only remove energy, whatever the time step):

* the nominal damping dp/dt = -zeta H_p (eq. (8)), rates lam_t, lam_r per node, plus the
  quadratic drag of the missing-physics library (``_damp_factors``);
* the Kelvin-Voigt bending damping, a segment moment m_d,j = c dkappa_j/dt with c >= 0
  (``rod.material.kelvin_voigt`` of the simulator, or the coefficient ``crgpr learn`` learned,
  ``learning.damping``). On the angular rates omega = H_p_theta it is the linear map
  K = (c / ds) D^T D (D the (N, N+1) difference matrix): nodal couples -K omega, dissipated
  power omega^T K omega = sum_j ds c (dkappa_j/dt)^2 >= 0 (``bending_power``), so the R it adds
  is positive semi-definite for every state. Its exact flow is ``kelvin_voigt_propagator``.
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


# --- Kelvin-Voigt bending damping -------------------------------------------------------------
def kelvin_voigt_propagator(c: float, ds: float, m_r: np.ndarray, free_rot: np.ndarray, h: float
                            ) -> np.ndarray:
    """Exact flow matrix P(h) of d omega/dt = -M_r^-1 K omega over a time h.

    K = (c / ds) D^T D with D the (N, N+1) difference matrix, i.e. the nodal couples of the
    segment moments m_j = c (omega_{j+1} - omega_j) / ds (Rayleigh dissipation
    sum_j ds c kappa_dot_j^2 >= 0). Restricted to the free rotational DOFs (a clamped base
    rate stays 0). P = M^-1/2 U exp(-h L) U^T M^1/2 with S = M^-1/2 K M^-1/2 = U L U^T, so P
    is a contraction in the kinetic-energy norm for any h (passive, unconditionally stable).
    Returns an (N+1, N+1) matrix; an empty (0, 0) array for c = 0 (no damping).
    """
    n = m_r.size
    if c <= 0.0:
        return np.zeros((0, 0))
    D = np.diff(np.eye(n), axis=0)
    K = (c / ds) * D.T @ D
    f = np.nonzero(np.asarray(free_rot) > 0)[0]
    P = np.zeros((n, n))
    ms = np.sqrt(m_r[f])
    S = K[np.ix_(f, f)] / np.outer(ms, ms)
    lam, U = np.linalg.eigh(0.5 * (S + S.T))
    P[np.ix_(f, f)] = (U * np.exp(-h * np.maximum(lam, 0.0))) @ U.T / ms[:, None] * ms[None, :]
    return P


@njit(cache=True)
def _kv_damp(v, m_r, P):
    """Apply the Kelvin-Voigt flow omega <- P omega; returns the rotational energy removed [J]."""
    n = v.shape[0]
    w = np.empty(n)
    for i in range(n):
        acc = 0.0
        for k in range(n):
            acc += P[i, k] * v[k, 2]
        w[i] = acc
    lost = 0.0
    for i in range(n):
        lost += 0.5 * m_r[i] * (v[i, 2] ** 2 - w[i] ** 2)
        v[i, 2] = w[i]
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


@njit(cache=True)
def kv_apply(P, x, out):
    """out = P x: a Kelvin-Voigt flow (``kelvin_voigt_propagator``) on the rotational entries x
    (n,) (out must not be x)."""
    n = x.shape[0]
    for i in range(n):
        acc = 0.0
        for k in range(n):
            acc += P[i, k] * x[k]
        out[i] = acc


@njit(cache=True)
def _kv_tangent(dv, P):
    """Tangent of ``_kv_damp`` (a linear flow): omega_a <- P omega_a for every direction."""
    n = dv.shape[1]
    w = np.empty(n)
    for a in range(dv.shape[0]):
        kv_apply(P, dv[a, :, 2], w)
        for i in range(n):
            dv[a, i, 2] = w[i]




def bending_power(omega: np.ndarray, c: float, ds: float) -> np.ndarray:
    """Power dissipated by the bending damping, sum_j ds c (dkappa_j/dt)^2 with dkappa_j/dt =
    (omega_{j+1} - omega_j) / ds, for angular rates omega (..., N+1) [W]; >= 0 for c >= 0."""
    if c < 0:
        raise ValueError(f"bending damping c = {c!r}: must be >= 0 (a passive R)")
    return (c / ds) * (np.diff(omega, axis=-1) ** 2).sum(axis=-1)
