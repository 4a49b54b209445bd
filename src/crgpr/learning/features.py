"""Inputs and targets of the gradient GPs (paper Sec. III-B step 3, eqs. (13)-(16),
GPR 1-6), shared by training (gradient_models.py) and rollouts (learned.py).

Targets. With J - R of eq. (8) and G u = [0, 0, 0, 0, -rho A g, 0] (gravity is the input):
    H_p  = dq/dt                                  (rows 1-3 of eq. (9))
    H_q  = -(dp/dt - G u) - zeta H_p              (rows 4-6)
per node and unit length. In the discrete rod (rod.py) the nodal force is
F_x,i = q_x,i - q_x,i-1 with q on segments and q_N = 0 at the free tip, and F_x,i = -w_i ds H_x,i;
so the paper's q_x, q_y (whose s-derivative gives dH/dx, dH/dy) are the tip-to-base sums
    q_j = sum_{i > j} w_i ds H_x,i        (segments j = 0..N-1),
and the learned dH/dx is recovered as -(q_i - q_{i-1}) / (w_i ds).

Paper features ('paper', methods cr_gpr and cr_gpr_fd):
    GPR 1, 2 (segments):  [theta_bar_j, dx/ds_j, dy/ds_j]  (mid-segment angle, segment slopes: the
                          discrete rod's own strain stencil, i.e. central differences at s_j+1/2)
    GPR 3 (nodes 1..N):   [theta_i, theta_{i-1}, theta_{i+1}, d2theta/ds2_i, dx/ds_i, dy/ds_i] (nodal
                          stencils of prefilter.spatial_derivatives; free-tip ghost theta_{N+1} =
                          theta_{N-1}, i.e. kappa = 0 at the tip)
    GPR 4-6:              p_x -> H_px, p_y -> H_py, p_theta -> H_ptheta
Angles are only defined modulo 2 pi: with ``theta_wrap`` every angle feature is shifted by the
multiple of 2 pi that puts theta (theta_i, or theta_bar_j) into the window [c - pi, c + pi)
centred on the middle c of the training range (neighbours get the same shift, so differences
are kept). The paper does not say how it treats the angle's periodicity.

Objective features ('objective', cr_gpr_objective, beyond the paper): frame-indifferent
segment strains; targets are the local stress resultants recovered from the same H_z:
    n1, n2 from [nu1_j, nu2_j, kappa_j]                 (q rotated into the segment frame)
    m      from [kappa_j, kappa_{j-1}, kappa_{j+1}, nu1_j, nu2_j] (ghosts kappa_{-1} = kappa_0,
                                                         kappa_N = 0 at the free tip)
with m from the moment balance of the discrete rod, tip to base:
    m_{i-1} = m_i + ds/2 (c_i + c_{i-1}) + w_i ds H_theta,i,  m_N = c_N = 0,
    c_j = nu1_j n2_j - nu2_j n1_j.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from crgpr.learning.prefilter import spatial_derivatives
from crgpr.physics.params import RodParams
from crgpr.physics.rod import node_weights
from crgpr.physics.stencils import _segment_strains

PAPER_Q_FEATURES = ("theta_bar", "dx_ds", "dy_ds")
PAPER_THETA_FEATURES = ("theta_i", "theta_im1", "theta_ip1", "d2theta_ds2", "dx_ds", "dy_ds")
OBJ_N_FEATURES = ("nu1", "nu2", "kappa")
OBJ_M_FEATURES = ("kappa", "kappa_jm1", "kappa_jp1", "nu1", "nu2")


def segment_arclength(N: int, ds: float) -> np.ndarray:
    """Arclength of the segment midpoints s_j = (j + 1/2) ds, j = 0..N-1 [m] (where kappa_j lives)."""
    return (np.arange(N) + 0.5) * ds


def theta_center(theta: np.ndarray) -> float:
    """Centre of the training range of theta (n_t, N+1) over the free nodes 1..N: the middle of
    the 2 pi window that ``wrap_shift`` maps angle features into."""
    th = theta[:, 1:]
    return 0.5 * (float(th.min()) + float(th.max()))


def wrap_shift(theta: np.ndarray, center: float | None) -> np.ndarray:
    """The multiple of 2 pi to add to theta to land in [center - pi, center + pi)."""
    if center is None:
        return np.zeros_like(theta)
    wrapped = center + np.mod(theta - center + math.pi, 2 * math.pi) - math.pi
    return wrapped - theta


# Columns of ``segment_table`` (..., N, 12): the objective feature matrices are slices of it,
# OBJ_N_FEATURES = columns 0:3 and OBJ_M_FEATURES = columns 2:7 (nu1, nu2 appear twice).
SEGMENT_COLUMNS = ("nu1", "nu2", "kappa", "kappa_jm1", "kappa_jp1", "nu1", "nu2", "cos", "sin", "ex", "ey",
                   "theta_bar")
_N_COLS, _M_COLS = slice(0, 3), slice(2, 7)


@njit(cache=True)
def _segment_table(q, ds, out):
    """Fill out (B, N, 12) with the ``SEGMENT_COLUMNS`` of the rods q (B, N+1, 3): the strains of
    the shared stencil (``stencils._segment_strains``), kappa_j = (theta_j+1 - theta_j) / ds and
    its neighbours with the ghosts kappa_-1 = kappa_0, kappa_N = 0 (free tip)."""
    n_seg = q.shape[1] - 1
    for b in range(q.shape[0]):
        for j in range(n_seg):
            ex, ey, c, s, nu1, nu2 = _segment_strains(q[b], j, ds)
            r = out[b, j]
            r[0] = nu1
            r[5] = nu1
            r[1] = nu2
            r[6] = nu2
            r[2] = (q[b, j + 1, 2] - q[b, j, 2]) / ds
            r[7] = c
            r[8] = s
            r[9] = ex
            r[10] = ey
            r[11] = 0.5 * (q[b, j, 2] + q[b, j + 1, 2])
        for j in range(n_seg):
            out[b, j, 3] = out[b, max(j - 1, 0), 2]
            out[b, j, 4] = out[b, j + 1, 2] if j + 1 < n_seg else 0.0


def segment_table(q: np.ndarray, ds: float) -> np.ndarray:
    """Segment quantities (..., N, 12) of configurations q (..., N+1, 3), columns ``SEGMENT_COLUMNS``."""
    q = np.asarray(q, dtype=float)
    q2 = np.ascontiguousarray(q.reshape(-1, *q.shape[-2:]))
    out = np.empty((q2.shape[0], q2.shape[1] - 1, len(SEGMENT_COLUMNS)))
    _segment_table(q2, float(ds), out)
    return out.reshape(*q.shape[:-2], *out.shape[1:])


def segments(x: np.ndarray, y: np.ndarray, th: np.ndarray, ds: float) -> dict[str, np.ndarray]:
    """Segment quantities (..., N): slopes, mid-segment angle, strains nu1, nu2, kappa."""
    t = segment_table(np.stack([x, y, th], axis=-1), ds)
    return {name: t[..., SEGMENT_COLUMNS.index(name)] for name in SEGMENT_COLUMNS}


def paper_q_features(x: np.ndarray, y: np.ndarray, th: np.ndarray, ds: float,
                     center: float | None) -> np.ndarray:
    """GPR 1, 2 inputs per segment (..., N, 3)."""
    sg = segments(x, y, th, ds)
    tb = sg["theta_bar"]
    return np.stack([tb + wrap_shift(tb, center), sg["ex"], sg["ey"]], axis=-1)


def paper_theta_features(x: np.ndarray, y: np.ndarray, th: np.ndarray, ds: float,
                         center: float | None) -> np.ndarray:
    """GPR 3 inputs at the free nodes 1..N (..., N, 6)."""
    dxs, dys, th2 = spatial_derivatives(x, y, th, ds)
    ghost = th[..., -2:-1]  # theta_{N+1} = theta_{N-1} (kappa = 0 at the free tip)
    th_ext = np.concatenate([th, ghost], axis=-1)
    ti = th[..., 1:]
    sh = wrap_shift(ti, center)
    return np.stack([ti + sh, th_ext[..., :-2] + sh, th_ext[..., 2:] + sh, th2[..., 1:],
                     dxs[..., 1:], dys[..., 1:]], axis=-1)


def objective_n_features(x: np.ndarray, y: np.ndarray, th: np.ndarray, ds: float) -> np.ndarray:
    """n1, n2 inputs per segment (..., N, 3): [nu1, nu2, kappa]."""
    return np.ascontiguousarray(segment_table(np.stack([x, y, th], axis=-1), ds)[..., _N_COLS])


def objective_m_features(x: np.ndarray, y: np.ndarray, th: np.ndarray, ds: float) -> np.ndarray:
    """m inputs per segment (..., N, 5): [kappa_j, kappa_{j-1}, kappa_{j+1}, nu1_j, nu2_j]."""
    return np.ascontiguousarray(segment_table(np.stack([x, y, th], axis=-1), ds)[..., _M_COLS])


def objective_inputs(table: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The n1, n2 and the m inputs (views (..., N, 3), (..., N, 5)) of a ``segment_table``."""
    return table[..., _N_COLS], table[..., _M_COLS]


def hz_targets(arr: dict[str, np.ndarray], params: RodParams) -> np.ndarray:
    """H_z = (J - R)^-1 (dz/dt - G u) per node (n_t, N+1, 6), eq. (13).

    G u is gravity plus, where ``arr`` carries it, the actuation inputs' ``G_u`` (n_t, N+1, 3)
    per unit length (``physics.ports``); ``damping_torque`` (same shape), a learned bending
    damping's nodal couples (``learning.damping``), is booked the same way, as a known force, so
    that the elastic targets no longer hold it."""
    hz = np.empty((*arr["x"].shape, 6))
    hp = np.stack([arr["dx_dt"], arr["dy_dt"], arr["dtheta_dt"]], axis=-1)
    dp = np.stack([arr["dp_x_dt"], arr["dp_y_dt"], arr["dp_theta_dt"]], axis=-1)
    gu = np.array([0.0, -params.rhoA * params.g, 0.0])
    if "G_u" in arr:
        gu = gu + arr["G_u"]
    if "damping_torque" in arr:
        gu = gu + arr["damping_torque"]
    hz[..., 3:] = hp
    hz[..., :3] = -(dp - gu) - params.zeta * hp
    return hz


def q_from_hz(hx: np.ndarray, params: RodParams) -> np.ndarray:
    """Tip-to-base sums q_j = sum_{i>j} w_i ds H_i (..., N) from nodal H (..., N+1)."""
    wds = node_weights(params.N) * params.ds
    contrib = hx[..., 1:] * wds[1:]
    return np.flip(np.cumsum(np.flip(contrib, axis=-1), axis=-1), axis=-1)


def forces_from_q(qx: np.ndarray, params: RodParams) -> np.ndarray:
    """Nodal force F_i = q_i - q_{i-1} (q_N = 0, q_{-1} = 0) per unit length: -(dH/dx) (..., N+1)."""
    wds = node_weights(params.N) * params.ds
    pad = np.zeros((*qx.shape[:-1], 1))
    return (np.concatenate([qx, pad], axis=-1) - np.concatenate([pad, qx], axis=-1)) / wds


def moments_from_htheta(hth: np.ndarray, c: np.ndarray, params: RodParams) -> np.ndarray:
    """Segment moments m_j (..., N) from nodal H_theta (..., N+1) and couples c_j (..., N)."""
    wds = node_weights(params.N) * params.ds
    N = params.N
    m = np.zeros_like(c)
    m_next = np.zeros(c.shape[:-1])
    c_next = np.zeros(c.shape[:-1])
    for i in range(N, 0, -1):  # node i gives m_{i-1}
        m_prev = m_next + 0.5 * params.ds * (c_next + c[..., i - 1]) + wds[i] * hth[..., i]
        m[..., i - 1] = m_prev
        m_next, c_next = m_prev, c[..., i - 1]
    return m


def theta_forces_objective(n1: np.ndarray, n2: np.ndarray, m: np.ndarray, nu1: np.ndarray,
                           nu2: np.ndarray, params: RodParams) -> np.ndarray:
    """-H_theta per unit length at nodes (..., N+1): (m_i - m_{i-1} + ds/2 (c_i + c_{i-1})) / (w_i ds)."""
    wds = node_weights(params.N) * params.ds
    c = nu1 * n2 - nu2 * n1
    pad = np.zeros((*m.shape[:-1], 1))
    mm = np.concatenate([m, pad], axis=-1) - np.concatenate([pad, m], axis=-1)
    cc = np.concatenate([c, pad], axis=-1) + np.concatenate([pad, c], axis=-1)
    return (mm + 0.5 * params.ds * cc) / wds


@njit(cache=True)
def _objective_forces(n1, n2, m, table, wds, ds, out):
    """``objective_forces`` on rows (B, N), (B, N, 12) -> out (B, N+1, 3)."""
    n_seg = n1.shape[1]
    for b in range(n1.shape[0]):
        qx0 = qy0 = m0 = c0 = 0.0  # segment i-1's values (none below the base)
        for i in range(n_seg + 1):
            qx1 = qy1 = m1 = c1 = 0.0  # segment i's values (none beyond the free tip)
            if i < n_seg:
                cs, sn = table[b, i, 7], table[b, i, 8]
                qx1 = n1[b, i] * cs - n2[b, i] * sn
                qy1 = n1[b, i] * sn + n2[b, i] * cs
                m1 = m[b, i]
                c1 = table[b, i, 0] * n2[b, i] - table[b, i, 1] * n1[b, i]
            out[b, i, 0] = (qx1 - qx0) / wds[i]
            out[b, i, 1] = (qy1 - qy0) / wds[i]
            out[b, i, 2] = ((m1 - m0) + 0.5 * ds * (c1 + c0)) / wds[i]
            qx0, qy0, m0, c0 = qx1, qy1, m1, c1


def objective_forces(n1: np.ndarray, n2: np.ndarray, m: np.ndarray, table: np.ndarray, wds: np.ndarray,
                     ds: float) -> np.ndarray:
    """-H_q per unit length at the nodes (..., N+1, 3) from the segments' stress resultants n1, n2
    and moments m (..., N) and their ``segment_table``: ``forces_from_q`` of the resultants in the
    lab frame (q = n1 cos - n2 sin, n1 sin + n2 cos) and ``theta_forces_objective``'s moment
    balance, in one compiled pass (tests/test_gradient_models.py checks the two agree). ``wds``
    (N+1,): the nodes' lengths w_i ds (``node_weights`` times ds); ``ds`` the segment length."""
    shape = table.shape[:-1]
    if not n1.shape == n2.shape == m.shape == shape:  # the rollout's case: no broadcasting
        shape = np.broadcast_shapes(n1.shape, n2.shape, m.shape, shape)
    n_col = table.shape[-1]
    tab = table if table.shape[:-1] == shape else np.broadcast_to(table, (*shape, n_col))
    tab = np.ascontiguousarray(tab.reshape(-1, shape[-1], n_col))

    def rows(a: np.ndarray) -> np.ndarray:
        a = a if a.shape == shape else np.broadcast_to(a, shape)
        return np.ascontiguousarray(a.reshape(-1, shape[-1]), dtype=float)

    out = np.empty((tab.shape[0], shape[-1] + 1, 3))
    _objective_forces(rows(n1), rows(n2), rows(m), tab, np.asarray(wds, dtype=float), float(ds), out)
    return out.reshape(*shape[:-1], shape[-1] + 1, 3)
