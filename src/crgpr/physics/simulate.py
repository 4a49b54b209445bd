"""Ground-truth simulation of the planar Cosserat rod dPHS (paper Sec. IV) and its energy.

``simulate`` returns a ``Trajectory`` of arrays; ``trajectory_frame`` and ``energy_frame``
turn it into the tidy tables written to Parquet (one row per (t, node); one row per t).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from crgpr.io import frame_to_grid
from crgpr.physics.dissipation import kelvin_voigt_flow
from crgpr.physics.integrator import Integration, run_rod
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.ports import CHANNELS, Ports
from crgpr.physics.rod import (
    STATE_NAMES,
    check_scheme,
    free_mask,
    internal_forces,
    masses,
    node_weights,
    segment_EI,
    segment_rest_curvature,
    straight_rod,
)
from crgpr.physics.signals import Inputs

TRAJECTORY_COLUMNS: tuple[str, ...] = ("theta0_deg", "t", "node", "s", *STATE_NAMES)
ENERGY_COLUMNS: tuple[str, ...] = ("t", "H", "dissipation_rate", "dissipated")


@dataclass
class Trajectory:
    """A rod trajectory: t (n_t,), q and p (n_t, N+1, 3); p is momentum per length.

    p = [rho A v_x, rho A v_y, rho I omega] (the paper's definition, also at a tip mass).
    """

    theta0_deg: float
    t: np.ndarray
    q: np.ndarray
    p: np.ndarray
    params: RodParams
    dissipated: np.ndarray | None = None
    scheme: str = "variational"  # spatial scheme that produced it (its energy's V)
    dq: np.ndarray | None = None  # tangent records (n_t, m, N+1, 3) of ``simulate``'s dq0/dv0
    input_work: np.ndarray | None = None  # cumulative work of the actuation inputs [J]
    u: np.ndarray | None = None  # actuation inputs (n_t, n_channels) at the recorded times
    ports: Ports | None = None  # the channels' G (tendon offset)
    force_work: np.ndarray | None = None  # a learned rollout's work of -H_q + gravity along its drifts [J]

    @property
    def z(self) -> np.ndarray:
        """State (n_t, N+1, 6) = [x, y, theta, p_x, p_y, p_theta]."""
        return np.concatenate([self.q, self.p], axis=-1)


def dissipation_coefficients(params: RodParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exponential rates lambda_t, lambda_r [1/s] and quadratic-drag factors k [1/m] per node."""
    m_t, m_r = masses(params)
    wds = node_weights(params.N) * params.ds
    lam_t = (params.zeta + params.viscous_drag) * wds / m_t
    lam_r = params.zeta * wds / m_r
    k_quad = params.air_drag * wds / m_t
    return lam_t, lam_r, k_quad


def rod_kernel_args(params: RodParams, theta_base: float) -> tuple:
    """Trailing arguments of the compiled force kernel for these parameters (the material as
    its EI(s), rest-curvature profile and law vector, ``rod._internal_forces``)."""
    return (params.ds, params.EA, params.GA, segment_EI(params), segment_rest_curvature(params),
            params.material.law_vector(), params.kappa0, params.nu1_0, params.nu2_0,
            params.nonlinear_stiffness, params.base_spring, theta_base)


def kelvin_voigt_kick(params: RodParams, m_r: np.ndarray, lam_r: np.ndarray, dt: float) -> np.ndarray:
    """``run_rod``'s ``kv``: the rod's rotational half-kick flow over dt/2 with its Kelvin-Voigt
    damping ``internal_damping`` and rotational rates lam_r (``dissipation.kelvin_voigt_flow``;
    an empty stack without Kelvin-Voigt damping)."""
    return kelvin_voigt_flow(params.internal_damping, params.ds, m_r, lam_r, free_mask(params)[:, 2],
                             0.5 * dt)


def simulate(
    theta0_deg: float,
    params: RodParams,
    settings: SimSettings,
    q0: np.ndarray | None = None,
    v0: np.ndarray | None = None,
    dq0: np.ndarray | None = None,
    dv0: np.ndarray | None = None,
    inputs: Inputs | None = None,
    ports: Ports | None = None,
) -> Trajectory:
    """Simulate the rod released at rest, straight, at theta0 [deg] from +x (clamped base).

    ``q0``/``v0`` (N+1, 3) override the initial configuration / velocities (the base node
    stays where ``q0`` puts it). ``dq0``/``dv0`` (m, N+1, 3): directions of (q0, v0) whose
    exact derivatives dq/d(direction) of the discrete trajectory are returned in
    ``Trajectory.dq`` (tangent-linear scheme, ``integrator.run_rod``; variational scheme).
    ``settings.scheme`` picks the spatial discretisation of the elastic forces (rod.py or
    collocated.py); masses, damping, gravity and the integrator are the same for both.
    ``inputs`` (with ``ports``, the channels' G): the actuation u(t) at the tip
    (``physics.ports``), sampled at every step time k dt; their work is ``input_work``.
    Raises ``SimulationDiverged`` if the run blows up.
    """
    check_scheme(params, settings.scheme)
    th0 = math.radians(theta0_deg)
    q_init = straight_rod(th0, params) if q0 is None else np.array(q0, dtype=float)
    v_init = np.zeros_like(q_init) if v0 is None else np.array(v0, dtype=float)
    m_t, m_r = masses(params)
    lam_t, lam_r, k_quad = dissipation_coefficients(params)
    grav = -m_t * params.g
    u = None
    if inputs is not None:
        if ports is None:
            raise ValueError("inputs need the ports (channels' G) they drive")
        u = inputs.values(np.arange(settings.n_steps + 1) * settings.dt)
    out: Integration = run_rod(
        q_init, v_init, free_mask(params), m_t, m_r, lam_t, lam_r, k_quad, grav,
        rod_kernel_args(params, float(q_init[0, 2])), settings.dt, settings.n_steps,
        settings.record_every,
        kv=kelvin_voigt_kick(params, m_r, lam_r, settings.dt),
        scheme=settings.scheme, dq0=dq0, dv0=dv0, u=u,
        tendon_offset=0.0 if ports is None else ports.tendon_offset_m,
    )
    p = out.v.copy()
    p[..., 0] *= params.rhoA
    p[..., 1] *= params.rhoA
    p[..., 2] *= params.rhoI
    return Trajectory(float(theta0_deg), out.t, out.q, p, params, out.dissipated, settings.scheme, out.dq,
                      out.input_work, None if u is None else u[::settings.record_every], ports)


def velocities(traj: Trajectory) -> np.ndarray:
    """Velocities (n_t, N+1, 3) from the momenta per length."""
    pr = traj.params
    return traj.p / np.array([pr.rhoA, pr.rhoA, pr.rhoI])


def energy(traj: Trajectory) -> dict[str, np.ndarray]:
    """Total energy H (kinetic + elastic + gravity + base spring) and dissipation rate per t.

    The elastic energy is that of the trajectory's own scheme (rod.py's V, or collocated.py's V_c).

    dissipation_rate = H_z^T R H_z integrated over the rod (paper Sec. V, E(t)), with the
    drag effects and the Kelvin-Voigt term sum_j ds c kappa_dot_j^2 added when present.
    """
    pr = traj.params
    m_t, m_r = masses(pr)
    v = velocities(traj)
    ke = 0.5 * (m_t * (v[..., 0] ** 2 + v[..., 1] ** 2) + m_r * v[..., 2] ** 2).sum(axis=-1)
    pe_g = (m_t * pr.g * traj.q[..., 1]).sum(axis=-1)
    th_base = float(traj.q[0, 0, 2])
    ve = np.array([internal_forces(q, pr, th_base, traj.scheme)[1] for q in traj.q])
    wds = node_weights(pr.N) * pr.ds
    speed2 = v[..., 0] ** 2 + v[..., 1] ** 2  # clamped DOFs have v = 0
    rate = ((pr.zeta + pr.viscous_drag) * wds * speed2).sum(axis=-1)
    rate += (pr.zeta * wds * v[..., 2] ** 2).sum(axis=-1)
    rate += (pr.air_drag * wds * speed2**1.5).sum(axis=-1)
    rate += pr.internal_damping / pr.ds * (np.diff(v[..., 2], axis=-1) ** 2).sum(axis=-1)
    return {"H": ke + ve + pe_g, "kinetic": ke, "elastic": ve, "gravity": pe_g,
            "dissipation_rate": rate}


def trajectory_frame(traj: Trajectory) -> pd.DataFrame:
    """Tidy long table, one row per (t, node), columns ``TRAJECTORY_COLUMNS`` (SI units)."""
    n_t, n_nodes, _ = traj.q.shape
    s = np.arange(n_nodes) * traj.params.ds
    return pd.DataFrame({
        "theta0_deg": np.full(n_t * n_nodes, traj.theta0_deg),
        "t": np.repeat(traj.t, n_nodes),
        "node": np.tile(np.arange(n_nodes, dtype=np.int32), n_t),
        "s": np.tile(s, n_t),
        "x": traj.q[..., 0].ravel(),
        "y": traj.q[..., 1].ravel(),
        "theta": traj.q[..., 2].ravel(),
        "p_x": traj.p[..., 0].ravel(),
        "p_y": traj.p[..., 1].ravel(),
        "p_theta": traj.p[..., 2].ravel(),
    })


def energy_frame(traj: Trajectory) -> pd.DataFrame:
    """One row per t: total energy H [J], dissipation rate [W], cumulative dissipated [J].

    An actuated trajectory adds the cumulative work of its inputs ``input_work`` [J] (the
    integrator's kick bookkeeping; H(t) - H(0) = input_work - dissipated up to the scheme's
    O(dt^2) energy error), and per channel the input u and the collocated output y."""
    e = energy(traj)
    diss = traj.dissipated if traj.dissipated is not None else np.full(traj.t.shape, np.nan)
    df = pd.DataFrame({"t": traj.t, "H": e["H"], "dissipation_rate": e["dissipation_rate"],
                       "dissipated": diss, "kinetic": e["kinetic"], "elastic": e["elastic"],
                       "gravity": e["gravity"]})
    if traj.input_work is not None:
        df["input_work"] = traj.input_work
        if traj.u is not None and traj.ports is not None:
            y = traj.ports.outputs(traj.q, velocities(traj))
            for k, c in enumerate(CHANNELS):
                df[f"u_{c}"] = traj.u[:, k]
                df[f"y_{c}"] = y[:, k]
    return df


def trajectory_from_frame(df: pd.DataFrame, params: RodParams) -> Trajectory:
    """Inverse of ``trajectory_frame`` (rows sorted by t, node)."""
    t, z = frame_to_grid(df, STATE_NAMES, "trajectory")
    theta0 = float(df["theta0_deg"].iloc[0]) if "theta0_deg" in df else float("nan")
    return Trajectory(theta0, t, z[..., :3].copy(), z[..., 3:].copy(), params)
