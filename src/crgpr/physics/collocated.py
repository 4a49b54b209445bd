"""Collocated nodal finite-difference discretisations of the planar Cosserat rod (paper eqs. (4)-(10),
Sec. III-A): the discretisations whose stencils are the paper's GPR 3 inputs
(eq. (15): theta_i, theta_{i-1}, theta_{i+1}, d2theta/ds2_i, dx/ds_i, dy/ds_i).

Grid and state as in rod.py (nodes i = 0..N, s_i = i ds, node 0 clamped, node N free), same
lumped masses, damping, gravity input and integrator; only the elastic force kernel differs.
Nodal stencils (those of prefilter.spatial_derivatives in the interior):
    x'_i = (x_{i+1} - x_{i-1}) / (2 ds)  (i = 1..N-1),   x'_0 = (x_1 - x_0) / ds  (clamped base)
    nu1_i = cos(theta_i) x'_i + sin(theta_i) y'_i,  nu2_i = -sin(theta_i) x'_i + cos(theta_i) y'_i
    n1_i = EA (nu1_i - nu1^0), n2_i = GA (nu2_i - nu2^0)            (eq. (10), as rod.py)
    c_i = nu1_i n2_i - nu2_i n1_i                                     (the nu x n couple)
Free tip: n = 0 and m = 0 at s = L0 are imposed at node N (q_N = 0, c_N = 0, m_N = 0).
Bending is the compact second difference d_s m_i = (m_{i+1/2} - m_{i-1/2}) / ds with
m_{j+1/2} = EI (kappa_j - kappa^0), kappa_j = (theta_{j+1} - theta_j) / ds; for the paper's
uniform linear rod d_s m_i = EI (theta_{i+1} - 2 theta_i + theta_{i-1}) / ds^2, the paper's
d2theta/ds2 stencil, and at the tip -m_{N-1/2} / (ds/2) = 2 EI (theta_{N-1} - theta_N) / ds^2
(ghost theta_{N+1} = theta_{N-1}: the prefilter's tip stencil). A central difference of nodal
moments would reach theta_{i+-2}, outside the paper's stencil.

Two schemes, differing in the translational equations (rows 4-5 of eq. (9)):

``collocated`` (config simulation.scheme: collocated). Couple at the nodes, forces in flux form:
    dp_theta,i/dt = d_s m_i + c_i(theta_i, x'_i, y'_i)                   (c_N = 0)
    dp_x,i/dt = (q_x,i+1/2 - q_x,i-1/2) / ds   (q at the half nodes from the segment slopes and
                                                theta_{i+1/2} = (theta_i + theta_{i+1}) / 2, as rod.py;
                                                tip: -q_x,N-1/2 / (ds/2), i.e. q_N = 0)
  So dH/dtheta_i = -EI theta''_i - c(theta_i, x'_i, y'_i) is EXACTLY a function of GPR 3's inputs
  at every free node (the variational rod instead has the mean of the two SEGMENT couples,
  which the nodal inputs do not determine, see learning/oracle.py), and the translational
  equations are those of rod.py (the segment resultants of GPR 1, 2 in learning/features.py are
  exact). It is not the gradient of any discrete energy: the nodal couple does not match the
  theta-dependence of the segment resultants, so the energy (rod.py's V) is not conserved;
  H(t) - H(0) + dissipated equals the work of the couple excess c_i - (c_{i-1/2} + c_{i+1/2}) / 2
  (tests/test_collocated.py). To leading order that excess is GA ds^2 theta''_i / 4: the theta
  equation sees a bending stiffness EI + GA ds^2 / 4 while the forces see EI, a locking-like
  O(ds^2) error whose constant GA ds^2 / (4 EI) = 4 pi ds^2 / (12 A) is 5.3 for Table I's
  slender rod at N = 25 (1.3 at N = 50, 0.08 at N = 200). Measured at N = 25: the energy
  swings by ~90 % of the largest kinetic energy with zeta = 0, the static tip under gravity
  lies 24 cm from the variational one, RMSE(theta) against the variational ground truth is
  0.6-1.5 rad over 2 s; the error falls at about second order with N (environment-notes.md).
  Stable at dt = 1e-4 s (linearised omega_max dt = 1.39 < 2 along the 85 deg run).

``collocated_nodal``. Everything at the nodes: the resultants q_i = R(theta_i) n_i at the nodes
and their central difference
    dp_x,i/dt = (q_x,i+1 - q_x,i-1) / (2 ds)  (i = 1..N-1),   dp_x,N/dt = -q_x,N-1 / ds
  (ghost q_{N+1} = 2 q_N - q_{N-1} with q_N = 0), couple and bending as above. With these
  closures the central difference is summation-by-parts: the nodal forces are exactly
  -dV_c/dq of V_c = sum_{i<N} a_i ds W_nt(nu1_i, nu2_i) + sum_j ds W_b(kappa_j) (a_0 = 1/2,
  a_i = 1; the tip term is zero by n(L0) = 0), so Stormer-Verlet conserves T + V_c up to its
  bounded O(dt^2) oscillation. But the odd-even displacement x_i = (-1)^i e has zero central
  strain at every interior node: a zero-energy mode, held only by the boundary closures. It
  grows in the 2 s runs (measured: segment lengths from 0.12 ds to 2.5 ds at 85 deg, N = 25),
  while theta, which never sees it, stays close to the other schemes. Kept as the measured
  reason why ``collocated`` uses the flux form for the forces; not a ground truth.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from crgpr.physics.stencils import _segment_strains


@njit(cache=True)
def _nodal_strains(q, i, ds):
    """Stretch and shear at node i from the paper's stencils (forward slope at the clamped node
    0, central slope elsewhere) with cos, sin of theta_i and the node's quadrature weight a."""
    if i == 0:
        ex = (q[1, 0] - q[0, 0]) / ds
        ey = (q[1, 1] - q[0, 1]) / ds
        a = 0.5
    else:
        ex = (q[i + 1, 0] - q[i - 1, 0]) / (2.0 * ds)
        ey = (q[i + 1, 1] - q[i - 1, 1]) / (2.0 * ds)
        a = 1.0
    c = math.cos(q[i, 2])
    s = math.sin(q[i, 2])
    return c * ex + s * ey, -s * ex + c * ey, c, s, a


@njit(cache=True)
def _collocated_forces(q, ds, EA, GA, EI_seg, kappa0, nu1_0, nu2_0, b_nl, k_base, th_base, F):
    """Generalised elastic forces (N+1, 3) of ``collocated`` (module docstring); same arguments
    as rod._internal_forces. Returns rod.py's elastic energy V of q (the reference energy; this
    scheme does not conserve it exactly)."""
    n = q.shape[0] - 1
    for i in range(n + 1):
        F[i, 0] = 0.0
        F[i, 1] = 0.0
        F[i, 2] = 0.0
    V = 0.0
    # segments: translational fluxes q_{j+1/2} and bending moments m_{j+1/2}
    for j in range(n):
        ex, ey, c, s, nu1, nu2 = _segment_strains(q, j, ds)
        n1 = EA * (nu1 - nu1_0)
        n2 = GA * (nu2 - nu2_0)
        qx = n1 * c - n2 * s
        qy = n1 * s + n2 * c
        F[j, 0] += qx
        F[j + 1, 0] -= qx
        F[j, 1] += qy
        F[j + 1, 1] -= qy
        dk = (q[j + 1, 2] - q[j, 2]) / ds - kappa0
        mb = EI_seg[j] * dk * (1.0 + b_nl * dk * dk)
        F[j, 2] += mb
        F[j + 1, 2] -= mb
        V += ds * (
            0.5 * EA * (nu1 - nu1_0) ** 2
            + 0.5 * GA * (nu2 - nu2_0) ** 2
            + EI_seg[j] * (0.5 * dk * dk + 0.25 * b_nl * dk**4)
        )
    # nodal couples c_i (i = 0..N-1; c_N = 0 at the free tip), weight w_i ds
    for i in range(n):
        nu1, nu2, c, s, a = _nodal_strains(q, i, ds)
        F[i, 2] += a * ds * (nu1 * GA * (nu2 - nu2_0) - nu2 * EA * (nu1 - nu1_0))
    if k_base < np.inf:
        F[0, 2] -= k_base * (q[0, 2] - th_base)
        V += 0.5 * k_base * (q[0, 2] - th_base) ** 2
    return V


@njit(cache=True)
def _nodal_forces(q, ds, EA, GA, EI_seg, kappa0, nu1_0, nu2_0, b_nl, k_base, th_base, F):
    """Nodal generalised elastic forces -dV_c/dq (N+1, 3) of ``collocated_nodal``; returns V_c.

    Same arguments as rod._internal_forces (module docstring for the stencils)."""
    n = q.shape[0] - 1
    for i in range(n + 1):
        F[i, 0] = 0.0
        F[i, 1] = 0.0
        F[i, 2] = 0.0
    V = 0.0
    # stretch and shear at the nodes 0..N-1 (q_N = 0 at the free tip)
    for i in range(n):
        nu1, nu2, c, s, a = _nodal_strains(q, i, ds)
        n1 = EA * (nu1 - nu1_0)
        n2 = GA * (nu2 - nu2_0)
        qx = n1 * c - n2 * s
        qy = n1 * s + n2 * c
        if i == 0:  # x'_0 = (x_1 - x_0) / ds
            F[0, 0] += a * qx
            F[0, 1] += a * qy
            F[1, 0] -= a * qx
            F[1, 1] -= a * qy
        else:  # x'_i = (x_{i+1} - x_{i-1}) / (2 ds)
            F[i - 1, 0] += 0.5 * qx
            F[i - 1, 1] += 0.5 * qy
            F[i + 1, 0] -= 0.5 * qx
            F[i + 1, 1] -= 0.5 * qy
        F[i, 2] += a * ds * (nu1 * n2 - nu2 * n1)
        V += a * ds * (0.5 * EA * (nu1 - nu1_0) ** 2 + 0.5 * GA * (nu2 - nu2_0) ** 2)
    # bending: compact second difference (moments at the half nodes, m_N = 0)
    for j in range(n):
        dk = (q[j + 1, 2] - q[j, 2]) / ds - kappa0
        mb = EI_seg[j] * dk * (1.0 + b_nl * dk * dk)
        F[j, 2] += mb
        F[j + 1, 2] -= mb
        V += ds * EI_seg[j] * (0.5 * dk * dk + 0.25 * b_nl * dk**4)
    if k_base < np.inf:
        F[0, 2] -= k_base * (q[0, 2] - th_base)
        V += 0.5 * k_base * (q[0, 2] - th_base) ** 2
    return V
