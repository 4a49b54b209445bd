"""Step 1 of the workflow, locating: where, when and in which state group the nominal model departs.

Theta RMSE at the markers per marker and per time window, the state group with the largest
normalised error, the net work of the missing terms from the port-Hamiltonian energy balance
dH/dt = -H_z^T R H_z + P_missing (paper eq. (7)-(9)), where along s the cut-moment residual
sits, and a per-segment stiffness error (``local_stiffness_error``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from crgpr.discovery.residual import Residual
from crgpr.discovery.settings import DiscoverySettings
from crgpr.measured.kinematics import Kinematics, marker_matrix
from crgpr.physics.params import RodParams
from crgpr.physics.rod import masses, node_weights, segment_EI
from crgpr.stats import autocorrelation_time

STATE_GROUPS: tuple[str, ...] = ("x", "y", "theta", "p_x", "p_y", "p_theta")


def _group_nrmse(kin: Kinematics, q_sim: np.ndarray, v_sim: np.ndarray, params: RodParams) -> dict:
    """Normalised RMSE (by the measured range) of the six state groups, free nodes."""
    scale = np.array([params.rhoA, params.rhoA, params.rhoI])
    meas = np.concatenate([kin.q, kin.v * scale], axis=-1)[:, 1:]
    sim = np.concatenate([q_sim, v_sim * scale], axis=-1)[:, 1:]
    out = {}
    for k, name in enumerate(STATE_GROUPS):
        rng = float(np.ptp(meas[..., k])) or 1.0
        out[name] = float(np.sqrt(np.mean((sim[..., k] - meas[..., k]) ** 2)) / rng)
    return out


def reduced_energy(kin: Kinematics, params: RodParams, theta_base: float) -> np.ndarray:
    """Nominal H of the measured states, rod taken unstretched and unsheared [J] (per t).

    Kinetic + bending (+ nominal base spring) + gravity; the stretch and shear energies are
    not resolvable from camera positions and are negligible for this rod.
    """
    m_t, m_r = masses(params)
    v = kin.v
    ke = 0.5 * (m_t * (v[..., 0] ** 2 + v[..., 1] ** 2) + m_r * v[..., 2] ** 2).sum(-1)
    dk = np.diff(kin.q[..., 2], axis=-1) / params.ds - params.kappa0
    b = params.nonlinear_stiffness
    vb = (params.ds * segment_EI(params) * (0.5 * dk**2 + 0.25 * b * dk**4)).sum(-1)
    if not params.clamped:
        vb = vb + 0.5 * params.base_spring * (kin.q[:, 0, 2] - theta_base) ** 2
    vg = (m_t * params.g * kin.q[..., 1]).sum(-1)
    return ke + vb + vg


def nominal_dissipation_rate(kin: Kinematics, params: RodParams) -> np.ndarray:
    """H_z^T R H_z of the nominal model on the measured velocities [W]."""
    w = node_weights(params.N) * params.ds
    v = kin.v
    sp2 = v[..., 0] ** 2 + v[..., 1] ** 2
    rate = ((params.zeta + params.viscous_drag) * w * sp2).sum(-1)
    rate = rate + (params.zeta * w * v[..., 2] ** 2).sum(-1)
    rate = rate + params.internal_damping / params.ds * (np.diff(v[..., 2], axis=-1) ** 2).sum(-1)
    return rate + (params.air_drag * w * sp2**1.5).sum(-1)


def time_windows(t: np.ndarray, window_s: float) -> list[tuple[float, float, np.ndarray]]:
    """Consecutive windows of about ``window_s`` covering t[0]..t[-1] (t from 0), each with its
    sample mask; the record is split into round(T / window_s) equal windows, so no window
    holds only the last sample (an arange of edges past t[-1] made a window [T, T] whose single
    end sample, where the GP derivatives are least reliable, was reported as the worst)."""
    n_win = max(1, int(round(float(t[-1]) / window_s)))
    edges = np.linspace(0.0, float(t[-1]), n_win + 1)
    out = []
    for i, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        sel = (t >= a) & ((t < b) if i < n_win - 1 else (t <= b))
        if sel.any():
            out.append((float(a), float(b), sel))
    return out


def local_stiffness_error(res: Residual, q_model: np.ndarray, params: RodParams, rows: slice
                          ) -> dict[str, Any]:
    """Where along s the bending law departs from the nominal one: a relative stiffness error
    d_j per segment (nominal EI_j too large by the fraction d_j), with its z-score.

    Per segment, the cut-moment residual rho_j = EI_j dk_j - mb_j^dyn is regressed on the
    measured elastic moment EI_j dk_j (a local version of ``stiffness_scale``'s signature).
    The measured curvature carries camera noise (errors in variables: near the free tip, where
    the true curvature vanishes, ordinary least squares returns d ~ 1 on effect-free data), so
    the regression uses the model's own curvature as the instrument (noise-free and
    independent of the camera noise): d_j = sum_t rho_j z_j / sum_t X_j z_j, z_j = EI_j k_j^model.
    Its standard error is deflated by the residual's autocorrelation time. Segment 0 (which
    needs the extrapolated base angle) is left out, as in the selection's regression. The
    peak is the segment of largest |d_j| / std_j; the extent, the segments above half of it.
    """
    y = res.rho[rows]
    X = res.sig["stiffness_scale"][rows]
    Z = segment_EI(params) * np.diff(q_model[rows, :, 2], axis=-1) / params.ds
    zx = np.sum(Z * X, axis=0)
    zx = np.where(np.abs(zx) > 0.0, zx, np.inf)
    d = np.sum(Z * y, axis=0) / zx
    r = y - X * d
    tau = autocorrelation_time(r[:, 1:], 0)
    std = np.sqrt(np.mean(r**2, axis=0) * np.sum(Z * Z, axis=0) * tau) / np.abs(zx)
    z = np.where(std > 0, d / np.where(std > 0, std, 1.0), 0.0)
    z[0] = 0.0
    s_mid = (np.arange(params.N) + 0.5) * params.ds
    peak = int(np.argmax(np.abs(z)))
    strong = np.nonzero(np.abs(z) >= 0.5 * abs(z[peak]))[0]
    return {"s_mid_m": [float(v) for v in s_mid], "relative_error": [float(v) for v in d],
            "std": [float(v) for v in std], "z": [float(v) for v in z],
            "peak_s_m": float(s_mid[peak]), "peak_relative_error": float(d[peak]), "peak_z": float(z[peak]),
            "extent_s_m": [float(s_mid[strong].min()), float(s_mid[strong].max())]}


def locate(kin: Kinematics, q_nom: np.ndarray, v_nom: np.ndarray, params: RodParams,
           st: DiscoverySettings, theta_base: float, res: Residual, rows: slice) -> dict[str, Any]:
    """Where (markers, and the residual moment along s), when and in which state group the
    nominal model departs from the data."""
    t = kin.t - kin.t[0]
    M = marker_matrix(kin.s_markers, params)
    s_cmp = kin.s_markers[kin.s_markers > 1e-9]
    err = q_nom[..., 2] @ M.T - kin.q[..., 2] @ M.T
    per_marker = np.sqrt(np.mean(err**2, axis=0))
    windows = [(a, b, float(np.sqrt(np.mean(err[sel] ** 2)))) for a, b, sel in time_windows(t, st.window_s)]
    worst = max(windows, key=lambda w: w[2])
    onset = next((w for w in windows if w[2] > st.min_gap_rad), None)
    top = np.nonzero(per_marker >= 0.5 * per_marker.max())[0]
    groups = _group_nrmse(kin, q_nom, v_nom, params)
    # energy balance: P_missing = dH/dt + H_z^T R H_z, integrated over the trimmed record
    H = reduced_energy(kin, params, theta_base)
    D = nominal_dissipation_rate(kin, params)
    tt = t[rows]
    P = np.gradient(H[rows], tt) + D[rows]
    W = float(H[rows][-1] - H[rows][0] + np.trapezoid(D[rows], tt))
    absW = float(np.trapezoid(np.abs(P), tt))
    # the residual moment along s (where a disturbance acts, not where its effect shows)
    s_mid = (np.arange(params.N) + 0.5) * params.ds
    rho_rms = np.sqrt(np.mean(res.rho[rows] ** 2, axis=0))
    peak = int(np.argmax(rho_rms))
    strong = np.nonzero(rho_rms >= 0.5 * rho_rms[peak])[0]
    local = local_stiffness_error(res, q_nom, params, rows)
    return {
        "markers_s_m": [float(s_cmp[i]) for i in top],
        "s_m": [float(s_cmp[top].min()), float(s_cmp[top].max())],
        "worst_marker_s_m": float(s_cmp[int(np.argmax(per_marker))]),
        "time_window_s": [worst[0], worst[1]],
        "onset_s": None if onset is None else onset[0],
        "residual_moment_peak_s_m": float(s_mid[peak]),
        "residual_moment_s_m": [float(s_mid[strong].min()), float(s_mid[strong].max())],
        "residual_moment_rms_Nm": [float(v) for v in rho_rms],
        "local_stiffness_error": local,
        "local_stiffness_peak_s_m": local["peak_s_m"],
        # p_theta = rho I dtheta/dt is below camera resolution: reported, not chosen
        "state_group": max((g for g in groups if g != "p_theta"), key=groups.get),
        "group_nrmse": groups,
        "character": "dissipative" if W < 0 else "conservative",
        "net_work_missing_J": W,
        "abs_work_missing_J": absW,
        "rmse_theta_per_marker": [float(x) for x in per_marker],
        "rmse_theta_per_window": [{"t0_s": a, "t1_s": b, "rmse": r} for a, b, r in windows],
    }
