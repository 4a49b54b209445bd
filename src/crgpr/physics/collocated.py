"""Collocated nodal finite-difference discretisation of the planar Cosserat rod (paper eqs. (4)-(10),
Sec. III-A; issue 11 part 2): the discretisation whose stencils the paper's GPR 3 inputs
(eq. (15): theta_i, theta_{i-1}, theta_{i+1}, d2theta/ds2_i, dx/ds_i, dy/ds_i) are.

Grid and state as in rod.py (nodes i = 0..N, s_i = i ds, node 0 clamped, node N free), same
lumped masses, damping and gravity input; only the elastic force kernel differs.

Strains and resultants AT THE NODES (rod.py has them on segments):
    x'_i = (x_{i+1} - x_{i-1}) / (2 ds)            i = 1..N-1 (central difference)
    x'_0 = (x_1 - x_0) / ds                          clamped base (one-sided, first order)
    nu1_i = cos(theta_i) x'_i + sin(theta_i) y'_i,  nu2_i = -sin(theta_i) x'_i + cos(theta_i) y'_i
    n1_i = EA (nu1_i - nu1^0), n2_i = GA (nu2_i - nu2^0)          (eq. (10))
    q_x,i = n1_i cos(theta_i) - n2_i sin(theta_i),  q_y,i = n1_i sin(theta_i) + n2_i cos(theta_i)
    c_i = nu1_i n2_i - nu2_i n1_i                     (the nu x n couple)
    free tip: q_N = 0, c_N = 0, m_N = 0               (n = 0, m = 0 at s = L0, imposed)
Nodal equations per unit length (eq. (9) rows 4-6 with J - R of eq. (8)):
    dp_x,i/dt = (q_x,i+1 - q_x,i-1) / (2 ds) - zeta v_x,i          i = 1..N-1 (central difference)
    dp_x,N/dt = (0 - q_x,N-1) / ds                                   (ghost q_N+1 = 2 q_N - q_N-1)
    dp_theta,i/dt = d_s m_i + c_i,  d_s m_i = (m_i+1/2 - m_i-1/2) / ds,  m_j+1/2 = EI (kappa_j - kappa^0)
with kappa_j = (theta_j+1 - theta_j) / ds: for the paper's uniform linear rod
d_s m_i = EI (theta_i+1 - 2 theta_i + theta_i-1) / ds^2, the paper's d2theta/ds2 stencil
(prefilter.spatial_derivatives), and at the tip d_s m_N = -m_N-1/2 / (ds/2) =
2 EI (theta_N-1 - theta_N) / ds^2 (ghost theta_N+1 = theta_N-1, the prefilter's tip stencil).
The bending term is the compact second difference, not a central difference of nodal moments
(that would reach theta_i+-2, outside the paper's stencil). So at every free node the nodal
couple is EXACTLY a function of GPR 3's inputs: dH/dtheta_i = -EI theta''_i - c(theta_i, x'_i, y'_i)
(tip: c = 0). The translational resultants are exact functions of (theta_i, x'_i, y'_i) at
the nodes (GPR 1, 2 written at nodes), but their divergence is a central difference.

What it conserves. The central difference with these closures is summation-by-parts: the nodal
forces F_i = w_i ds f_i are exactly -dV_c/dq of the collocated discrete energy
    V_c = sum_{i=0}^{N-1} a_i ds W_nt(nu1_i, nu2_i) + sum_j ds W_b(kappa_j),   a_0 = 1/2, a_i = 1,
(trapezoid quadrature of the stretch/shear energy with the tip's term zero by n(L0) = 0), so
the scheme is Hamiltonian for H_c = T + V_c, and Stormer-Verlet conserves H_c up to its bounded
O(dt^2) oscillation when zeta = 0 (tests/test_collocated.py measures it). What it does not
conserve: the variational rod's energy V of rod.py (a different quadrature), and the
odd-even ("checkerboard") displacement x_i = (-1)^i e has zero central-difference strain at
the interior nodes: it is a zero-energy mode of V_c, held only by the boundary closures.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _collocated_forces(q, ds, EA, GA, EI_seg, kappa0, nu1_0, nu2_0, b_nl, k_base, th_base, F):
    """Nodal generalised elastic forces -dV_c/dq (N+1, 3) of the collocated scheme; returns V_c.

    Same arguments as rod._internal_forces (module docstring for the stencils)."""
    n = q.shape[0] - 1
    for i in range(n + 1):
        F[i, 0] = 0.0
        F[i, 1] = 0.0
        F[i, 2] = 0.0
    V = 0.0
    # stretch and shear at the nodes 0..N-1 (q_N = 0 at the free tip)
    for i in range(n):
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
        nu1 = c * ex + s * ey
        nu2 = -s * ex + c * ey
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
