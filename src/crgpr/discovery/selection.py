"""Missing-physics workflow: locate, name, add and verify a missing effect (beyond the paper).

Given screened camera markers (``crgpr.measured.records``), the rod kinematics they imply on
the model's grid (``crgpr.measured.kinematics``) and the nominal model of config.yaml:

1. Locate. The nominal model is simulated from the measured initial state (GP-smoothed,
   projected onto an unstretched, unsheared rod, corrected by a short shooting fit; the
   record may start mid-motion) and compared with the data at the marker positions: RMSE of
   theta per marker and per time window, the state group with the largest normalised error,
   the sign of the net work of the missing terms from the port-Hamiltonian energy balance
   dH/dt = -H_z^T R H_z + P_missing (paper eq. (7)-(9)), and where along s the cut-moment
   residual sits.
2. Floor. The gap the nominal model shows with nothing missing: camera noise and initial-
   state uncertainty (parametric bootstrap: the nominal trajectory re-measured at the same
   markers, with the same missing samples and the GP's noise level, and fitted exactly as the
   data are) and the model's own
   discretisation error (the model fitted to the data on its grid and time step and on a
   grid twice as fine with half the step, each with its own initial state; the difference
   of the two fitted trajectories, Richardson-scaled by 4/3 for a second-order scheme) and a
   model-form difference another rig or simulator can have (``floor.model_form_error``: the
   fit with a clamp of finite length against the point clamp), added in quadrature. A named
   model is judged against its own floor: the bootstrap around its own fitted trajectory and
   its own discretisation error (``floor_of``).
3. Name. The cut-moment residual of the data against the current model
   (``crgpr.discovery.residual``) is regressed on every candidate's signature; candidates enter
   by forward stepwise selection with the Bayesian information criterion of a heteroscedastic
   Gaussian model (one variance per segment and one for the clamp constraint), the sample
   size deflated by the integrated autocorrelation time of the residuals in time and along s;
   a candidate must lower BIC by ``bic_min_improvement`` (10: "very strong evidence", Kass and
   Raftery 1995) or rank high by its linearised trajectory evidence (in the first step every
   candidate the residual shows is confirmed, besides the ``max_confirm`` best by that
   evidence), and be confirmed by the joint trajectory fit of all named effects and the initial
   state (its BIC; its own effect size in that fit, the RMSE between the model with and without
   it, at least ``min_effect_fraction`` of the gap; and the same sign of its coefficient in the
   joint residual regression and in the trajectory fit). After each entry the other named
   effects are tested again in the joint model (backward elimination with the same BIC and size
   tests): an effect that entered as a proxy leaves. At the end each named effect is tried
   replaced by the candidates of its own place in the structure (``swap``): an effect that
   entered in place of a correlated one while the model was incomplete is exchanged.
   A model within ``min_gap_rad`` of its floor is "hidden" (``entry_threshold``): its fitted
   initial state may mimic an effect on a short record, so the search goes on with the
   candidates the initial-state-free cut-moment residual shows, each of which must be large
   enough to have put the gap over the "none" threshold by itself. A model of two or more
   effects then passes a leave-one-effect-out test on held-out time blocks
   (``crgpr.discovery.holdout``): an effect the others make redundant out of sample leaves.
   Last, the smallest model that reaches its own floor (``crgpr.discovery.prune``): an effect
   leaves when the model without it still closes the gap by the verdict's rule and fits within
   its own floor, and the search would not add it back.
4. Verdict. ``effect_found`` if effects were named that close at least ``min_explained`` of
   the gap (of its excess over the floor when the nominal gap was hidden) AND leave no excess
   over the floor above ``max(min_gap_rad, max_remaining * excess)``; else ``none`` if the
   nominal gap's excess over the floor is below ``min_gap_rad``; else ``described`` if a learned
   bending-stiffness profile EI(s) f(s) (``crgpr.discovery.describe``) closes the gap by the
   same rule, with its band away from the nominal law somewhere (``none`` if that change is
   confined to ``clamp_form_m`` next to the clamp: the clamp's form); otherwise ``unexplained``
   (no name is forced: a global effect that absorbs part of a disturbance it does not
   describe is reported as a partial attempt, with where the disturbance sits).

The steps' mechanics live in ``locate`` (1), ``floor`` (2), ``regression``, ``trajectory``,
``stepwise``, ``holdout`` and ``prune`` (3); this module runs them on one record (``discover``)
and assembles the verdict.
"""

from __future__ import annotations

import logging
import math
import time
from functools import partial
from typing import Any

import numpy as np

from crgpr.discovery.describe import describe
from crgpr.discovery.effects import EFFECT_NAMES, EFFECTS
from crgpr.discovery.floor import discretisation_error, model_form_error, noise_floor
from crgpr.discovery.holdout import holdout_check
from crgpr.discovery.locate import locate
from crgpr.discovery.prune import closes_gap, residual_gain, smallest_model
from crgpr.discovery.regression import Fit, Regression
from crgpr.discovery.residual import residual
from crgpr.discovery.settings import DiscoverySettings
from crgpr.discovery.stepwise import alternatives, eliminate, entry_threshold, swap, trajectory_delta_bic
from crgpr.discovery.synthetic import aligned_settings
from crgpr.discovery.trajectory import (
    TrajectoryFit,
    TrajectoryFitter,
    augmented_params,
    theta_rmse,
    tip_rmse_over_L,
)
from crgpr.measured.kinematics import smooth_kinematics
from crgpr.measured.records import Measured
from crgpr.physics.params import RodParams
from crgpr.physics.simulate import simulate

log = logging.getLogger(__name__)


def check_extent(meas: Measured, params: RodParams) -> None:
    """The markers must lie on a rod of the configured length (raises ValueError)."""
    if meas.s[-1] < 0.25 * params.L0:
        raise ValueError(f"{meas.source}: the outermost marker is at s = {meas.s[-1]:.3g} m; markers must "
                         f"cover at least a quarter of rod.L0 = {params.L0:g} m")


def discover(meas: Measured, params: RodParams, dt_max: float, st: DiscoverySettings) -> dict[str, Any]:
    """Run the workflow on screened measured data; returns the result dict (and arrays).

    ``params`` is the nominal model (its own grid), ``dt_max`` its time step [s]."""
    t_start = time.perf_counter()
    check_extent(meas, params)
    kin = smooth_kinematics(meas, params, seed=st.seed, max_points=st.gp_max_points)
    t_smooth = time.perf_counter() - t_start
    period = float(np.median(np.diff(kin.t)))
    n = len(kin.t)
    fitter = TrajectoryFitter(params, kin, dt_max, n_modes=st.init_modes, window_s=st.init_window_s)
    M = fitter.M
    nominal = fitter.fit([], np.zeros(0), np.zeros(0), st.refine_max_nfev)
    q_nom = nominal.q
    theta_b = float(nominal.q0[0, 2])
    tr = simulate(math.degrees(theta_b), params, aligned_settings(params, dt_max, period, n),
                  q0=nominal.q0, v0=nominal.v0)
    v_nom = tr.p[:n] / np.array([params.rhoA, params.rhoA, params.rhoI])
    gap_before = theta_rmse(q_nom, kin.q, M)
    s_last = float(kin.s_markers[-1])
    tip_before = tip_rmse_over_L(q_nom, kin.q, s_last, params)
    f_noise = noise_floor(q_nom, meas, kin, params, dt_max, st)
    f_disc = discretisation_error(fitter, dt_max, c0=nominal.init)
    f_form = model_form_error(fitter, dt_max, st.floor_clamp_m, st.floor_clamp_factor, c0=nominal.init)
    floor = math.sqrt(f_noise**2 + f_disc**2 + f_form**2)
    floors: dict[tuple[str, ...], float] = {(): floor}  # by names and coefficients

    floor_parts: dict[tuple[str, ...], dict[str, float]] = {}

    def model_key(fit: TrajectoryFit) -> tuple[str, ...]:
        return tuple(fit.names) + tuple(f"{c:.4g}" for c in fit.coef)

    def floor_of(fit: TrajectoryFit) -> float:
        """Floor of a named model: the same model-form part, its own noise and discretisation
        parts. The noise part is the bootstrap around the model's own fitted trajectory: how well
        the camera and the smoothing resolve a trajectory depends on it (a rod 30 % softer bends
        in higher modes: 0.061 rad around its own trajectory, 0.045 around the nominal one, on
        6 markers with 2 mm noise), and the nominal one's would hold a right model to a floor
        its data cannot reach."""
        key = model_key(fit)
        if key not in floors:
            noise = noise_floor(fit.q, meas, kin, augmented_params(params, fit.names, fit.coef), dt_max, st)
            disc = discretisation_error(fitter, dt_max, tuple(fit.names), fit.coef, fit.init)
            floors[key] = math.sqrt(noise**2 + disc**2 + f_form**2)
            floor_parts[key] = {"noise": noise, "discretisation": disc, "model_form": f_form}
        return floors[key]
    excess = math.sqrt(max(gap_before**2 - floor**2, 0.0))
    hidden_nominal = excess <= st.min_gap_rad
    trim = max(1, int(round(st.edge_trim_s / period)))
    rows = slice(trim, n - trim)
    theta_b0 = float(kin.q[0, 0, 2])
    res0 = residual(kin.q, kin.v, kin.a, params, theta_b0, kin.base_segment_angle)
    where = locate(kin, q_nom, v_nom, params, st, theta_b, res0, rows)
    # name: forward stepwise on the port-Hamiltonian residual; at each step the residual is
    # taken against the current (augmented) model, the remaining candidates are ranked and
    # the best ones are confirmed in turn by the joint trajectory fit (BIC of theta, effect
    # size >= min_effect_fraction of the gap, signs), then backward elimination
    cur = nominal
    accepted: list[TrajectoryFit] = []
    steps: list[dict[str, Any]] = []
    single: dict[str, Fit] = {}
    dropped: set[str] = set()  # removed by backward elimination: not offered again
    reg0 = Regression(res0, rows)
    while True:
        p_cur = augmented_params(params, cur.names, cur.coef)
        reg = reg0 if not cur.names else Regression(
            residual(kin.q, kin.v, kin.a, p_cur, theta_b0, kin.base_segment_angle), rows,
            candidates=tuple(k for k in EFFECT_NAMES if k not in cur.names and k not in dropped))
        base_fit = reg.fit([])
        ranked = []
        for k in reg.candidates:
            f = reg.fit([k])
            gain = base_fit.bic - f.bic
            if k not in single:
                single[k] = f
            ranked.append((gain, k, f))
        ranked.sort(key=lambda r: -r[0])
        step = {"model": list(cur.names), "tau_time": reg.tau_t, "tau_s": reg.tau_s, "n_eff": reg.n_eff,
                "residual_bic_gain": {k: g for g, k, _ in ranked}, "coefficients": {
                    k: float(f.coef[0]) for _, k, f in ranked}, "confirmation": []}
        steps.append(step)
        # a model at its floor (hidden: the fitted initial state may mimic an effect) tries only
        # the candidates the initial-state-free cut-moment residual shows (BIC gain >=
        # bic_min_improvement)
        hidden, size_min = entry_threshold(cur.rmse, floor_of(cur) if cur.names else floor, gap_before, st)
        step["hidden_by_initial_state"] = hidden
        pool = [r for r in ranked if r[0] >= st.bic_min_improvement] if hidden else ranked
        if not pool:
            break
        step["min_effect_size_rad"] = size_min
        added = False
        # order: the candidates the residual shows (BIC gain >= bic_min_improvement) ranked
        # together with all others by their linearised trajectory evidence (the residual of
        # noisy accelerations can misrank correlated stiffness candidates); the first
        # max_confirm (in the first step also every one the residual shows) are confirmed by
        # full trajectory fits, the rest only if none holds up
        scores = {k: fitter.score(cur, k) for _, k, _ in pool}
        step["trajectory_score"] = scores
        order = sorted(pool, key=lambda r: -scores[r[1]])
        # in the first step, besides the best max_confirm by score, every candidate the residual
        # of the nominal model shows is confirmed: the score ranks what the trajectory fit of the
        # model's current form wants, and an effect the initial-state-free residual shows may rank
        # below correlated candidates that then fit the floor (rest_curvature under
        # stiffness_scale on 6 markers, 2 mm). Later steps keep max_confirm: confirming all there
        # let three_effects' stiffness error enter ahead of its drag, after which the model sat
        # within min_gap_rad of its floor, where the drag's residual gain (9.1) is too small
        screened = order[:st.max_confirm] + [r for r in order[st.max_confirm:]
                                             if not cur.names and r[0] >= st.bic_min_improvement]
        # all others are fitted if the screened ones fail: the linearised score is local (a
        # frequency-changing effect's response is far from linear once the phase error is
        # large: on the mid-motion camera record tip_mass scored 0, pointing out of range,
        # and was the effect); not when hidden (the gap is small, the linearisation holds)
        tried = {r[1] for r in screened}
        rest = [] if hidden else [r for r in order if r[1] not in tried]
        for group in (screened, rest):
            best = None
            for gain, k, f in group:
                names = cur.names + [k]
                c_reg = f.coef.copy()
                if c_reg[0] == 0.0 and EFFECTS[k].reg_lo == 0.0:  # at its bound: start inside
                    c_reg[0] = max(float(f.std[0]), 1e-6)
                x0 = np.concatenate([cur.coef, c_reg])
                xs = np.concatenate([cur.std, f.std])
                cand = fitter.fit(names, x0, xs, st.refine_max_nfev)
                if cand.rmse >= cur.rmse:  # a poor regression start: start from the current model
                    x1 = np.concatenate([cur.coef, [0.0 if EFFECTS[k].reg_lo < 0.0 else 1e-6]])
                    retry = fitter.fit(names, x1, xs, st.refine_max_nfev)
                    cand = retry if retry.rss < cand.rss else cand
                dbic = trajectory_delta_bic(cur, cand)
                # practical significance: the effect's own size in the joint fit (its marginal
                # RMSE decrease understates it when candidates are correlated)
                size = fitter.effect_size(cand, k)
                closes = size >= size_min
                # the two independent estimates of the same joint model must agree in sign:
                # a candidate whose cut-moment regression coefficient (all named effects
                # regressed jointly on the nominal residual) is opposite, or at its bound,
                # while the trajectory fit wants it is a global effect absorbing a disturbance
                # it does not describe
                joint_reg = reg0.fit(names)
                agrees = float(joint_reg.coef[-1]) * float(cand.coef[-1]) > 0.0
                ok = dbic >= st.bic_min_improvement and closes and agrees
                step["confirmation"].append({"effect": k, "residual_bic_gain": gain, "rmse": cand.rmse,
                                             "trajectory_delta_bic": dbic, "accepted": False,
                                             "effect_size_rad": size,
                                             "residual_coefficient": float(f.coef[0]),
                                             "joint_residual_coefficient": float(joint_reg.coef[-1]),
                                             "trajectory_coefficient": float(cand.coef[-1]),
                                             "signs_agree": agrees, "nfev": cand.nfev})
                log.info("trajectory fit %s: RMSE %.4f, delta BIC %.1f, size %.4f, acceptable %s", names,
                         cand.rmse, dbic, size, ok)
                if ok and (best is None or cand.rss < best[0].rss):
                    best = (cand, len(step["confirmation"]) - 1)
            if best is not None:  # the best confirmed candidate of the group enters
                cur = best[0]
                step["confirmation"][best[1]]["accepted"] = True
                added = True
                break
        if added:
            cur, step["elimination"] = eliminate(fitter, cur, cur.names[-1], gap_before, st)
            dropped.update(e["effect"] for e in step["elimination"] if e["dropped"])
            accepted.append(cur)
        if not added or len(cur.names) >= st.max_effects:
            break
    swaps: list[dict[str, Any]] = []
    size_min_final = entry_threshold(gap_before, floor, gap_before, st)[1]
    holdout: list[dict[str, Any]] = []
    pruning: list[dict[str, Any]] = []
    if accepted:
        cur, swaps = swap(fitter, cur, reg0, dropped, size_min_final, st)
        # no effect that the others make redundant out of sample (held-out time blocks)
        cur, holdout = holdout_check(fitter, cur, st)
        # the smallest model that reaches its own floor (crgpr.discovery.prune)
        cur, pruning = smallest_model(fitter, cur, floor_of, partial(residual_gain, kin, params, rows),
                                      gap_before, excess, hidden_nominal, st)
        if cur is not accepted[-1]:
            accepted.append(cur)
    result: dict[str, Any] = {
        "measured": meas.source, "input": meas.summary(), "n_samples": n,
        "n_markers_compared": int(M.shape[0]), "model_N": params.N,
        "sample_rate_hz": 1.0 / period, "gp_noise_std_m": kin.noise_std_m,
        "gap_before": gap_before, "tip_gap_before": tip_before, "gap_floor": floor,
        "gap_floor_noise": f_noise, "gap_floor_discretisation": f_disc, "gap_floor_model_form": f_form,
        "gap_excess_over_floor": excess,
        "hidden_by_initial_state": hidden_nominal,
        "initial_state_fit": {"modes": st.init_modes, "nominal_corrections": nominal.init.tolist()},
        "selection": {"criterion": "forward stepwise BIC on the port-Hamiltonian residual "
                                   "(heteroscedastic, autocorrelation-deflated), each step confirmed "
                                   "by the trajectory fit's BIC",
                      "bic_min_improvement": st.bic_min_improvement,
                      "tau_time": reg0.tau_t, "tau_s": reg0.tau_s, "tau_base": reg0.tau_b,
                      "n_eff": reg0.n_eff, "steps": steps, "swaps": swaps, "holdout": holdout,
                      "pruning": pruning},
    }
    effects: list[dict[str, Any]] = []
    best_attempt = None
    q_aug = q_nom
    if accepted:
        fit = accepted[-1]
        attempt = []
        for i, k in enumerate(fit.names):
            e = EFFECTS[k]
            nominal_val = getattr(params, e.field)
            base = 0.0 if (k == "base_compliance" or not math.isfinite(nominal_val)) else nominal_val
            rc = single.get(k)
            attempt.append({
                "name": k, "unit": e.unit, "place": e.place,
                "coefficient": base + e.to_coefficient(float(fit.coef[i])),
                # the trajectory fit's std holds the initial state fixed; the residual
                # regression's is usually larger: report the larger (conservative)
                "coefficient_std": max(e.coefficient_std(float(fit.coef[i]), float(fit.std[i])),
                                       e.coefficient_std(float(rc.coef[0]), float(rc.std[0])) if rc else 0.0),
                "trajectory_fit_std": e.coefficient_std(float(fit.coef[i]), float(fit.std[i])),
                "regression_coefficient": base + e.to_coefficient(float(rc.coef[0])) if rc else None,
                "regression_std": e.coefficient_std(float(rc.coef[0]), float(rc.std[0])) if rc else None,
            })
        frac = 1.0 - fit.rmse / gap_before
        remaining = math.sqrt(max(fit.rmse**2 - floor_of(fit) ** 2, 0.0))
        excess_frac = 1.0 - remaining / excess if excess > 0 else (1.0 if remaining == 0.0 else 0.0)
        best_attempt = {"effects": attempt, "gap_after": fit.rmse, "explained_fraction": frac,
                        "explained_excess_fraction": excess_frac,
                        "remaining_excess": remaining, "gap_floor": floor_of(fit),
                        "gap_floor_parts": floor_parts[model_key(fit)]}
        # an effect hidden by the initial state (nominal gap within min_gap_rad of the floor)
        # cannot close half of a gap that is mostly floor: there it must close half the excess
        if closes_gap(fit.rmse, floor_of(fit), gap_before, excess, hidden_nominal,
                      max(st.min_gap_rad, st.max_remaining * excess), st):
            effects, q_aug = attempt, fit.q
    described = None
    if effects:
        verdict = "effect_found"
    elif hidden_nominal:
        verdict = "none"
    else:
        # no named effect closes the gap: learn the bending stiffness along s instead
        rivals = tuple((step["model"] + [c["effect"]], c["rmse"])
                       for step in steps for c in step["confirmation"])
        described = describe(fitter, nominal, floor, nominal.tau, gap_before, excess, st, rivals)
        q_desc = described.pop("_q")
        # a change confined to the clamp's neighbourhood is the clamp's form (a clamp of finite
        # length; another simulator's clamp model), not a missing effect, even where a library
        # effect rejected by its own tests fits about as well
        region = described["region"]
        described["clamp_form"] = bool(described["closes_the_gap"] and region["s_to_m"] <= st.clamp_form_m)
        if described["clamp_form"]:
            verdict = "none"
        elif described["accepted"]:
            verdict, q_aug = "described", q_desc
        else:
            verdict = "unexplained"
    gap_after = theta_rmse(q_aug, kin.q, M)
    result.update({
        "effects": effects, "verdict": verdict, "gap_after": gap_after,
        "tip_gap_after": tip_rmse_over_L(q_aug, kin.q, s_last, params),
        "explained_fraction": 1.0 - gap_after / gap_before if gap_before > 0 else 0.0,
        # share of the excess over the floor closed (floor, excess and remainder in quadrature)
        "explained_excess_fraction": (1.0 - math.sqrt(max(gap_after**2 - floor**2, 0.0)) / excess
                                      if excess > 0 else 0.0),
        "where": where, "best_attempt": best_attempt, "described": described,
        "indistinguishable_alternatives": alternatives(swaps, [e["name"] for e in effects], size_min_final,
                                                       st),
        # effects that entered in-sample but did not predict held-out time blocks
        "rejected_out_of_sample": [{"effect": h["effect"], "model": h["model"],
                                    "held_out_evidence": h["held_out_evidence"]}
                                   for h in holdout if h["dropped"]],
        # effects of the selected model that a smaller model reaching its own floor does not need
        "not_needed": [{"effect": p["effect"], "model": p["model"], "rmse_without": p["rmse_without"],
                        "floor_without": p["floor_without"]} for p in pruning if p["dropped"]],
        "significant_but_below_tolerance": [k for k, g in steps[0]["residual_bic_gain"].items()
                                            if g >= st.bic_min_improvement] if verdict == "none" else [],
        "timing_s": {"gp_smoothing": t_smooth, "total": time.perf_counter() - t_start},
    })
    arrays = {"kin": kin, "q_nom": q_nom, "q_aug": q_aug, "residual": res0, "params": params, "M": M}
    return {"result": result, "arrays": arrays}
