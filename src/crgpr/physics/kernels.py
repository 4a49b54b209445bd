"""Compiled kernels of ``integrator.run_rod``: the analytic rod's Stormer-Verlet rollout with
its tangent-linear directions, ports and divergence check (``integrator`` module docstring for
the scheme, paper Sec. IV), and the elastic forces' directional derivatives.

``integrator`` is the Python side (``run_rod`` sets these kernels' arguments up and turns a
failing step into ``SimulationDiverged``); the scheme and its energy bookkeeping are described
there once.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from crgpr.physics.collocated import _collocated_forces, _nodal_forces
from crgpr.physics.dissipation import (
    _damp_exponentials,
    _damp_factors,
    _damp_tangent,
    _kv_flow,
    _kv_flow_tangent,
)
from crgpr.physics.material import bend_law, stretch_law
from crgpr.physics.ports import _tip_load
from crgpr.physics.rod import _internal_forces
from crgpr.physics.stencils import _segment_strains

MAX_SPEED = 1.0e3  # [m/s] and [rad/s]: ~20 x the wave speed of Table I's rod


@njit(cache=True)
def _force_tangent(q, dq, ds, EA, GA, EI_seg, kap_seg, law, kappa0, nu1_0, nu2_0, b_nl, k_base,
                   dth_base, dF):
    """Directional derivatives dF (m, N+1, 3) of the variational elastic forces
    (``rod._internal_forces``, same material arguments; the laws' tangents of ``material``) at q
    along the directions dq (m, N+1, 3); ``dth_base`` (m,): the directions' change of the base
    spring's rest angle (the initial base angle)."""
    n = q.shape[0] - 1
    m = dq.shape[0]
    for a in range(m):
        for i in range(n + 1):
            dF[a, i, 0] = 0.0
            dF[a, i, 1] = 0.0
            dF[a, i, 2] = 0.0
    for j in range(n):
        ex, ey, c, s, nu1, nu2 = _segment_strains(q, j, ds)
        dk = (q[j + 1, 2] - q[j, 2]) / ds - (kappa0 + kap_seg[j])
        n1, _, dn1_de = stretch_law(law, EA, nu1 - nu1_0)
        n2 = GA * (nu2 - nu2_0)
        _, _, dmb_ddk = bend_law(law, EI_seg[j], dk, b_nl)
        for a in range(m):
            dex = (dq[a, j + 1, 0] - dq[a, j, 0]) / ds
            dey = (dq[a, j + 1, 1] - dq[a, j, 1]) / ds
            dtb = 0.5 * (dq[a, j, 2] + dq[a, j + 1, 2])
            dc = -s * dtb
            dsn = c * dtb
            dnu1 = dc * ex + c * dex + dsn * ey + s * dey
            dnu2 = -dsn * ex - s * dex + dc * ey + c * dey
            dn1 = dn1_de * dnu1
            dn2 = GA * dnu2
            dmb = dmb_ddk * (dq[a, j + 1, 2] - dq[a, j, 2]) / ds
            dqx = dn1 * c + n1 * dc - dn2 * s - n2 * dsn
            dqy = dn1 * s + n1 * dsn + dn2 * c + n2 * dc
            dF[a, j, 0] += dqx
            dF[a, j + 1, 0] -= dqx
            dF[a, j, 1] += dqy
            dF[a, j + 1, 1] -= dqy
            dtq = 0.5 * ds * (dn1 * nu2 + n1 * dnu2 - dn2 * nu1 - n2 * dnu1)
            dF[a, j, 2] -= dtq - dmb
            dF[a, j + 1, 2] -= dtq + dmb
    if k_base < np.inf:
        for a in range(m):
            dF[a, 0, 2] -= k_base * (dq[a, 0, 2] - dth_base[a])


@njit(cache=True)
def _forces(scheme, q, ds, EA, GA, EI_seg, kap_seg, law, kappa0, nu1_0, nu2_0, b_nl, k_base, th_base, F):
    """Elastic force kernel of the spatial scheme, index into ``SCHEMES`` (0: variational,
    rod.py; 1: collocated, 2: collocated_nodal, collocated.py: the linear material only, so
    they do not take ``kap_seg``, ``law``; ``run_rod`` refuses other materials for them)."""
    if scheme == 1:
        return _collocated_forces(q, ds, EA, GA, EI_seg, kappa0, nu1_0, nu2_0, b_nl, k_base, th_base, F)
    if scheme == 2:
        return _nodal_forces(q, ds, EA, GA, EI_seg, kappa0, nu1_0, nu2_0, b_nl, k_base, th_base, F)
    return _internal_forces(q, ds, EA, GA, EI_seg, kap_seg, law, kappa0, nu1_0, nu2_0, b_nl, k_base,
                            th_base, F)


@njit(cache=True)
def _port_kick(v, i, P, m_t, m_r, free, h, v_pre, n_c):
    """Kick node i by the port load P (F_x, F_y, M) over h, after its elastic and gravity kick
    from the velocities ``v_pre``; returns the port work [J]: the port impulse h P dotted with
    the mean of the velocities before and after the whole kick. The kick's kinetic-energy change
    is exactly its total impulse dotted with that mean, so this is the ports' exact share (the
    elastic share cancels the potential's change to the scheme's O(dt^2)). Components
    0..n_c-1 only (n_c = 2: the moment goes with the Kelvin-Voigt flow, ``_kv_flow``)."""
    w = 0.0
    for c in range(n_c):
        m = m_t[i] if c < 2 else m_r[i]
        v[i, c] += h * P[c] / m * free[i, c]
        w += h * P[c] * free[i, c] * 0.5 * (v_pre[c] + v[i, c])
    return w


@njit(cache=True)
def _rod_kernel(q, v, free, m_t, m_r, lam_t, lam_r, k_quad, grav, ds, EA, GA, EI_seg, kap_seg, law,
                kappa0, nu1_0, nu2_0, b_nl, k_base, th_base, dt, n_steps, every, reach, out_q, out_v,
                out_d, kv, scheme, dq, dv, out_dq, u, d_tendon, out_w):
    """Compiled rollout of the analytic rod. Returns -1 on success, else the failing step.

    ``dq``, ``dv`` (m, N+1, 3): m directions of the initial state, propagated by the tangent-
    linear scheme alongside (variational scheme only; m = 0: none) and recorded in ``out_dq``;
    the rollout itself does the same arithmetic with or without them. ``u`` (n_steps + 1,
    n_channels): the input values at the step times k dt (``physics.ports``; 0 rows: no inputs),
    applied at the tip after each elastic kick with the tendon offset ``d_tendon``; their
    cumulative work is recorded in ``out_w``. ``kv`` (3, n, n): the Kelvin-Voigt rod's rotational
    half-kick flow (``dissipation.kelvin_voigt_flow``, which then holds the rotational damping
    lam_r too); (0, n, n): none, the plain kick with the Strang-split diagonal flow."""
    n = q.shape[0]
    use_u = u.shape[0] > 0
    tip = n - 1
    Gs = np.zeros((4, 3))
    Pt = np.zeros(3)
    vpre = np.zeros(3)
    work = 0.0
    if use_u:
        _tip_load(q[tip, 2], u[0], d_tendon, Gs, Pt)
        out_w[0] = 0.0
    m = dq.shape[0]
    F = np.zeros((n, 3))
    dF = np.zeros((m, n, 3))
    dth_base = np.empty(m)  # the base spring's rest angle is the initial base angle
    for a in range(m):
        dth_base[a] = dq[a, 0, 2]
    _forces(scheme, q, ds, EA, GA, EI_seg, kap_seg, law, kappa0, nu1_0, nu2_0, b_nl, k_base, th_base, F)
    if m > 0:
        _force_tangent(q, dq, ds, EA, GA, EI_seg, kap_seg, law, kappa0, nu1_0, nu2_0, b_nl, k_base, dth_base,
                           dF)
        out_dq[0] = dq
    diss = 0.0
    out_q[0] = q
    out_v[0] = v
    out_d[0] = 0.0
    h = 0.5 * dt
    use_kv = kv.shape[0] > 0
    ft, fr = _damp_exponentials(lam_t, lam_r * (0.0 if use_kv else 1.0), h)
    kr = 0.0 if use_kv else 1.0  # the rotational kick is part of the Kelvin-Voigt flow
    n_c = 2 if use_kv else 3
    bx, by = q[0, 0], q[0, 1]
    for k in range(1, n_steps + 1):
        if m > 0:
            _damp_tangent(v, dv, ft, fr, k_quad, free, h)
            if use_kv:
                _kv_flow_tangent(dv, dF, m_r, free, kv)
        diss += _damp_factors(v, m_t, m_r, ft, fr, k_quad, free, h)
        if use_u:
            for c in range(3):
                vpre[c] = v[tip, c]
        if use_kv:
            diss += _kv_flow(v, F, Pt[2] if use_u else 0.0, tip, m_r, free, kv)
            if use_u:
                work += h * Pt[2] * free[tip, 2] * 0.5 * (vpre[2] + v[tip, 2])
        for i in range(n):
            v[i, 0] += h * F[i, 0] / m_t[i] * free[i, 0]
            v[i, 1] += h * (F[i, 1] + grav[i]) / m_t[i] * free[i, 1]
            v[i, 2] += kr * h * F[i, 2] / m_r[i] * free[i, 2]
            if use_u and i == tip:
                work += _port_kick(v, i, Pt, m_t, m_r, free, h, vpre, n_c)
            q[i, 0] += dt * v[i, 0]
            q[i, 1] += dt * v[i, 1]
            q[i, 2] += dt * v[i, 2]
        for a in range(m):
            for i in range(n):
                dv[a, i, 0] += h * dF[a, i, 0] / m_t[i] * free[i, 0]
                dv[a, i, 1] += h * dF[a, i, 1] / m_t[i] * free[i, 1]
                dv[a, i, 2] += kr * h * dF[a, i, 2] / m_r[i] * free[i, 2]
                dq[a, i, 0] += dt * dv[a, i, 0]
                dq[a, i, 1] += dt * dv[a, i, 1]
                dq[a, i, 2] += dt * dv[a, i, 2]
        _forces(scheme, q, ds, EA, GA, EI_seg, kap_seg, law, kappa0, nu1_0, nu2_0, b_nl, k_base, th_base, F)
        if use_u:
            for c in range(3):
                vpre[c] = v[tip, c]
        for i in range(n):
            v[i, 0] += h * F[i, 0] / m_t[i] * free[i, 0]
            v[i, 1] += h * (F[i, 1] + grav[i]) / m_t[i] * free[i, 1]
            v[i, 2] += kr * h * F[i, 2] / m_r[i] * free[i, 2]
        if use_u:
            _tip_load(q[tip, 2], u[k], d_tendon, Gs, Pt)
            work += _port_kick(v, tip, Pt, m_t, m_r, free, h, vpre, n_c)
        if m > 0:
            _force_tangent(q, dq, ds, EA, GA, EI_seg, kap_seg, law, kappa0, nu1_0, nu2_0, b_nl, k_base,
                           dth_base, dF)
            for a in range(m):
                for i in range(n):
                    dv[a, i, 0] += h * dF[a, i, 0] / m_t[i] * free[i, 0]
                    dv[a, i, 1] += h * dF[a, i, 1] / m_t[i] * free[i, 1]
                    dv[a, i, 2] += kr * h * dF[a, i, 2] / m_r[i] * free[i, 2]
            _damp_tangent(v, dv, ft, fr, k_quad, free, h)
            if use_kv:
                _kv_flow_tangent(dv, dF, m_r, free, kv)
        diss += _damp_factors(v, m_t, m_r, ft, fr, k_quad, free, h)
        if use_kv:
            w0 = v[tip, 2]
            diss += _kv_flow(v, F, Pt[2] if use_u else 0.0, tip, m_r, free, kv)
            if use_u:
                work += h * Pt[2] * free[tip, 2] * 0.5 * (w0 + v[tip, 2])
        if k % every == 0:
            r = k // every
            bad = False
            for i in range(n):
                for c in range(3):
                    if not (abs(v[i, c]) < MAX_SPEED) or not math.isfinite(q[i, c]):
                        bad = True
                if not (math.hypot(q[i, 0] - bx, q[i, 1] - by) <= reach):
                    bad = True
            if bad:
                return k
            out_q[r] = q
            out_v[r] = v
            out_d[r] = diss
            if use_u:
                out_w[r] = work
            if m > 0:
                out_dq[r] = dq
    return -1
