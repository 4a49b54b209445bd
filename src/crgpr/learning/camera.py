"""The rod state and its derivatives from camera positions (paper Sec. III-B step 2 and its Remark).

The paper's Remark: a real experiment observes positions only; theta follows from neighbouring
positions and the momenta from the known mass distribution. Given measured node positions
x_i(t), y_i(t) (``crgpr.measured.Measured``, validated by its loader), this module
returns the arrays of the derivative data set E (eq. (12)) in the schema of
``prefilter.prefiltered_arrays``, so the gradient GPs (``gradient_models.train_model_arrays``)
are trained exactly as from the simulator's full state:

* theta: chord angles psi_k = atan2(dy_k, dx_k) between markers; with the ``gp`` prefilter the
  nodal angles theta_i are fitted to them along s (the model's segment j lies at the mid-segment
  angle (theta_j + theta_{j+1})/2, exact for a rod without shear), theta_0 one clamp angle for
  the whole record, a penalty on the ``camera.learn.angle_penalty_order``-th difference of theta
  (``measured.kinematics.clamped_angle_fit``); with ``fd``, theta_i = (phi_{i-1} + phi_i)/2 of
  the raw segment angles and linear extrapolation at the ends (``kinematics.node_angles``);
* momenta per unit length (nominal rod): p_x = rho A dx/dt, p_y = rho A dy/dt,
  p_theta = rho I dtheta/dt (the simulator's definition, ``physics.simulate.Trajectory``);
* time derivatives by one of two prefilters:
  ``gp``: the project's GP smoother of the positions (``measured.smooth_kinematics``:
  Matern-5/2 + quadratic basis, hyperparameters and the noise level sigma_n fitted by the
  marginal likelihood on the data in metres, so the noise is estimated, not given; angle rates
  analytically from the smoothed position derivatives, fitted along s like the angles, the
  clamp's rate zero);
  ``fd``: central finite differences of the raw positions (``prefilter.fd_time_derivatives``),
  angles from the raw positions: the paper's ablation alternative;
* the clamped base: node 0 does not move, so its position and angle are the time means of the
  (smoothed) values and its rates are zero (with ``gp`` the fitted clamp angle is already one
  constant);
* frames within ``edge_trim_s`` of either end of the record are dropped (GP derivatives are
  least certain there), then at most ``n_t_out`` evenly spaced frames are kept;
* the bending law's moment targets smoothed as the curvatures are (``camera.learn.
  bending_targets: smoothed``; ``gp`` only): the clamped fit rebuilds the curvatures as
  kappa_hat = L kappa (``kinematics.curvature_operator``), a linear map that is far from the
  identity near the clamp, where the curvature's profile is not the penalty's; pairing kappa_hat
  with the moments m would teach the law the smoothing (on the paper's rod, a law 3 % too soft
  at 40 /m). The arrays carry L (``KAPPA_OPERATOR``) and ``gradient_models.training_data``
  pairs kappa_hat with L m, so a linear law is learned exactly whatever the smoothing (errors
  in variables of the reconstruction, not of the noise); for a nonlinear law L m differs from
  m(L kappa) at second order.

Nothing here assumes the data came from our simulator: with a ``node`` column the node grid is
the camera's (N = measured segments, s_i = i L0 / N); with an ``s`` column (markers anywhere,
``gp`` prefilter) the model keeps the config's grid and the state is rebuilt on it from the
markers (``measured.kinematics.smooth_kinematics``); the time grid is the camera's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from crgpr.learning.gradient_models import KAPPA_OPERATOR, training_data
from crgpr.learning.moment_prior import MomentPriorSettings, polynomial_law
from crgpr.learning.nominal import segment_curvature_snr
from crgpr.learning.prefilter import fd_time_derivatives, output_indices, spatial_derivatives
from crgpr.measured.kinematics import Kinematics, angle_kinematics, node_angles, smooth_kinematics
from crgpr.measured.records import Measured, MeasuredDataError
from crgpr.physics.params import RodParams
from crgpr.physics.rod import STATE_NAMES

PREFILTERS: tuple[str, ...] = ("gp", "fd")
SMOOTHED_WITH_MOMENT_PRIOR = ("camera.learn.bending_targets: smoothed (the curvature prior's operator L) "
                              "cannot be combined with camera.learn.moment_prior.passes > 0")


@dataclass(frozen=True)
class LearnSettings:
    """Section ``camera.learn`` of config.yaml (see its schema for units)."""

    gp_max_points: int
    hyper_points: int
    angle_penalty_order: int
    edge_trim_s: float
    n_t_out: int
    bending_targets: str
    snr_min: float
    moment_prior: MomentPriorSettings

    @classmethod
    def from_config(cls, c: dict) -> LearnSettings:
        return cls(gp_max_points=int(c["gp_max_points"]), hyper_points=int(c["hyper_points"]),
                   angle_penalty_order=int(c["angle_penalty_order"]), edge_trim_s=float(c["edge_trim_s"]),
                   n_t_out=int(c["n_t_out"]), bending_targets=str(c["bending_targets"]),
                   snr_min=float(c["snr_min"]),
                   moment_prior=MomentPriorSettings.from_config(c["moment_prior"]))


def check_node_grid(meas: Measured, params: RodParams, why: str = "crgpr learn") -> None:
    """Raw positions used as nodal states (the ``fd`` prefilter, full-state files) need every
    node of the model grid (s_i = i ds) at every frame, none missing."""
    if meas.s.size != params.N + 1 or not np.allclose(meas.s, params.s, atol=1e-9 * params.L0):
        raise MeasuredDataError(f"{meas.source}: markers at s = {np.round(meas.s, 6).tolist()} m; "
                                f"{why} needs one per node of the model grid "
                                f"(N + 1 = {params.N + 1}, s = i ds)")
    bad = ~(np.isfinite(meas.x) & np.isfinite(meas.y))
    if bad.any():
        raise MeasuredDataError(f"{meas.source}: {int(bad.sum())} missing (NaN) or screened-out "
                                f"positions; {why} needs complete frames")


def fd_kinematics(meas: Measured) -> Kinematics:
    """Raw positions, central differences in time, angles and their rates from the raw positions."""
    h = meas.dt
    x, y = meas.x, meas.y
    vx, ax = fd_time_derivatives(x, h)
    vy, ay = fd_time_derivatives(y, h)
    phi, w, al = angle_kinematics(x, y, vx, vy, ax, ay)
    q = np.stack([x, y, node_angles(phi)], axis=-1)
    v = np.stack([vx, vy, node_angles(w)], axis=-1)
    a = np.stack([ax, ay, node_angles(al)], axis=-1)
    return Kinematics(meas.t, q, v, a, float("nan"), phi[:, 0].copy(), meas.s.copy())


def gp_kinematics(meas: Measured, params: RodParams, st: LearnSettings, seed: int,
                  moment_weights: tuple[np.ndarray, float] | None = None) -> Kinematics:
    """The GP prefilter of the positions (noise level fitted on the data), see module docstring.

    ``measured.kinematics.smooth_kinematics`` on the model grid, the base clamped: the nodal
    angles are fitted along s with one clamp angle for the record and the difference of order
    ``camera.learn.angle_penalty_order`` penalised (``kinematics.clamped_angle_fit``), or that
    difference of a moment profile (``moment_weights``: ``kinematics.weighted_angle_fit``).
    """
    return smooth_kinematics(meas, params, seed=seed, max_points=st.gp_max_points,
                             hyper_points=st.hyper_points, clamp_order=st.angle_penalty_order,
                             moment_weights=moment_weights)


def kinematics(meas: Measured, params: RodParams, prefilter: str, st: LearnSettings, seed: int) -> Kinematics:
    """Positions, velocities and accelerations (x, y, theta) by the chosen prefilter.

    ``gp`` takes markers anywhere along the rod (any number the loader accepts, base marker
    optional) with dropped frames and occlusions, and returns the state on the model grid;
    ``fd`` differentiates raw positions, so it needs a complete marker at every model node.
    """
    if prefilter == "gp":
        return gp_kinematics(meas, params, st, seed)
    if prefilter == "fd":
        check_node_grid(meas, params, "the fd prefilter (raw positions as nodal states)")
        return fd_kinematics(meas)
    raise ValueError(f"unknown prefilter {prefilter!r}; expected one of {PREFILTERS}")


def clamp_base(kin: Kinematics) -> Kinematics:
    """Clamped base: node 0 at its time-mean position and angle, zero rates."""
    q, v, a = kin.q.copy(), kin.v.copy(), kin.a.copy()
    q[:, 0, :] = q[:, 0, :].mean(axis=0)
    v[:, 0, :] = 0.0
    a[:, 0, :] = 0.0
    return Kinematics(kin.t, q, v, a, kin.noise_std_m, kin.base_segment_angle, kin.s_markers, kin.kappa_noise,
                      kin.kappa_operator)


def kept_frames(t: np.ndarray, edge_trim_s: float, n_out: int) -> np.ndarray:
    """Indices of the frames used for training: edges trimmed, at most n_out evenly spaced."""
    inner = np.flatnonzero((t >= t[0] + edge_trim_s - 1e-12) & (t <= t[-1] - edge_trim_s + 1e-12))
    if inner.size < 3:
        raise ValueError(f"only {inner.size} frames remain after trimming {edge_trim_s:g} s at both "
                         "ends of the record; record longer or lower camera.learn.edge_trim_s")
    return inner[output_indices(inner.size, n_out)]


def state_arrays(kin: Kinematics, params: RodParams, idx: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Arrays of the derivative data set E (schema of ``prefilter.prefiltered_arrays``).

    z = (x, y, theta, rho A vx, rho A vy, rho I omega); dz/dt and d2z/dt2 from the kinematics
    (d2p/dt2, which no target uses, by central differences of dp/dt); spatial derivatives on
    the node grid of ``params`` (N must equal the measured segments).
    """
    if kin.q.shape[1] != params.N + 1:
        raise ValueError(f"{kin.q.shape[1]} measured nodes but the model has N + 1 = {params.N + 1}")
    mass = np.array([params.rhoA, params.rhoA, params.rhoI])
    z = np.concatenate([kin.q, kin.v * mass], axis=-1)
    d1 = np.concatenate([kin.v, kin.a * mass], axis=-1)
    h = float(np.median(np.diff(kin.t)))
    d2p = fd_time_derivatives(d1[..., 3:], h)[0]
    d2 = np.concatenate([kin.a, d2p], axis=-1)
    sel = slice(None) if idx is None else idx
    out: dict[str, np.ndarray] = {"t": kin.t[sel]}
    for k, name in enumerate(STATE_NAMES):
        out[name] = z[sel, :, k]
        out[f"d{name}_dt"] = d1[sel, :, k]
        out[f"d2{name}_dt2"] = d2[sel, :, k]
    out["s"] = np.broadcast_to(params.s, out["x"].shape).copy()
    out["dx_ds"], out["dy_ds"], out["d2theta_ds2"] = spatial_derivatives(out["x"], out["y"], out["theta"],
                                                                         params.ds)
    return out


def positions_to_state(meas: Measured, params: RodParams, prefilter: str, st: LearnSettings, seed: int,
                       moment_prior: bool = False,
                       add_inputs: Callable[[dict[str, np.ndarray]], None] | None = None
                       ) -> tuple[dict[str, np.ndarray], dict]:
    """Measured positions -> training arrays and a report (noise level, frames used).

    ``moment_prior`` (``crgpr learn``; ``gp`` prefilter): the reconstruction is repeated with the
    prior on the bending-moment profile (``learning.moment_prior``) for
    ``camera.learn.moment_prior.passes`` rounds; the report's ``moment_prior`` lists each round's
    law. ``add_inputs`` puts into the arrays what the moment targets need besides the state
    (an actuated record's G u, ``commands.learn``).
    """
    kin = clamp_base(kinematics(meas, params, prefilter, st, seed))
    idx = kept_frames(kin.t, st.edge_trim_s, st.n_t_out)
    arr = state_arrays(kin, params, idx)
    rounds: list[dict] = []
    if moment_prior and prefilter == "gp" and st.moment_prior.passes > 0:
        if st.bending_targets == "smoothed":
            raise ValueError(SMOOTHED_WITH_MOMENT_PRIOR)
        for _ in range(st.moment_prior.passes):
            if add_inputs is not None:
                add_inputs(arr)
            weights, entry = _moment_weights(kin, arr, params, st)
            rounds.append(entry)
            if weights is None:
                break
            kin = clamp_base(gp_kinematics(meas, params, st, seed, weights))
            arr = state_arrays(kin, params, idx)
    if not all(np.all(np.isfinite(v)) for v in arr.values()):
        raise ValueError(f"{meas.source}: the derived state has non-finite values")
    if st.bending_targets == "smoothed" and kin.kappa_operator is not None:
        arr[KAPPA_OPERATOR] = kin.kappa_operator
    report = {"prefilter": prefilter, "n_frames": int(meas.t.size), "n_frames_used": int(idx.size),
              "rate_hz": meas.rate_hz, "n_nodes": int(params.N + 1), "markers": meas.summary(),
              "noise_std_m_estimated": None if np.isnan(kin.noise_std_m) else float(kin.noise_std_m),
              "edge_trim_s": st.edge_trim_s,
              "kappa_noise_per_segment": None if kin.kappa_noise is None else
              [float(v) if np.isfinite(v) else None for v in kin.kappa_noise]}
    if rounds:
        report["moment_prior"] = rounds
    return arr, report


def _moment_weights(kin: Kinematics, arr: dict[str, np.ndarray], params: RodParams, st: LearnSettings
                    ) -> tuple[tuple[np.ndarray, float] | None, dict]:
    """One round of ``learning.moment_prior``: the pooled law of the bending samples of the
    segments that resolve their curvature (``snr_min``, as ``crgpr learn`` keeps them) and its
    secant weights at every frame's rebuilt curvatures; None where the law is linear or its
    secant is not positive over its covered range (``PolynomialLaw.admissible``)."""
    X, m = training_data(arr, params, "obj_m", None)
    n_t = arr["x"].shape[0]
    keep = np.ones(params.N, dtype=bool)
    if kin.kappa_noise is not None:
        keep = segment_curvature_snr(m.reshape(n_t, params.N), params.EI, kin.kappa_noise) >= st.snr_min
    if keep.sum() < 2:  # too few resolved segments for a law (crgpr learn refuses the record later)
        return None, {"segments": int(keep.sum()), "used": False}
    k = X[:, 0].reshape(n_t, params.N)[:, keep].ravel()
    law = polynomial_law(k, m.reshape(n_t, params.N)[:, keep].ravel(), st.moment_prior.degree_max,
                         st.moment_prior.blocks)
    entry = {"degree": law.degree, "centre": law.centre, "covered": [law.lo, law.hi], "steps": law.steps,
             "segments": int(keep.sum())}
    if law.degree == 1 or not law.admissible():
        entry["used"] = False
        return None, entry
    kappa_all = np.diff(kin.q[..., 2], axis=1) / params.ds
    w = law.relative_secant(kappa_all)
    entry.update(used=True, secant_min=float(w.min()), secant_max=float(w.max()))
    return (w, law.centre), entry


def curvature_calibration(kappa_hat: np.ndarray, kappa_noise: np.ndarray) -> np.ndarray:
    """Regression calibration of rebuilt curvatures (errors in variables; beyond the paper):
    (2, N) rows mu_j and lambda_j such that mu_j + lambda_j (kappa_hat_j - mu_j) = E[kappa_j |
    kappa_hat_j] for a Gaussian curvature seen with independent noise of sd sigma_j:
    mu_j the mean of ``kappa_hat`` (n_t, N) over frames, lambda_j = 1 - sigma_j^2 / var(kappa_hat_j),
    clipped to [0, 1], from ``kappa_noise`` (N,), the clamped angle fit's own noise estimate
    (``measured.kinematics.clamped_angle_fit``; NaN or 0: lambda = 1). A law regressed on
    kappa_hat has its slope attenuated by lambda_j on segment j (at SNR 2, 0.8); on the
    calibrated inputs a linear law's slope is unbiased."""
    k = np.asarray(kappa_hat, dtype=float)
    noise = np.asarray(kappa_noise, dtype=float)
    mu = k.mean(axis=0)
    var = k.var(axis=0)
    known = np.isfinite(noise) & (noise > 0) & (var > 0)
    lam = np.where(known, 1.0 - np.square(np.where(known, noise, 0.0)) / np.where(known, var, 1.0), 1.0)
    return np.stack([mu, np.clip(lam, 0.0, 1.0)])
