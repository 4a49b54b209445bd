"""The residual used to name an effect: the "cut-moment" form of the port-Hamiltonian residual.

Summing the discrete momentum balances of ``rod.py`` from the free tip inwards removes the
stiff axial and shear forces (which positions cannot resolve): with nodal applied-minus-
inertial forces F_i = f_i - m_i a_i and couples C_i = mu_i - J_i alpha_i, the internal force
of segment j is Q_j = sum_{i>j} F_i (exact) and the bending moment the dynamics require is

    mb_j^dyn = sum_{i>j} C_i - tq_j - 2 sum_{i>j} tq_i,    tq_j = (Q_j x (r_{j+1} - r_j)) / 2,

the discrete moment balance of the rod beyond the cut. The constitutive law gives
mb_j^const = EI_j dk_j (1 + b dk_j^2) + c dkappa_j/dt (the Kelvin-Voigt term). Their
difference rho_j(t) = mb^const - mb^dyn is the generalised force (moment) the nominal
model misses at segment j; it is affine in every candidate's coefficient, and
d rho / d coefficient is that candidate's signature. The base spring shows in the clamp
constraint instead: theta_0 - theta_b = C B(t), C = 1/k, with B the moment the rod exerts
on the base (node-0 moment balance).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crgpr.physics.params import RodParams
from crgpr.physics.rod import node_weights, segment_EI


def dyn_moment(pos: np.ndarray, F: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bending moments mb_j^dyn (n_t, N) and the base moment B (n_t,) of applied loads.

    ``pos`` (n_t, N+1, 2) node positions, ``F`` (n_t, N+1, 2) nodal forces (applied minus
    inertial), ``C`` (n_t, N+1) nodal couples (applied minus rotary inertia). Linear in F, C.
    B = mb_0 - tq_0 + C_0 is the moment the rod and the node-0 loads exert on the base.
    """
    G = np.cumsum(F[:, ::-1], axis=1)[:, ::-1]  # G_i = sum_{k >= i} F_k
    Q = G[:, 1:]  # Q_j = sum_{i > j} F_i, j = 0..N-1
    dr = np.diff(pos, axis=1)
    tq = 0.5 * (Q[..., 0] * dr[..., 1] - Q[..., 1] * dr[..., 0])
    Cs = np.cumsum(C[:, ::-1], axis=1)[:, ::-1][:, 1:]  # sum_{i > j} C_i
    tq_beyond = np.cumsum(tq[:, ::-1], axis=1)[:, ::-1] - tq  # sum_{i > j} tq_i
    mb = Cs - tq - 2.0 * tq_beyond
    B = mb[:, 0] - tq[:, 0] + C[:, 0]
    return mb, B


@dataclass
class Residual:
    """Nominal residual and candidate signatures on the measured kinematics.

    rho (n_t, N): mb^const - mb^dyn of the nominal model [N m]; sig[name] (n_t, N): d rho /
    d coefficient; base_y (n_t,): theta_0 - theta_b [rad]; base_sig (n_t,): B(t) [N m].
    """

    rho: np.ndarray
    sig: dict[str, np.ndarray]
    base_y: np.ndarray
    base_sig: np.ndarray
    mb_const: np.ndarray
    mb_dyn: np.ndarray


def curvature_terms(theta: np.ndarray, params: RodParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """kappa_j, dk_j = kappa_j - kappa0 and EI_j (segment values) for nodal angles."""
    kappa = np.diff(theta, axis=-1) / params.ds
    return kappa, kappa - params.kappa0, segment_EI(params)


def residual(q: np.ndarray, v: np.ndarray, a: np.ndarray, params: RodParams,
             theta_base: float, phi0: np.ndarray | None = None) -> Residual:
    """Cut-moment residual of the nominal model and every candidate's signature.

    q, v, a: (n_t, N+1, 3) smoothed measured kinematics (x, y, theta). ``theta_base`` is the
    rest angle of a base spring (the measured base angle at the first sample); base_y is the
    base angle estimated from the base segment and the base moment, minus theta_base;
    ``phi0`` (n_t,) is the base segment's angle (default: the mean of the first two nodal
    angles, which is phi_0 for angles built by ``measured.node_angles``).
    """
    pr = params
    w = node_weights(pr.N) * pr.ds
    m_t = pr.rhoA * w
    m_t[-1] += pr.tip_mass
    m_r = pr.rhoI * w
    pos = q[..., :2]
    vel = v[..., :2]
    speed = np.linalg.norm(vel, axis=-1)
    # nominal applied loads: gravity (G u), damping zeta (R) and any nominal effect terms
    f = np.zeros_like(pos)
    f[..., 1] -= m_t * pr.g
    f -= ((pr.zeta + pr.viscous_drag) * w)[None, :, None] * vel
    f -= (pr.air_drag * w)[None, :, None] * speed[..., None] * vel
    F = f - m_t[None, :, None] * a[..., :2]
    C = -(pr.zeta * w) * v[..., 2] - m_r * a[..., 2]
    mb_dyn, B = dyn_moment(pos, F, C)
    _, dk, EI = curvature_terms(q[..., 2], pr)
    b = pr.nonlinear_stiffness
    kdot = np.diff(v[..., 2], axis=-1) / pr.ds  # dkappa/dt per segment
    mb_const = EI * dk * (1.0 + b * dk**2) + pr.internal_damping * kdot
    # Curvature the nominal law needs for the dynamic moment (regression calibration):
    # signatures built from it carry no camera noise of theta, so the constitutive
    # candidates are free of the errors-in-variables bias of the measured curvature.
    m_el = mb_dyn - pr.internal_damping * kdot  # the elastic part of the dynamic moment
    dk_dyn = m_el / EI
    for _ in range(30 if b > 0 else 0):  # invert m = EI dk (1 + b dk^2) (monotone)
        dk_dyn -= (EI * dk_dyn * (1.0 + b * dk_dyn**2) - m_el) / (EI * (1.0 + 3.0 * b * dk_dyn**2))
    zero_C = np.zeros(C.shape)
    sig: dict[str, np.ndarray] = {}
    sig["viscous_drag"] = -dyn_moment(pos, -w[None, :, None] * vel, zero_C)[0]
    sig["air_drag"] = -dyn_moment(pos, -w[None, :, None] * speed[..., None] * vel, zero_C)[0]
    Ftip = np.zeros_like(pos)
    Ftip[:, -1, 0] = -a[:, -1, 0]
    Ftip[:, -1, 1] = -(a[:, -1, 1] + pr.g)
    sig["tip_mass"] = -dyn_moment(pos, Ftip, zero_C)[0]
    sig["nonlinear_stiffness"] = EI * dk_dyn**3
    sig["rest_curvature"] = -EI * (1.0 + 3.0 * b * dk_dyn**2)
    s_mid = (np.arange(pr.N) + 0.5) * pr.ds
    sig["stiffness_gradient"] = -pr.EI * (s_mid / pr.L0) * dk_dyn * (1.0 + b * dk_dyn**2)
    sig["internal_damping"] = kdot
    # a uniform stiffness error scales the elastic moment itself: built from the dynamic
    # moment its signature would share that moment's acceleration noise with the residual
    # (a bias towards a = 1); the measured curvature's noise only attenuates it slightly
    sig["stiffness_scale"] = EI / (1.0 + pr.stiffness_scale) * dk * (1.0 + b * dk**2)
    # base angle from the base segment's direction and the curvature the base moment implies
    # (exact for rod.py: theta_bar_0 = (theta_0 + theta_1) / 2, theta_1 - theta_0 = ds kappa_0)
    if phi0 is None:
        phi0 = 0.5 * (q[:, 0, 2] + q[:, 1, 2])
    theta0_est = phi0 - 0.5 * pr.ds * (dk_dyn[:, 0] + pr.kappa0)
    return Residual(mb_const - mb_dyn, sig, theta0_est - theta_base, B, mb_const, mb_dyn)
