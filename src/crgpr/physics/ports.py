"""Input ports of the rod: the G(z) u term of the port-Hamiltonian model (paper eqs. (9), (13)).

    dz/dt = (J - R) dH/dz + G(z) u,        y = G(z)^T dH/dz  (collocated output)

Gravity stays the constant input it always was (``grav`` of the kernels). The actuation
channels all act on the free tip (node N); each is one column of G, a generalised nodal force
(F_x, F_y, M) per unit input at the tip, evaluated at the tip angle theta_N:

=================  =====  =====================================  ============================
channel            unit   G column at the tip (F_x, F_y, M)      collocated output y
=================  =====  =====================================  ============================
``tip_force_x``    N      (1, 0, 0)                              tip velocity v_x [m/s]
``tip_force_y``    N      (0, 1, 0)                              tip velocity v_y [m/s]
``tip_moment``     N m    (0, 0, 1)  (counter-clockwise)         tip angular rate omega [rad/s]
``tendon_tension`` N      (-cos theta_N, -sin theta_N, d)        -t . v_tip + d omega [m/s]
=================  =====  =====================================  ============================

The tendon of tension T runs at the offset d (config key ``ports.tendon_offset_m``; d > 0 on
the counter-clockwise side) and is anchored at the tip: a compressive follower force T along
the tip tangent t = (cos theta_N, sin theta_N) plus the couple T d, a state-dependent G(z). The
power delivered by the inputs is y^T u (the tip's nodal velocities dotted with the nodal
forces). ``_tip_columns`` is the one implementation of G: the compiled ground-truth kernel
(``integrator.run_rod``) and the Python rollouts (``Ports`` through ``run_verlet``) both call it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

CHANNELS: tuple[str, ...] = ("tip_force_x", "tip_force_y", "tip_moment", "tendon_tension")
UNITS: dict[str, str] = {"tip_force_x": "N", "tip_force_y": "N", "tip_moment": "N m",
                         "tendon_tension": "N"}
OUTPUTS: dict[str, str] = {"tip_force_x": "tip v_x [m/s]", "tip_force_y": "tip v_y [m/s]",
                           "tip_moment": "tip omega [rad/s]",
                           "tendon_tension": "-t.v_tip + d omega_tip [m/s]"}


@njit(cache=True)
def _tip_columns(theta_tip, d, G):
    """The G columns (n_channels, 3) at the tip: generalised force (F_x, F_y, M) per unit input
    of each channel in ``CHANNELS`` order (module table), for the tip angle ``theta_tip`` [rad]
    and the tendon offset ``d`` [m]."""
    for k in range(4):
        for c in range(3):
            G[k, c] = 0.0
    G[0, 0] = 1.0
    G[1, 1] = 1.0
    G[2, 2] = 1.0
    G[3, 0] = -math.cos(theta_tip)
    G[3, 1] = -math.sin(theta_tip)
    G[3, 2] = d


@njit(cache=True)
def _tip_load(theta_tip, u, d, G, P):
    """Tip load P = G(theta_tip)^T u (F_x, F_y, M) of the input values u (n_channels,); G is
    scratch space (n_channels, 3)."""
    _tip_columns(theta_tip, d, G)
    for c in range(3):
        acc = 0.0
        for k in range(4):
            acc += G[k, c] * u[k]
        P[c] = acc


@dataclass(frozen=True)
class Ports:
    """The actuation channels of one rod: G(z) and the collocated outputs (module table).

    ``tendon_offset_m``: the tendon's offset d [m] (config key ``ports.tendon_offset_m``).
    States may carry leading batch axes (..., N+1, 3); inputs u are (..., n_channels)."""

    tendon_offset_m: float

    def columns(self, q: np.ndarray) -> np.ndarray:
        """G columns at the tip (..., n_channels, 3) for configurations q (..., N+1, 3)."""
        th = np.asarray(q, dtype=float)[..., -1, 2]
        out = np.empty((*th.shape, len(CHANNELS), 3))
        flat_th, flat = th.reshape(-1), out.reshape(-1, len(CHANNELS), 3)
        for i in range(flat_th.size):
            _tip_columns(float(flat_th[i]), self.tendon_offset_m, flat[i])
        return out

    def nodal_forces(self, q: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Generalised nodal forces G(z) u (..., N+1, 3) [N, N, N m] of the inputs u."""
        out = np.zeros(np.shape(q))
        out[..., -1, :] = np.einsum("...kc,...k->...c", self.columns(q), np.asarray(u, dtype=float))
        return out

    def outputs(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Collocated outputs y = G(z)^T dH/dz (..., n_channels): the G columns dotted with the
        tip's velocities v = dq/dt (..., N+1, 3); the input power is y . u."""
        return np.einsum("...kc,...c->...k", self.columns(q), np.asarray(v, dtype=float)[..., -1, :])

    def to_dict(self) -> dict[str, object]:
        """The G used (for manifests and file metadata)."""
        return {"channels": list(CHANNELS), "units": UNITS, "outputs": OUTPUTS,
                "node": "tip", "tendon_offset_m": self.tendon_offset_m}


def ports_from_config(cfg: dict) -> Ports:
    """The channels of the config's ``ports`` section."""
    return Ports(float(cfg["ports"]["tendon_offset_m"]))
