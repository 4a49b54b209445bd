"""A learned passive bending damping m_d = c dkappa/dt, c >= 0, decided from the data.

The paper's model dz/dt = (J - R) dH/dz + G u (eqs. (7)-(9), Sec. III-A) fixes R to the
nominal zeta I. A viscoelastic rod (Kelvin-Voigt, ``rod.material.kelvin_voigt``) also has a
segment moment c dkappa_j/dt; the bending-moment targets of ``obj_m`` (eq. (13) through the
moment balance, ``learning.features``) then hold m_j = m_el(kappa_j) + c dkappa_j/dt. With
dkappa_j/dt = (omega_{j+1} - omega_j) / ds from the angular rates of the training state:

* joint fit: m_j = sum_{k <= D} a_jk u^k + c dkappa_j/dt, u = (kappa - mean) / std, one
  elastic polynomial of degree D = ``degree`` per segment j (it absorbs a stiffness varying
  along s and the per-segment bias of the targets near the base, which a single law would
  leave for c to explain), a single c for the rod, least squares with c >= 0 (one bound: the
  unconstrained optimum, or c = 0 and the elastic polynomials alone where that optimum has
  c < 0), so R = zeta I + the damping's
  K = (c / ds) D^T D is positive semi-definite for every state (``physics.dissipation``);
* decision by held-out contiguous time blocks, as ``learning.laws`` decides the symmetry: the
  samples (time-major rows) are cut into ``blocks`` blocks; each law, with and without the
  damping, is fitted without one block and predicts it; the damping is kept only where it
  predicts the held-out blocks consistently better: the mean over blocks of
  log(elastic error / damped error) above 1.96 standard errors, and its band (below) excludes
  c = 0. A rod without material
  damping then keeps R = zeta I and its training set, hence its model, is unchanged.
* the band of c: the delete-a-block jackknife, c +- 1.96 se.
* refinement by the rollout (``refine_by_rollout``, where ``camera.learn.record_fit`` is off;
  with it on, the record fit sizes c jointly with the bending law's warp,
  ``learning.record_fit``): the regression sees c dkappa/dt only as far as the targets
  resolve it: noisy camera rates attenuate it, and a bending law left nominal passes its
  shape error to it. Where the damping is kept, c is therefore refined as the one that best
  reproduces the training record itself: the learned rod (its elastic laws already trained) rolled out from
  the record's first state, RMSE of theta over the free nodes at the record's frames,
  minimised over log c in [c_fit / f, c_fit f] by golden section (f = ``refine_factor``,
  ``refine_evaluations`` rollouts; 0: no refinement).

Where the damping is kept, the elastic law is learned from the targets without c dkappa/dt
(``damping_torques``, booked like a known input in ``features.hz_targets``) and the rollout
applies c by its exact flow (``learning.learned.LearnedRod``, ``integrator.run_hamiltonian``).
Noisy angular rates (camera data) attenuate the fitted c (errors in variables).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from crgpr.learning.gradient_models import training_data
from crgpr.learning.laws import Z95, consistent_gain, heldout_blocks, jackknife_se, log_error_ratio
from crgpr.learning.learned import LearnedRod, free_angles_at, record_settings, rollout
from crgpr.physics.integrator import SimulationDiverged
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.ports import Ports
from crgpr.physics.rod import node_weights
from crgpr.physics.signals import Inputs

MODES: tuple[str, ...] = ("auto", "none")
DAMPING_TORQUE = "damping_torque"  # key of the prefilter arrays booked as a known force


@dataclass(frozen=True)
class DampingFit:
    """The learned bending damping and its decision (JSON-able)."""

    coefficient: float  # c the learned rod uses [N m^2 s] where kept (refined or record-fitted), else 0
    c_fit: float  # c >= 0 of the joint fit to all samples [N m^2 s]
    band_lo: float  # c_fit - 1.96 se (delete-a-block jackknife) [N m^2 s]
    band_hi: float  # c_fit + 1.96 se [N m^2 s]
    se: float  # jackknife standard error of c [N m^2 s]
    heldout_mse_elastic: float  # held-out-block mean squared error without damping [(N m)^2]
    heldout_mse_damped: float  # ... with it [(N m)^2]
    heldout_log_ratio: float  # mean over blocks of log(elastic / damped held-out error) [-]
    heldout_log_ratio_se: float  # its standard error over the blocks [-]
    kept: bool
    degree: int
    blocks: int
    n: int
    c_refined: float | None = None  # c of the rollout refinement [N m^2 s] (None: not refined)
    refine_rmse_theta: float | None = None  # its training-record RMSE of theta [rad]
    fit_rmse_theta: float | None = None  # the same RMSE with c_fit [rad]
    c_record_fit: float | None = None  # c of the record fit (learning.record_fit) [N m^2 s]

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def curvature_rates(omega: np.ndarray, ds: float) -> np.ndarray:
    """dkappa_j/dt = (omega_{j+1} - omega_j) / ds per segment (..., N) from nodal rates (..., N+1)."""
    return np.diff(omega, axis=-1) / ds


def _design(kappa: np.ndarray, segment: np.ndarray, center: float, scale: float, degree: int
            ) -> np.ndarray:
    """Per-segment polynomial columns: u^k on the rows of segment j, 0 elsewhere."""
    u = (kappa - center) / scale
    powers = np.stack([u**k for k in range(degree + 1)], axis=-1)
    segs = np.unique(segment)
    onehot = (segment[:, None] == segs[None, :]).astype(float)
    return (onehot[:, :, None] * powers[:, None, :]).reshape(kappa.size, -1)


def _fit(A: np.ndarray, kdot: np.ndarray, m: np.ndarray, damped: bool) -> tuple[np.ndarray, float]:
    """(elastic coefficients, c >= 0) of the least-squares fit, c = 0 when not ``damped``."""
    if damped:
        coef, *_ = np.linalg.lstsq(np.column_stack([A, kdot]), m, rcond=None)
        if coef[-1] > 0:
            return coef[:-1], float(coef[-1])
    coef, *_ = np.linalg.lstsq(A, m, rcond=None)
    return coef, 0.0


def fit_bending_damping(kappa: np.ndarray, kappa_dot: np.ndarray, m: np.ndarray, segment: np.ndarray,
                        degree: int, blocks: int) -> DampingFit:
    """The joint fit, its held-out decision and band (module doc) from law samples.

    ``kappa``, ``kappa_dot``, ``m``: (n,) curvatures, curvature rates and bending-moment targets,
    rows in time order; ``segment`` (n,): the segment of each row; ``degree``: the degree of
    the elastic polynomials; ``blocks`` (>= 2): contiguous held-out blocks."""
    kappa, kdot, m = (np.asarray(a, dtype=float).ravel() for a in (kappa, kappa_dot, m))
    segment = np.asarray(segment).ravel()
    if not kappa.size == kdot.size == m.size == segment.size:
        raise ValueError("fit_bending_damping: kappa, kappa_dot, m and segment must have the same size")
    n_par = np.unique(segment).size * (degree + 1) + 1
    if degree < 0 or blocks < 2 or kappa.size * (blocks - 1) < blocks * 2 * n_par:
        raise ValueError(f"fit_bending_damping: {kappa.size} samples cannot fill {blocks} blocks of a "
                         f"degree-{degree} law with damping")
    center, scale = float(kappa.mean()), float(kappa.std()) or 1.0
    A = _design(kappa, segment, center, scale, degree)
    _, c = _fit(A, kdot, m, True)
    cs, diff, e_el, e_d = [], [], 0.0, 0.0
    for test in heldout_blocks(kappa.size, blocks):
        ge, _ = _fit(A[~test], kdot[~test], m[~test], False)
        gd, cb = _fit(A[~test], kdot[~test], m[~test], True)
        cs.append(cb)
        ee = float(np.sum((m[test] - A[test] @ ge) ** 2))
        ed = float(np.sum((m[test] - A[test] @ gd - cb * kdot[test]) ** 2))
        e_el, e_d = e_el + ee, e_d + ed
        diff.append(log_error_ratio(ee, ed))
    se = jackknife_se(np.array(cs))
    mean, ratio_se, gain = consistent_gain(np.array(diff))
    # kept where it predicts the held-out blocks consistently better AND its band excludes c = 0
    # (a term the blocks cannot tell from none, e.g. noise a rate happens to correlate with on a
    # short record, is not a material damping)
    kept = bool(c > 0 and gain and c - Z95 * se > 0)
    return DampingFit(coefficient=c if kept else 0.0, c_fit=c, band_lo=c - Z95 * se, band_hi=c + Z95 * se,
                      se=se, heldout_mse_elastic=e_el / kappa.size, heldout_mse_damped=e_d / kappa.size,
                      heldout_log_ratio=mean, heldout_log_ratio_se=ratio_se, kept=kept,
                      degree=int(degree), blocks=int(blocks), n=int(kappa.size))


def damping_torques(kappa_dot: np.ndarray, c: float, params: RodParams) -> np.ndarray:
    """Nodal forces per unit length (..., N+1, 3) of the segment moments m_d = c dkappa/dt
    (..., N): the couple (m_d,i - m_d,i-1) / (w_i ds) at node i (m_d,-1 = m_d,N = 0), as the
    moment balance of ``features.theta_forces_objective`` books a segment moment."""
    md = c * np.asarray(kappa_dot, dtype=float)
    pad = np.zeros((*md.shape[:-1], 1))
    out = np.zeros((*md.shape[:-1], params.N + 1, 3))
    out[..., 2] = (np.concatenate([md, pad], axis=-1) - np.concatenate([pad, md], axis=-1)) / (
        node_weights(params.N) * params.ds)
    return out


def learn_bending_damping(arr: dict[str, np.ndarray], params: RodParams, segments: np.ndarray,
                          settings: dict[str, Any]) -> tuple[dict[str, np.ndarray], DampingFit | None]:
    """Decide and fit the bending damping on the ``obj_m`` samples of the prefilter arrays ``arr``
    (the segments ``segments`` kept), ``settings`` = config ``camera.learn.bending_damping``.

    Returns the arrays the constitutive laws are then trained on (``arr`` itself unless the
    damping is kept; else a copy whose ``damping_torque`` books c dkappa/dt as a known force,
    ``features.hz_targets``) and the fit (None for ``mode: none``)."""
    mode = settings["mode"]
    if mode not in MODES:
        raise ValueError(f"camera.learn.bending_damping.mode: {mode!r}; expected one of {MODES}")
    if mode == "none":
        return arr, None
    X, m = training_data(arr, params, "obj_m", None, segments)
    kdot = curvature_rates(arr["dtheta_dt"], params.ds)
    seg = np.broadcast_to(np.flatnonzero(segments), (kdot.shape[0], int(segments.sum())))
    fit = fit_bending_damping(X[:, 0], kdot[:, segments].reshape(-1), m, seg.reshape(-1),
                              int(settings["degree"]), int(settings["blocks"]))
    if not fit.kept:
        return arr, fit
    return {**arr, DAMPING_TORQUE: damping_torques(kdot, fit.coefficient, params)}, fit


def golden_log_search(objective: Callable[[float], float], lo: float, hi: float, evaluations: int
                      ) -> tuple[float, float, dict[float, float]]:
    """Minimise ``objective`` over [lo, hi] (> 0) on a log scale by golden section with
    ``evaluations`` calls (>= 2); returns (argmin, min, every value evaluated)."""
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = math.log(lo), math.log(hi)
    seen: dict[float, float] = {}

    def f(u: float) -> float:
        x = math.exp(u)
        if x not in seen:
            seen[x] = float(objective(x))
        return seen[x]

    x1, x2 = b - g * (b - a), a + g * (b - a)
    f1, f2 = f(x1), f(x2)
    for _ in range(max(evaluations - 2, 0)):
        if f1 <= f2:
            b, x2, f2 = x2, x1, f1
            x1 = b - g * (b - a)
            f1 = f(x1)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + g * (b - a)
            f2 = f(x2)
    best = min(seen, key=seen.__getitem__)
    return best, seen[best], seen


def refine_by_rollout(fit: DampingFit, record_rmse: Callable[[float], float], settings: dict[str, Any]
                      ) -> DampingFit:
    """The kept damping's c refined on the training record (module doc): ``record_rmse(c)`` is the
    RMSE of theta of the learned rod with damping c rolled out over the record (inf where it
    diverges); ``settings`` = config ``camera.learn.bending_damping``. Unchanged where the
    damping is not kept or ``refine_evaluations`` is 0."""
    n_eval, factor = int(settings["refine_evaluations"]), float(settings["refine_factor"])
    if not fit.kept or n_eval == 0:
        return fit
    c, err, _ = golden_log_search(record_rmse, fit.c_fit / factor, fit.c_fit * factor, n_eval)
    return DampingFit(**{**fit.to_dict(), "coefficient": c, "c_refined": c, "refine_rmse_theta": err,
                         "fit_rmse_theta": float(record_rmse(fit.c_fit))})


def record_rmse_theta(components: dict[str, Any], features: str, params: RodParams, center: float | None,
                      settings: SimSettings, arr: dict[str, np.ndarray], inputs: Inputs | None = None,
                      ports: Ports | None = None) -> Callable[[float], float]:
    """``refine_by_rollout``'s objective: c -> RMSE of theta over the free nodes 1..N between the
    learned rod of ``components`` with bending damping c, rolled out (``settings``' dt, under the
    record's ``inputs``) from the first frame of the training arrays ``arr`` over the record and
    linearly interpolated to its times, and the record's angles; inf where it diverges."""
    t, theta = arr["t"], arr["theta"]
    st = record_settings(settings, t)
    q0 = np.stack([arr["x"][0], arr["y"][0], theta[0]], axis=-1)
    p0 = np.stack([arr[c][0] for c in ("p_x", "p_y", "p_theta")], axis=-1)

    def rmse(c: float) -> float:
        model = LearnedRod(components, features, params, center, c)
        try:
            tr = rollout(model, math.nan, st, "damping refinement", inputs=inputs, ports=ports,
                         initial=(q0, p0, float(t[0])), book_energy=False)
        except SimulationDiverged:
            return math.inf
        return float(np.sqrt(np.mean((free_angles_at(tr, t) - theta[:, 1:]) ** 2)))

    return rmse
