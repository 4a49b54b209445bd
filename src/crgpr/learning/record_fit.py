"""The learned rod fitted to its own training record by output error: the record's initial state
and a smooth correction of the bending law, jointly (errors in variables).

From positions (camera data) the bending law m(kappa) is learned by regressing the moment targets
of eq. (13) on the curvatures of the same smoothing fit (equation error). Both sides come from
one fit of noisy marker positions, and that fit's bias (near the clamp and at the largest
curvatures, docs/learned-laws.md) is not noise that more samples average out: the regression
inherits it, and a law off by a few per cent shifts every rollout's phase. An output-error fit
does not inherit it: the learned rod (eq. (17)) is integrated over the whole record and its
angles are compared with the record's, so the law is judged by the motion it produces.

Parameters (``RecordFit``):

* the bending law's warp: m(kappa) <- m(kappa) w(kappa), w = 1 + sum_{k < K} a_k u^(2k),
  u = (kappa - c) / kappa_s clipped to [-1, 1]; c the law's centre (the point it is mirrored
  about, else the nominal kappa0), kappa_s the largest |kappa - c| of its training samples. Even
  in u, so the law keeps its symmetry about c; multiplicative, so m(c) = 0 is kept; constant
  beyond the covered range, where the record says nothing of it (``BendingWarp``); kept only
  where w > 0 on the covered range (``warp.admissible``: the law keeps its sign where few
  samples constrain the warp): the warp refitted on the whole record, else the warp as chosen
  on the record's first part, else none (the law as learned then compared with the nominal rod
  again);
* where the bending law learned from positions takes s as an input
  (``learning.law_choice.bending_arclength``), a profile along the rod: a stiffness factor
  v(s) = exp(sum_{j = 1..S} b_j P_j(2 s/L - 1)) (``warp.profile_factor``), positive for any b,
  and a rest-curvature shift d(s) = sum_{j < R} c_j P_j(2 s/L - 1) (``warp.rest_shift``):
  m(kappa, s) <- m(kappa - d(s), s) w(kappa - d(s)) v(s); the positions' curvature
  reconstruction smooths the law along s, and the motion shows what it misses. To a law without
  s mirrored about a rest curvature the data estimated, the shift's variation along s alone
  (c_0 = 0: one c cannot hold a rest curvature that varies along the rod);
* the record's initial state, from positions (camera data): the derived angles theta_0(s) and
  rates omega_0(s) at its first kept frame, each corrected by sum_{j = 1..J} b_j (s / L)^j (zero
  at the clamp); positions and velocities are rebuilt from them at the nominal strains nu^0 from
  the clamped base (``start_state``). The derived positions' strain noise would otherwise start
  stretch and shear oscillations that the record does not have, and the derived rates are least
  certain at the record's start, where its time derivatives are end-affected. From the full
  state the record's first state is exact and is used as it is (J = 0);
* where a bending damping c is kept (``learning.damping``), its size: c exp(d). Its regression
  and rollout refinement are made with the bending law as it was learned from targets that
  still held the rest of the damping, and a law left nominal biases the refined c (a stiffening
  rod's extra restoring moment read as less damping); fitted jointly, both are judged by the
  motion. Rows of a batch with different c run as separate batches (one c per rollout).

* where the learned bending law has a reach (``learning.extrapolation``: the law beyond it is
  continued by its tangent), the tail factor g of that tangent's slope (``tail_factor``), free
  with every warp of the learned law: the rollouts of the fit continue the law as the model's
  will, and the record's largest curvatures (at the clamp, where the positions' reconstruction
  attenuates them, so they lie beyond the law's covered range) show how steep the law goes on.

A kept warp's truncation estimate (``record_stats.truncation``): the warp of the next candidate number of
terms offered less the kept one's, both fitted on the first part (``warp.warp_sd`` adds it to the
law's band: the coefficients' covariance holds their scatter, not the error of too few terms).

Fit: Levenberg-Marquardt on the residuals theta(t, s_i) - theta_rec(t, s_i) over the free nodes
at the record's frames, the Jacobian by forward differences, each evaluation one batched rollout
(``learned.rollout``). Decision from the data (``decide``): the start alone and the start with
the warp of each candidate number of terms K (``warp_terms``; each from the start-alone fit,
the first two side by side in the same batched rollouts) are fitted on the first 1 - f of the
record and compared on its last f, cut into ``blocks`` contiguous blocks
(``laws.consistent_gain``). Forward selection (``select_terms``): a candidate
replaces the current choice (at first the start alone) only where it forecasts the held-out
blocks consistently better than that choice, and a candidate beyond the second is offered only
where the one before it was chosen; a chosen warp is then refitted on the whole
record. Where none is chosen the law stays as the regression learned it. The damping's size is
free in every fit (the damping itself was decided by its own held-out blocks); the fit that is
kept sets it.

Against the nominal rod (``_against_nominal``): the rod with every law nominal, its start fitted
on the same first part (from the learned rod's), is rolled out over the same record. The learned
rod as chosen above (its start and warp as fitted on the first part) is refused, and ``crgpr
learn`` keeps every law nominal (``nominal_fallback``), where the nominal rod forecasts the
held-out blocks consistently better, or follows the whole record with a smaller RMSE of theta:
the learned laws were regressed on that whole record, so a learned rod that follows it worse
than the nominal rod does has laws the data do not pin down (a softening law attenuated by the
curvature's errors in variables, say). A learned rod that leaves the physical range on its own
record (its residuals then pi) is refused where the nominal rod stays within it.

A damped rod's bending law (``_nominal_bending``): where a damping is kept, the moment targets
hold only part of it as c dkappa/dt (``learning.damping``; docs/learned-laws.md), and a law
regressed on them carries the rest. There the rod with the bending law nominal is fitted as the
learned one is (start, damping, warp candidates) and taken where it forecasts the held-out
blocks consistently better or follows the whole record with a smaller RMSE of theta; the
nominal rod's comparison then runs against it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from crgpr.learning.learned import LearnedRod, free_angles_at, record_settings, rollout
from crgpr.learning.lm import levenberg_marquardt
from crgpr.learning.record_select import batch_rows, select_terms
from crgpr.learning.record_stats import coefficient_wald, decide, truncation, warp_covariance
from crgpr.learning.warp import admissible
from crgpr.physics.integrator import SimulationDiverged
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.ports import Ports
from crgpr.physics.signals import Inputs

MODES: tuple[str, ...] = ("auto", "none")
TAIL_LOG_BOUND = math.log(100.0)  # the tail factor g of the law's tangent is held to [1/100, 100] [-]


def tail_factor(log_g: np.ndarray | float) -> np.ndarray:
    """g = exp(log g) with log g clipped to +-``TAIL_LOG_BOUND``: the tangent continuation's slope
    factor (``extrapolation.Reach.slope_factor``) the record fit sizes; where the motion wants the
    tail flat, its log runs off towards -inf and g stops at 1/100."""
    return np.exp(np.clip(np.asarray(log_g, dtype=float), -TAIL_LOG_BOUND, TAIL_LOG_BOUND))

P95 = 0.95  # the rest shift's Wald test's level: that of every held-out choice's 1.96 standard errors


def _chi2_quantile(p: float, dof: int) -> float:
    """The chi-squared distribution's p-quantile (scipy.stats imported here: it costs every
    rule's job half a second at import)."""
    from scipy.stats import chi2

    return float(chi2.ppf(p, dof))


@dataclass(frozen=True)
class RecordFit:
    """What ``fit_record`` decided (the manifest's ``record_fit``): the warp's centre, scale and
    coefficients (all zero where it was not kept), the start's mode coefficients, the RMSE of
    theta over the record [rad] as learned (from the derived start), with the fitted start alone
    and after the fit, the held-out comparison (mean and se of the per-block log error ratio,
    start alone over start and warp), the fit's wall time [s] and the bending damping before
    and after it."""

    kept: bool
    center: float
    kappa_scale: float
    coefficients: list[float]
    start_coefficients: list[float]
    rmse_learned: float
    rmse_start_only: float
    rmse_fitted: float
    heldout_log_ratio: float
    heldout_log_ratio_se: float
    note: str
    seconds: float
    damping: float = 0.0  # the bending damping c after the fit [N m^2 s] (0: none kept)
    damping_before: float = 0.0  # c as it came in (the damping's regression and refinement) [N m^2 s]
    exact_start: bool = False  # the record's first state used as it is (full state), no start modes
    coefficient_cov: list[list[float]] | None = None  # a kept warp's coefficient covariance (warp_covariance)
    warp_terms: int = 0  # the kept warp's number of terms K (0: none kept)
    candidates: list[dict[str, Any]] = field(default_factory=list)  # each candidate K's held-out comparison
    nominal_fallback: bool = False  # the nominal rod forecasts or follows the record better: laws nominal
    nominal_log_ratio: float = math.nan  # mean per-block log(learned / nominal held-out error) [-]
    nominal_log_ratio_se: float = math.nan  # its standard error [-]
    rmse_nominal: float = math.nan  # the nominal rod's RMSE of theta over the record, start fitted [rad]
    rmse_compared: float = math.nan  # the same for the learned rod as compared with it [rad]
    bending_nominal: bool = False  # the nominal bending law, warped, follows the record better: taken
    bending_terms: int = 0  # the warp terms of that alternative as compared (0: not compared)
    bending_log_ratio: float = math.nan  # mean per-block log(learned law / nominal law held-out error) [-]
    bending_log_ratio_se: float = math.nan  # its standard error [-]
    rmse_bending_nominal: float = math.nan  # the alternative's RMSE of theta over the record [rad]
    rmse_bending_learned: float = math.nan  # the learned law's, as compared with it [rad]
    profile_coefficients: list[float] = field(default_factory=list)  # a kept profile's b_j (profile_factor)
    profile_terms: int = 0  # the profile candidate's number of stiffness terms S (0: not offered)
    rest_coefficients: list[float] = field(default_factory=list)  # a kept profile's c_j [1/m] (rest_shift)
    rest_terms: int = 0  # the profile candidate's number of rest-curvature terms R
    profile_log_ratio: float = math.nan  # mean per-block log(held-out error: pick / pick with v(s)) [-]
    profile_log_ratio_se: float = math.nan  # its standard error [-]
    rest_log_ratio: float = math.nan  # the same for the rest shift d(s), on top of the pick then [-]
    rest_log_ratio_se: float = math.nan  # its standard error [-]
    rest_wald: float = math.nan  # c^T cov^-1 c of the rest shift's free c_j fitted on the first part [-]
    rest_fitted: list[float] = field(default_factory=list)  # that fit's free c_j, kept or not [1/m]
    rest_fitted_sd: list[float] = field(default_factory=list)  # their sd (warp_covariance) [1/m]
    truncation_coefficients: list[float] = field(default_factory=list)  # a kept warp's truncation d_k
    truncation_terms: int = -1  # the candidate K' it compares with (0: no warp; -1: none kept)
    tail_log_factor: float = 0.0  # log of the tail factor g of the law's tangent (``tail_factor``; 0: g = 1)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def start_state(arr: dict[str, np.ndarray], params: RodParams, b: np.ndarray, modes: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """Initial states (B, N+1, 3) q and p (per length) from the first frame of the derived record
    ``arr`` with the corrections b (B, 2 J): theta_0 + sum_j b_j (s/L)^j, omega_0 + sum_j
    b_{J+j} (s/L)^j; x, y and the linear momenta rebuilt from the clamped base at the nominal
    strains (nu1^0, nu2^0) along the mid-segment angle (``features.segments``)."""
    P = params
    b = np.atleast_2d(np.asarray(b, dtype=float))
    s = np.linspace(0.0, 1.0, P.N + 1)
    phi = np.stack([s ** (j + 1) for j in range(modes)]) if modes else np.zeros((0, P.N + 1))
    th = arr["theta"][0][None] + b[:, :modes] @ phi
    om = arr["p_theta"][0][None] / P.rhoI + b[:, modes:2 * modes] @ phi
    om[:, 0] = 0.0
    tb, ob = 0.5 * (th[:, 1:] + th[:, :-1]), 0.5 * (om[:, 1:] + om[:, :-1])
    c, sn = np.cos(tb), np.sin(tb)
    ex, ey = P.nu1_0 * c - P.nu2_0 * sn, P.nu1_0 * sn + P.nu2_0 * c  # tangent of the rest strains
    z = np.zeros((b.shape[0], 1))

    def cum(v: np.ndarray) -> np.ndarray:
        return np.concatenate([z, np.cumsum(P.ds * v, axis=1)], axis=1)
    q = np.stack([arr["x"][0][0] + cum(ex), arr["y"][0][0] + cum(ey), th], axis=-1)
    p = np.stack([P.rhoA * cum(-ey * ob), P.rhoA * cum(ex * ob), P.rhoI * om], axis=-1)
    return q, p


def recorded_start(arr: dict[str, np.ndarray], n: int) -> tuple[np.ndarray, np.ndarray]:
    """The record's first state as it is (full state), q and p (n, N+1, 3) for n rods."""
    q = np.stack([arr["x"][0], arr["y"][0], arr["theta"][0]], axis=-1)
    p = np.stack([arr["p_x"][0], arr["p_y"][0], arr["p_theta"][0]], axis=-1)
    return np.repeat(q[None], n, axis=0), np.repeat(p[None], n, axis=0)


def record_residuals(model_for: Callable[[np.ndarray, float], LearnedRod], arr: dict[str, np.ndarray],
                     params: RodParams, settings: SimSettings, modes: int, n_frames: int,
                     damping: float = 0.0, exact_start: bool = False,
                     inputs: Inputs | None = None, ports: Ports | None = None
                     ) -> Callable[[np.ndarray], np.ndarray | None]:
    """A -> residuals (B, n_frames x N) of theta at the free nodes over the record's first
    ``n_frames`` frames, for parameter rows A (B, 2 J + D + K): start corrections (none with
    ``exact_start``: the recorded first state), the damping's log factor d (D = 1 where
    ``damping`` c > 0: the rod's c exp(d)), then warp coefficients (``model_for(W, c)``: the
    learned rod of warps W (B', K) and damping c); None where any rod leaves the physical range."""
    t, theta = arr["t"][:n_frames], arr["theta"][:n_frames, 1:]
    st = replace(record_settings(settings, arr["t"]), t_end=float(t[-1] - t[0]))
    nd = int(damping > 0)
    j0 = 0 if exact_start else 2 * modes

    def residuals(A: np.ndarray) -> np.ndarray | None:
        q0, p0 = (recorded_start(arr, A.shape[0]) if exact_start
                  else start_state(arr, params, A[:, :j0], modes))
        with np.errstate(over="ignore"):
            c = damping * np.exp(A[:, j0]) if nd else np.full(A.shape[0], damping)
        if not np.all(np.isfinite(c)):  # a trial step's damping beyond any rod: out of the physical range
            return None
        out = np.empty((A.shape[0], theta.size))
        for cv in np.unique(c):
            rows = np.flatnonzero(c == cv)
            try:
                tr = rollout(model_for(A[rows, j0 + nd:], float(cv)), math.nan, st, "record fit",
                             n_batch=rows.size, inputs=inputs, ports=ports,
                             initial=(q0[rows], p0[rows], float(t[0])), book_energy=False)
            except SimulationDiverged:
                return None
            out[rows] = (free_angles_at(tr, t) - theta[:, None]).transpose(1, 0, 2).reshape(rows.size, -1)
        return out
    return residuals


def _against_nominal(nominal_rod: LearnedRod, learned: np.ndarray, start: np.ndarray,
                     arr: dict[str, np.ndarray], params: RodParams, settings: SimSettings, J: int,
                     n_fit: int, n_t: int, exact_start: bool, inputs: Inputs | None, ports: Ports | None,
                     lm: tuple[int, float], blocks: int) -> dict[str, Any]:
    """The nominal rod on the same record: its start fitted on the first ``n_fit`` frames, from
    the learned rod's fitted corrections ``start`` (2 J,) (the recorded start with
    ``exact_start``), compared with the learned rod's residuals ``learned`` (n_t, nodes): held
    out (``decide``, the nominal rod as the richer side) and over the whole record (RMSE). A
    nominal rod that leaves the physical range is not taken."""
    def model_for(W: np.ndarray, c: float) -> LearnedRod:
        return nominal_rod
    part = record_residuals(model_for, arr, params, settings, J, n_fit, 0.0, exact_start, inputs, ports)
    full = record_residuals(model_for, arr, params, settings, J, n_t, 0.0, exact_start, inputs, ports)
    a = np.asarray(start, dtype=float)[:2 * J]
    if J:
        a = levenberg_marquardt(part, a, np.ones(2 * J, dtype=bool), *lm)[0]
    r = full(a[None])
    rmse_learned = float(np.sqrt(np.mean(learned**2)))
    if r is None:
        return {"nominal_fallback": False, "rmse_nominal": math.inf, "rmse_compared": rmse_learned}
    r = r.reshape(n_t, -1)
    ratio, se, better = decide(learned[n_fit:] ** 2, r[n_fit:] ** 2, blocks)
    rmse = float(np.sqrt(np.mean(r**2)))
    return {"nominal_fallback": better or rmse < rmse_learned, "nominal_log_ratio": ratio,
            "nominal_log_ratio_se": se, "rmse_nominal": rmse, "rmse_compared": rmse_learned}


def _nominal_bending(rod_for: Callable[[np.ndarray, float], LearnedRod], learned: np.ndarray,
                     start: np.ndarray, arr: dict[str, np.ndarray], params: RodParams, settings: SimSettings,
                     J: int, n_fit: int, n_t: int, damping: float, exact_start: bool, inputs: Inputs | None,
                     ports: Ports | None, terms: list[int], lm: tuple[int, float], blocks: int
                     ) -> dict[str, Any]:
    """The rod with the bending law nominal (``rod_for(W, c)``, its warp W and damping c) fitted as
    the learned one is: each warp candidate of ``terms`` with the start and the damping's size,
    from the learned rod's start-alone fit ``start``, on the first ``n_fit`` frames, the candidates
    chosen among by forward selection (fewest terms first); then compared with the learned rod's
    residuals ``learned`` (n_t, nodes): taken (``bending_nominal``) where it forecasts the held-out
    blocks consistently better or follows the whole record with a smaller RMSE of theta (the
    learned rod's record fit has the same freedom). A fit that leaves the physical range is not
    taken. Returns the manifest's entries (``record``) and the taken fit."""
    full = record_residuals(rod_for, arr, params, settings, J, n_t, damping, exact_start, inputs, ports)
    part = record_residuals(rod_for, arr, params, settings, J, n_fit, damping, exact_start, inputs, ports)
    n_free, a0 = 2 * J + int(damping > 0), np.asarray(start, dtype=float)
    sel = select_terms(part, full, a0, terms, lambda k: np.arange(a0.size) < n_free + k, lm, n_fit, n_t,
                       blocks)
    rmse_learned = float(np.sqrt(np.mean(learned**2)))
    if sel is None:
        return {"record": {"bending_nominal": False, "rmse_bending_nominal": math.inf,
                           "rmse_bending_learned": rmse_learned}}
    fits, res, i, _ = sel
    terms = terms[:len(fits)]  # the candidates offered
    ratio, se, better = decide(learned[n_fit:] ** 2, res[i, n_fit:] ** 2, blocks)
    rmse = float(np.sqrt(np.mean(res[i] ** 2)))
    return {"record": {"bending_nominal": better or rmse < rmse_learned, "bending_terms": terms[i],
                       "bending_log_ratio": ratio, "bending_log_ratio_se": se, "rmse_bending_nominal": rmse,
                       "rmse_bending_learned": rmse_learned},
            "terms": terms[i], "a": fits[i], "r": res[i], "full": full,
            "truncation": truncation(fits, terms, i, n_free)}


def fit_record(law_rod: Callable[[np.ndarray, float], LearnedRod], arr: dict[str, np.ndarray],
               params: RodParams, settings: SimSettings, center: float, kappa_scale: float,
               cfg: dict[str, Any], inputs: Inputs | None = None, ports: Ports | None = None,
               damping: float = 0.0, exact_start: bool = False,
               nominal_rod: LearnedRod | None = None,
               nominal_bending: tuple[Callable[[np.ndarray, float], LearnedRod], float, float] | None = None,
               profile_terms: tuple[int, int] = (0, 0), tail: bool = False, rest_level: bool = True
               ) -> RecordFit:
    """The module's fit and decision on the training record ``arr`` (prefilter or
    ``positions_to_state`` arrays, time-major; its first ``max_record_s`` seconds);
    ``law_rod(W, c)`` is the learned rod with warp coefficients W (B, K + S + R) (``BendingWarp``
    of its bending law: the K = max(``warp_terms``) coefficients a_k, then the (S, R) =
    ``profile_terms`` coefficients b_j and c_j of its profile along s) and bending damping c;
    ``damping``: the kept damping's c (0: none, not fitted);
    ``exact_start``: the record holds the full state, its first state is used as it is;
    ``cfg``: config ``camera.learn.record_fit``. A record whose held-out part has fewer than two
    frames per block keeps the law as learned.

    The warp's number of terms is chosen from the candidates ``warp_terms`` (ascending) by
    forward selection on the held-out blocks (``select_terms``): each candidate is fitted on the
    first part from the start-alone fit, and replaces the current choice (at first: the start
    alone, no warp) only where it forecasts the held-out blocks consistently better than that
    choice (``decide``); a candidate beyond the second is offered only where the one before it was
    chosen. Every comparison made is recorded (``candidates``).

    ``nominal_rod`` (the rod with every law nominal and no learned damping), its start fitted on
    the same first part: its held-out blocks are compared with the chosen learned rod's;
    where the nominal rod forecasts them consistently better, or reproduces the whole record with
    a smaller RMSE, ``nominal_fallback`` is set (``crgpr learn`` then keeps every law nominal),
    and also where the learned rod leaves the physical range on the record and the nominal one
    does not.

    ``nominal_bending`` = (the rod with the bending law nominal, ``rod(W, c)`` like ``law_rod``; its
    warp's centre; its kappa scale): fitted as the learned rod is and compared with it
    (``_nominal_bending``); where it follows the record better, ``bending_nominal`` is set, the
    warp is the nominal law's (``crgpr learn`` then refuses the learned bending law), and the
    comparison with ``nominal_rod`` runs against it.

    ``profile_terms`` (S, R), not both 0 (a bending law that takes s as an input, or one without
    s mirrored about an estimated rest curvature: S = 0): after the choice of K, a profile along
    the rod by forward selection on top of the pick: first a stiffness factor v(s) of S Legendre
    terms (``warp.profile_factor``), then a rest-curvature shift d(s) of R (``warp.rest_shift``),
    each fitted on the first part from the pick's fit and taken where it forecasts the held-out
    blocks consistently better than the pick (``profile_log_ratio``, ``rest_log_ratio``): a law
    learned along s from positions is smoothed along s by their curvature reconstruction, and
    the motion shows the profile the regression misses. The rest shift is also taken where the
    fit resolves it (``coefficient_wald`` above the 95 % chi-square quantile of R degrees,
    ``rest_wald``) and the held-out blocks do not forecast worse (mean log ratio > 0), the rule
    of the rest curvature itself (``laws.RestState.mirror_about``): it shifts the moment by
    EI d(s) only, small against the held-out errors of every block, so their test has little
    power for it. ``rest_level`` False: the shift's level c_0 stays 0, d(s) = sum_{1 <= j < R}
    c_j P_j(2 s/L - 1), whose mean along the rod is 0 (a law mirrored about a rest curvature the
    regression estimated keeps that estimate as its mean, and the record fit adds its variation
    along s)."""
    t_start = time.perf_counter()
    J = 0 if exact_start else int(cfg["start_modes"])
    terms = sorted({int(k) for k in cfg["warp_terms"]})
    K, blocks = terms[-1], int(cfg["blocks"])
    nd = int(damping > 0)
    within = arr["t"] <= arr["t"][0] + float(cfg["max_record_s"]) + 1e-12
    arr = {k: v[within] if isinstance(v, np.ndarray) and v.shape[:1] == within.shape else v
           for k, v in arr.items()}
    n_t, lm = arr["t"].size, (int(cfg["iterations"]), float(cfg["tolerance"]))
    n_fit = int(round((1.0 - float(cfg["holdout_fraction"])) * n_t))
    if n_fit < 3 or n_t - n_fit < 2 * blocks:
        return RecordFit(False, float(center), float(kappa_scale), [], [0.0] * (2 * J), math.nan,
                         math.nan, math.nan, math.nan, math.nan,
                         f"record too short to decide: {n_t} frames", time.perf_counter() - t_start,
                         float(damping), float(damping), bool(exact_start))
    full = record_residuals(law_rod, arr, params, settings, J, n_t, damping, exact_start, inputs, ports)
    part = record_residuals(law_rod, arr, params, settings, J, n_fit, damping, exact_start, inputs, ports)
    S, R = (int(v) for v in profile_terms)
    T = int(bool(tail))
    n_a = 2 * J + nd + K + S + R + T
    zero = np.zeros(n_a)
    at_tail = np.arange(n_a) >= n_a - T  # the tail factor's log, free with every warp
    start_free = np.arange(n_a) < 2 * J + nd
    if start_free.any():
        r0 = full(zero[None])
        learned = math.inf if r0 is None else float(np.sqrt(np.mean(r0**2)))
        a_start, _ = levenberg_marquardt(part, zero, start_free, *lm)
    else:  # nothing but the warp to fit: the start-only rod is the learned one (its RMSE below)
        learned, a_start = math.nan, zero
    sel = select_terms(part, full, a_start, terms, lambda k: (np.arange(n_a) < 2 * J + nd + k) | at_tail,
                       lm, n_fit, n_t, blocks, base=a_start)
    if sel is not None and not start_free.any():
        learned = float(np.sqrt(np.mean(sel[1][0] ** 2)))
    candidates: list[dict[str, Any]] = []  # each candidate's held-out comparison
    bending: dict[str, Any] = {}  # the comparison with the nominal bending law (nominal_bending)

    profile: dict[str, Any] = {"profile_terms": S, "rest_terms": R}  # the profile's comparison

    w0, p0 = 2 * J + nd, 2 * J + nd + K  # the first warp and the first profile parameter
    blocks_along = {"profile": slice(p0, p0 + S), "rest": slice(p0 + S, p0 + S + R)}

    def result(k: int, a: np.ndarray, start_only: float, fitted: float, ratio: float, se: float, note: str,
               frame: tuple[float, float] = (float(center), float(kappa_scale)),
               along: np.ndarray | None = None) -> RecordFit:
        on_s = np.zeros(n_a, dtype=bool) if along is None else along
        prof = {**profile, **{f"{name}_coefficients": [float(v) for v in a[b]] if on_s[b].any() else []
                              for name, b in blocks_along.items()}}
        return replace(RecordFit(k > 0 or bool(on_s.any()), frame[0], frame[1],
                                 [float(v) for v in a[w0:w0 + k]],
                                 [float(v) for v in a[:2 * J]], learned, start_only, fitted, ratio, se, note,
                                 time.perf_counter() - t_start,
                                 float(damping * math.exp(a[2 * J]) if nd else damping), float(damping),
                                 bool(exact_start), None, k, candidates), **bending, **prof)
    if sel is None:  # the learned rod leaves the physical range on its own record (start alone)
        # its residuals are pi (no better than any angle; as ``batch_rows``): a nominal rod that
        # stays in range follows the record better, every law nominal
        torn = np.full((n_t, arr["theta"].shape[1] - 1), math.pi)
        floor = {} if nominal_rod is None else _against_nominal(
            nominal_rod, torn, a_start, arr, params, settings, J, n_fit, n_t, exact_start, inputs, ports,
            lm, blocks)
        why = "; the nominal rod does not: every law nominal" if floor.get("nominal_fallback") else ""
        return replace(result(0, zero, math.inf, learned, math.nan, math.nan,
                              "the learned rod left the physical range on its own record" + why), **floor)
    fits, res, chosen, steps = sel  # rows of res: 0 the start alone, then each candidate offered
    offered = terms[:len(fits)]
    start_only = float(np.sqrt(np.mean(res[0] ** 2)))
    held = res[:, n_fit:] ** 2
    for i, (k, (against, gain, gain_se, _)) in enumerate(zip(offered, steps, strict=True), start=1):
        ratio, se, _ = decide(held[0], held[i], blocks)
        candidates.append({"terms": k, "heldout_log_ratio": ratio, "heldout_log_ratio_se": se,
                           "against_terms": offered[against - 1] if against else 0,
                           "gain_log_ratio": gain, "gain_log_ratio_se": gain_se, "chosen": False})
    # the pick so far: the learned law, warped where a candidate was chosen
    k = offered[chosen - 1] if chosen else 0
    a_pick, r_pick, full_pick = (fits[chosen - 1] if chosen else a_start), res[chosen], full
    trunc = truncation(fits, offered, chosen - 1, w0) if chosen else {}
    frame = (float(center), float(kappa_scale))
    pick = candidates[chosen - 1] if chosen else candidates[0]
    ratio, se = pick["heldout_log_ratio"], pick["heldout_log_ratio_se"]
    along = np.zeros(n_a, dtype=bool)  # the profile's parameters taken: stiffness, then rest shift
    resolved = False  # the rest shift taken as resolved by the fit, its held-out gain not significant
    for name, b in blocks_along.items():  # forward selection on top of the pick
        if b.stop > b.start:
            free = (np.arange(n_a) < w0 + k) | along | (at_tail if k else False)
            on_b = np.zeros(n_a, dtype=bool)
            on_b[b] = True
            on_b[b.start] &= name != "rest" or rest_level  # the level: the law's own estimate
            if not on_b.any():
                continue
            free |= on_b
            fin: dict[str, np.ndarray] = {}
            a_s = levenberg_marquardt(part, a_pick, free, *lm, fin)[0]
            r_s = batch_rows(full, a_s[None])
            if r_s is None:
                continue
            r_s = r_s.reshape(n_t, -1)
            p_ratio, p_se, better = decide(r_pick[n_fit:] ** 2, r_s[n_fit:] ** 2, blocks)
            profile.update({f"{name}_log_ratio": p_ratio, f"{name}_log_ratio_se": p_se})
            if name == "rest" and "J" in fin:  # resolved by the fit, and not forecasting worse
                wald, wald_sd = coefficient_wald(fin["r"], fin["J"], n_fit, free, np.flatnonzero(on_b), a_s)
                profile.update(rest_fitted=[float(v) for v in a_s[on_b]], rest_fitted_sd=wald_sd,
                               rest_wald=wald)
                resolved = not better and wald > _chi2_quantile(P95, int(on_b.sum())) and p_ratio > 0.0
                better = better or resolved
            if better:
                along, a_pick, r_pick = along | on_b, a_s, r_s
    if nominal_bending is not None:
        alt = _nominal_bending(nominal_bending[0], r_pick, a_start, arr, params, settings, J, n_fit, n_t,
                               damping, exact_start, inputs, ports, terms, lm, blocks)
        bending.update(alt["record"])
        if bending["bending_nominal"]:
            k, a_pick, r_pick, full_pick = alt["terms"], alt["a"], alt["r"], alt["full"]
            trunc = alt["truncation"]
            along[:] = False
            frame = (float(nominal_bending[1]), float(nominal_bending[2]))
            ratio, se = bending["bending_log_ratio"], bending["bending_log_ratio_se"]
    if nominal_rod is not None:
        nominal = _against_nominal(nominal_rod, r_pick, a_start, arr, params, settings, J, n_fit, n_t,
                                   exact_start, inputs, ports, lm, blocks)
        if nominal["nominal_fallback"]:
            bending["bending_nominal"] = False
            return replace(result(0, a_start, start_only, start_only, math.nan, math.nan,
                                  "the nominal rod forecasts the held-out blocks consistently better or "
                                  "reproduces the record better: every law nominal"), **nominal)
    else:
        nominal = {}
    if not k and not along.any():
        return replace(result(0, a_start, start_only, start_only, ratio, se,
                              "no warp forecasts the held-out blocks consistently better"), **nominal)
    if chosen and not bending.get("bending_nominal"):
        candidates[chosen - 1]["chosen"] = True
    last: dict[str, np.ndarray] = {}
    on_law = k and not bending.get("bending_nominal")  # the learned law's warp: its tail too
    free = (np.arange(n_a) < w0 + k) | along | (at_tail if on_law else False)
    a, rms = levenberg_marquardt(full_pick, a_pick, free, *lm, last)
    refit = ""
    if not admissible(a[w0:w0 + k])[0]:  # reversed where few samples constrain it
        if not admissible(a_pick[w0:w0 + k])[0]:  # so is the pick: the law as learned, checked again
            bending["bending_nominal"] = False
            floor = {} if nominal_rod is None else _against_nominal(
                nominal_rod, res[0], a_start, arr, params, settings, J, n_fit, n_t, exact_start, inputs,
                ports, lm, blocks)
            why = ("; the nominal rod forecasts or reproduces the record better than the law as learned: "
                   "every law nominal" if floor.get("nominal_fallback") else "")
            return replace(result(0, a_start, start_only, start_only, ratio, se, "the fitted warp reverses "
                                  f"the law within the covered range (w <= 0): not kept{why}"), **floor)
        last.clear()  # the pick as the held-out blocks chose it, fitted on the record's first part
        a, rms = levenberg_marquardt(full_pick, a_pick, free, 0, 0.0, last)
        refit = ("; refitted on the whole record it reverses the law (w <= 0): kept as fitted on the "
                 "record's first part")
    which = "the nominal bending law" if bending.get("bending_nominal") else "the learned law"
    parts = [f"{int(along[b].sum())} {name} terms" for name, b in blocks_along.items() if along[b].any()]
    on_s = f" and a profile along s: {', '.join(parts)}" if parts else ""
    tail_log = float(np.clip(a[-1], -TAIL_LOG_BOUND, TAIL_LOG_BOUND)) if free[at_tail].any() else 0.0
    wald = resolved and along[blocks_along["rest"]].any()
    by_wald = ("; its rest shift: resolved by the fit (rest_wald above the chi-square 95 % quantile), "
               "forecasting the held-out blocks no worse" if wald else "")
    kept = replace(result(k, a, start_only, rms, ratio, se, f"kept ({k} terms{on_s}, on {which}): forecasts "
                          f"the held-out blocks consistently better{refit}{by_wald}", frame, along),
                   **nominal,
                   **(trunc if k else {}), tail_log_factor=tail_log)
    n_w, n_tail = k + int(along.sum()), int(free[at_tail].sum())
    cov = (warp_covariance(last["r"], last["J"], n_t, n_w + n_tail)[:n_w, :n_w] if "J" in last
           else np.full((n_w, n_w), np.nan))
    return replace(kept, coefficient_cov=[[float(v) for v in row] for row in cov])
