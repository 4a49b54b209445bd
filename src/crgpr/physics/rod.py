"""Variational spatial discretisation of the planar Cosserat rod (paper eqs. (4), (9); Sec. III-A).

Grid
    N segments of length ds = L0 / N between nodes i = 0..N at s_i = i ds. Node 0 is the
    clamped base, node N the free tip. Every node carries the full state
    z_i = [x_i, y_i, theta_i, p_x,i, p_y,i, p_theta,i] (theta at the nodes, as in the paper).

Strains and stress resultants live on the segments j = 0..N-1 (between nodes j, j+1):
    x'_j = (x_{j+1} - x_j) / ds,   y'_j likewise,
    theta_bar_j = (theta_j + theta_{j+1}) / 2         (mid-segment angle)
    nu1_j = cos(theta_bar) x' + sin(theta_bar) y',   nu2_j = -sin(theta_bar) x' + cos(theta_bar) y'
    kappa_j = (theta_{j+1} - theta_j) / ds
    n_1 = EA (nu1 - nu1^0), n_2 = GA (nu2 - nu2^0), m = EI (kappa - kappa^0)
    (the linear material; material.py: the nonlinear laws of n_1 and m, EI(s), kappa^0(s))
    q_x = n_1 cos(theta_bar) - n_2 sin(theta_bar),  q_y = n_1 sin(theta_bar) + n_2 cos(theta_bar)
The mid-segment angle is one-point (reduced) quadrature of the shear energy, which avoids
shear locking.

Energy (the discrete Hamiltonian)
    H = sum_i w_i ds [ (p_x^2 + p_y^2) / (2 rho A) + p_theta^2 / (2 rho I) ]
        + sum_j ds W(nu1_j, nu2_j, kappa_j)              (+ base spring, tip mass terms)
with trapezoid weights w_0 = w_N = 1/2, w_i = 1 otherwise (lumped mass).

Equations of motion are Hamilton's equations of this H, i.e. the nodal generalised forces
are F = -dV/dq exactly, which gives a discrete dPHS whose energy is conserved by the
symplectic integrator when zeta = 0:
    F_x,i = q_x,i - q_x,i-1      (= ds d/ds q_x: the discrete -delta H / delta x)
    F_theta,i = m_i - m_{i-1} + (ds/2) [c_{i-1} + c_i],   c_j = nu1_j n_2,j - nu2_j n_1,j
The variational derivative (per unit length) at node i is H_z,i = (dV/dq_i) / (w_i ds).

Tip (free end): there is no segment N, so q_N = m_N = 0: the conditions n_x = n_y = m = 0
are natural boundary conditions of the discrete energy, not imposed by hand. The tip node
has half a segment of mass and rotational inertia.

Sign note: the paper writes delta H / delta theta = -d_s m + (nu1 n_y - nu2 n_x). The
variational derivative of its own W is -d_s m - (nu1 n_y - nu2 n_x); the paper's sign
would make the couple inject energy. We use the variational one.

Gravity is the constant port input G u = [0, 0, 0, 0, -rho A g, 0] (per length), not part
of H_z; energy files report the total energy H + int rho A g y ds, which is what the
damping alone dissipates.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from crgpr.physics.collocated import _collocated_forces, _nodal_forces
from crgpr.physics.material import axial_force, bend_law, bending_moment, stretch_law
from crgpr.physics.params import SCHEMES, RodParams
from crgpr.physics.stencils import _segment_strains

STATE_NAMES: tuple[str, ...] = ("x", "y", "theta", "p_x", "p_y", "p_theta")


def node_weights(n_segments: int) -> np.ndarray:
    """Trapezoid weights w_i of the lumped mass (1/2 at both ends)."""
    w = np.ones(n_segments + 1)
    w[0] = w[-1] = 0.5
    return w


def segment_EI(params: RodParams) -> np.ndarray:
    """Bending stiffness per segment, EI(s) = EI (1 - g s / L0) f(s) D(s) at segment midpoints
    [N m^2] (f, D: the material's profile and defect, material.py)."""
    s_mid = (np.arange(params.N) + 0.5) * params.ds
    EI = params.EI * (1.0 - params.stiffness_gradient * s_mid / params.L0)
    if params.material.stiffness_profile or params.material.defect_factor != 1.0:
        EI = EI * params.material.ei_factor(s_mid / params.L0)
    return EI


def segment_rest_curvature(params: RodParams) -> np.ndarray:
    """The rest-curvature profile k(s) at segment midpoints [1/m]; kappa^0(s) = kappa0 + k(s)."""
    s_mid = (np.arange(params.N) + 0.5) * params.ds
    return params.material.rest_curvature(s_mid / params.L0)


def check_scheme(params: RodParams, scheme: str) -> None:
    """Refuse a material the spatial scheme does not implement (collocated: linear laws,
    uniform rest curvature; EI(s) profiles and the defect are fine)."""
    if scheme != "variational" and params.material.needs_variational:
        raise ValueError(f"rod.material: the {scheme!r} scheme implements linear laws and a uniform "
                         "rest curvature only; use simulation.scheme: variational for this material")


def masses(params: RodParams) -> tuple[np.ndarray, np.ndarray]:
    """Lumped translational [kg] and rotational [kg m^2] nodal masses."""
    w = node_weights(params.N)
    m_t = params.rhoA * w * params.ds
    m_t[-1] += params.tip_mass
    m_r = params.rhoI * w * params.ds
    return m_t, m_r


@njit(cache=True)
def _internal_forces(q, ds, EA, GA, EI_seg, kap_seg, law, kappa0, nu1_0, nu2_0, b_nl, k_base, th_base, F):
    """Generalised internal forces F = -dV/dq (nodal, not per length); returns elastic V.

    ``kap_seg`` (N,): the rest-curvature profile k(s) added to ``kappa0``; ``law``: the material
    laws (``material.Material.law_vector``, energies in ``material.bend_law``/``stretch_law``)."""
    n = q.shape[0] - 1
    for i in range(n + 1):
        F[i, 0] = 0.0
        F[i, 1] = 0.0
        F[i, 2] = 0.0
    V = 0.0
    for j in range(n):
        ex, ey, c, s, nu1, nu2 = _segment_strains(q, j, ds)
        dk = (q[j + 1, 2] - q[j, 2]) / ds - (kappa0 + kap_seg[j])
        n1, w_s, _ = stretch_law(law, EA, nu1 - nu1_0)
        n2 = GA * (nu2 - nu2_0)
        mb, w_b, _ = bend_law(law, EI_seg[j], dk, b_nl)
        qx = n1 * c - n2 * s
        qy = n1 * s + n2 * c
        F[j, 0] += qx
        F[j + 1, 0] -= qx
        F[j, 1] += qy
        F[j + 1, 1] -= qy
        tq = 0.5 * ds * (n1 * nu2 - n2 * nu1)
        F[j, 2] -= tq - mb
        F[j + 1, 2] -= tq + mb
        V += ds * (w_s + 0.5 * GA * (nu2 - nu2_0) ** 2 + w_b)
    if k_base < np.inf:
        F[0, 2] -= k_base * (q[0, 2] - th_base)
        V += 0.5 * k_base * (q[0, 2] - th_base) ** 2
    return V


def free_mask(params: RodParams) -> np.ndarray:
    """1.0 where a degree of freedom moves, 0.0 where the clamp holds it (N+1, 3)."""
    free = np.ones((params.N + 1, 3))
    free[0, :2] = 0.0
    if params.clamped:
        free[0, 2] = 0.0
    return free


def internal_forces(q: np.ndarray, params: RodParams, theta_base: float = 0.0,
                    scheme: str = "variational") -> tuple[np.ndarray, float]:
    """Nodal generalised elastic forces -dV/dq (N+1, 3) and the elastic energy V [J].

    ``theta_base`` is the spring's rest angle when ``params.base_spring`` is finite;
    ``scheme``: 'variational' (this module), 'collocated' (collocated.py; V is this module's) or
    'collocated_nodal' (collocated.py; V is its own V_c).
    """
    if scheme not in SCHEMES:
        raise ValueError(f"unknown spatial scheme {scheme!r}; expected one of {SCHEMES}")
    check_scheme(params, scheme)
    F = np.empty_like(q, dtype=float)
    q = np.ascontiguousarray(q, dtype=float)
    tail = (params.kappa0, params.nu1_0, params.nu2_0, params.nonlinear_stiffness, params.base_spring,
            theta_base, F)
    if scheme == "variational":
        V = _internal_forces(q, params.ds, params.EA, params.GA, segment_EI(params),
                             segment_rest_curvature(params), params.material.law_vector(), *tail)
    else:
        kernel = _collocated_forces if scheme == "collocated" else _nodal_forces
        V = kernel(q, params.ds, params.EA, params.GA, segment_EI(params), *tail)
    return F, V


def strains(q: np.ndarray, params: RodParams) -> dict[str, np.ndarray]:
    """Segment strains and stress resultants for states q (..., N+1, 3), vectorised."""
    x, y, th = q[..., 0], q[..., 1], q[..., 2]
    ex = np.diff(x, axis=-1) / params.ds
    ey = np.diff(y, axis=-1) / params.ds
    tb = 0.5 * (th[..., 1:] + th[..., :-1])
    c, s = np.cos(tb), np.sin(tb)
    nu1 = c * ex + s * ey
    nu2 = -s * ex + c * ey
    kappa = np.diff(th, axis=-1) / params.ds
    law = params.material.law_vector()
    n1 = axial_force(law, params.EA, nu1 - params.nu1_0)
    n2 = params.GA * (nu2 - params.nu2_0)
    dk = kappa - (params.kappa0 + segment_rest_curvature(params))
    m = bending_moment(law, segment_EI(params), dk, params.nonlinear_stiffness)
    return {
        "nu1": nu1, "nu2": nu2, "kappa": kappa, "n1": n1, "n2": n2, "m": m,
        "q_x": n1 * c - n2 * s, "q_y": n1 * s + n2 * c, "theta_bar": tb,
    }


def segment_moment_law(params: RodParams, kappa: np.ndarray) -> np.ndarray:
    """The true bending law m(kappa, s_j) [N m] of every segment j at the curvatures ``kappa``
    (n,): (n, N), each segment with its own EI(s_j) and rest curvature kappa^0(s_j) (eqs. (5),
    (10) with the material's law, docs/materials.md; the elastic part: Kelvin-Voigt excluded)."""
    kappa = np.asarray(kappa, dtype=float)[:, None]
    dk = kappa - (params.kappa0 + segment_rest_curvature(params))[None, :]
    return bending_moment(params.material.law_vector(), segment_EI(params), dk, params.nonlinear_stiffness)


def variational_derivative(q: np.ndarray, p: np.ndarray, params: RodParams) -> np.ndarray:
    """Discrete H_z = [dH/dx, dH/dy, dH/dtheta, p_x/rhoA, p_y/rhoA, p_theta/rhoI] per node.

    ``q`` and ``p`` are (N+1, 3); ``p`` is momentum per length. Internal energy only
    (gravity is the input G u). Returns (N+1, 6); rows of clamped DOFs are still filled.
    """
    F, _ = internal_forces(q, params)
    w = node_weights(params.N) * params.ds
    hz = np.empty((params.N + 1, 6))
    hz[:, :3] = -F / w[:, None]
    hz[:, 3] = p[:, 0] / params.rhoA
    hz[:, 4] = p[:, 1] / params.rhoA
    hz[:, 5] = p[:, 2] / params.rhoI
    return hz


def straight_rod(theta0_rad: float, params: RodParams) -> np.ndarray:
    """Configuration q (N+1, 3) of the straight rod at rest inclined at theta0 from +x.

    With nu1^0 = 1 the rod is unstretched; with a rest curvature the initial state is
    still the straight rod (the effect then shows as motion).
    """
    s = params.s * params.nu1_0
    q = np.empty((params.N + 1, 3))
    q[:, 0] = s * math.cos(theta0_rad)
    q[:, 1] = s * math.sin(theta0_rad)
    q[:, 2] = theta0_rad
    return q
