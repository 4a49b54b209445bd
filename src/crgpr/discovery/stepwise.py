"""Stepwise selection's tests on joint trajectory fits: entry, elimination, swaps, alternatives.

A candidate enters if the joint fit lowers the trajectory BIC (``trajectory_delta_bic``) and its
own size clears ``entry_threshold``; after each entry the other named effects are tested again
(``eliminate``); at the end each named effect is tried replaced by the candidates of its own
place in the structure (``swap``), and the replacements the data do not tell apart are
reported (``alternatives``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from crgpr.discovery.effects import EFFECT_NAMES, EFFECTS
from crgpr.discovery.regression import Regression
from crgpr.discovery.settings import DiscoverySettings
from crgpr.discovery.trajectory import TrajectoryFit, TrajectoryFitter

log = logging.getLogger(__name__)


def trajectory_delta_bic(small: TrajectoryFit, big: TrajectoryFit) -> float:
    """BIC(small) - BIC(big) for theta residuals with the sample size deflated by big's tau."""
    n_eff = big.n / max(big.tau, 1.0)
    dp = len(big.names) - len(small.names)
    return n_eff * math.log(max(small.rss, 1e-300) / max(big.rss, 1e-300)) - dp * math.log(n_eff)


def entry_threshold(rmse: float, floor: float, gap_before: float, st: DiscoverySettings
                    ) -> tuple[bool, float]:
    """(hidden, least effect size [rad]) for a candidate entering a model with theta RMSE
    ``rmse`` and floor ``floor``.

    ``hidden``: the model, with its own fitted initial state, is within ``min_gap_rad`` of its
    floor. On a short record the initial state mimics much of an effect (0.8 s of viscous drag:
    0.099 rad from the true release, 0.018 rad from the fitted initial state), so a small gap
    does not show that nothing is missing; the cut-moment residual, which needs no initial
    state, still does. A hidden effect must be large enough that it alone would have put the
    gap over the "none" threshold: its own size (with vs without it, same initial state)
    >= hypot(floor, min_gap_rad). Otherwise an effect's size must be >= min_effect_fraction of
    the nominal gap ``gap_before``."""
    hidden = math.sqrt(max(rmse**2 - floor**2, 0.0)) <= st.min_gap_rad
    return hidden, (math.hypot(floor, st.min_gap_rad) if hidden else st.min_effect_fraction * gap_before)


def eliminate(fitter: TrajectoryFitter, cur: TrajectoryFit, keep: str, gap_before: float,
              st: DiscoverySettings) -> tuple[TrajectoryFit, list[dict[str, Any]]]:
    """Backward elimination after a candidate entered (nested-model test on the joint fit).

    Every other named effect is tested in the model that now holds them all: the model is
    refitted without it (all remaining coefficients and the initial state free) and the effect
    stays only if it still lowers BIC by ``bic_min_improvement`` and its own size in the joint
    fit is at least ``min_effect_fraction`` of the gap, the tests it had to pass to enter. The
    weakest failing effect is dropped first and the test repeated. An effect that entered early
    as a proxy for two true ones (a rest curvature for a tip mass plus drag) leaves once both
    are named. ``keep`` (the effect that just entered) is not tested again."""
    def judge(cur: TrajectoryFit, k: str, red: TrajectoryFit, dbic: float) -> tuple[dict[str, Any], bool]:
        size = fitter.effect_size(cur, k)
        stays = dbic >= st.bic_min_improvement and size >= st.min_effect_fraction * gap_before
        log.info("elimination %s from %s: delta BIC %.1f, size %.4f, stays %s", k, cur.names, dbic, size,
                 stays)
        return {"effect": k, "model": list(cur.names), "trajectory_delta_bic": dbic, "effect_size_rad": size,
                "rmse_without": red.rmse}, not stays

    return drop_weakest(fitter, cur, judge, st, keep)


Judge = Callable[[TrajectoryFit, str, TrajectoryFit, float], tuple[dict[str, Any], bool]]


def drop_weakest(fitter: TrajectoryFitter, cur: TrajectoryFit, judge: Judge, st: DiscoverySettings,
                 keep: str | None = None) -> tuple[TrajectoryFit, list[dict[str, Any]]]:
    """Drop named effects one at a time, weakest first, while ``judge`` lets one go.

    Each effect of ``cur`` but ``keep`` is refitted out (remaining coefficients and the initial
    state free, ``refine_max_nfev``); ``judge(cur, k, reduced, delta_bic)`` returns the record of
    that test and whether k may leave; of those that may, the one of smallest trajectory BIC
    contribution (``trajectory_delta_bic``) is dropped (its record marked ``dropped``) and the
    tests repeated on the smaller model. Backward elimination (``eliminate``) and the pruning to
    the smallest model at its floor (``prune.smallest_model``) differ only in their judge."""
    records: list[dict[str, Any]] = []
    while len(cur.names) > 1:
        weakest = None
        for i, k in enumerate(cur.names):
            if k == keep:
                continue
            red = fitter.fit([n for n in cur.names if n != k], np.delete(cur.coef, i), np.delete(cur.std, i),
                             st.refine_max_nfev)
            dbic = trajectory_delta_bic(red, cur)
            rec, may_drop = judge(cur, k, red, dbic)
            rec["dropped"] = False
            records.append(rec)
            if may_drop and (weakest is None or dbic < weakest[0]):
                weakest = (dbic, red, rec)
        if weakest is None:
            break
        weakest[2]["dropped"] = True
        cur = weakest[1]
    return cur, records


def swap(fitter: TrajectoryFitter, cur: TrajectoryFit, reg0: Regression, excluded: set[str],
         size_min: float, st: DiscoverySettings) -> tuple[TrajectoryFit, list[dict[str, Any]]]:
    """Replacement step of stepwise selection (Miller, Subset Selection in Regression, 2002,
    Sec. 3.5): each named effect is tried replaced by every candidate of the same place in the
    structure (``Effect.place``: the dissipative R terms among themselves, the H terms among
    themselves), all coefficients and the initial state refitted. Forward selection fixes the
    order of entry while the model is still incomplete: three_effects' drag entered as air_drag
    beside a tip mass at half its value, when viscous_drag's linearised score was lower; once
    the stiffness and the tip mass are named, the right drag fits better. The best replacement
    that lowers the trajectory BIC by ``bic_min_improvement`` (same number of parameters: the
    RSS ratio alone) and passes the entry tests (own size >= ``size_min``, the same sign in the
    joint residual regression) is made, and the search repeated; an effect replaced is not
    offered again."""
    records: list[dict[str, Any]] = []
    gone = set(excluded)
    fitted: dict[frozenset[str], tuple[TrajectoryFit, float, float]] = {}  # a model is fitted once
    while True:
        best = None
        for i, k in enumerate(cur.names):
            for j in EFFECT_NAMES:
                if j in cur.names or j in gone or EFFECTS[j].place != EFFECTS[k].place:
                    continue
                names = cur.names[:i] + [j] + cur.names[i + 1:]
                if frozenset(names) not in fitted:
                    jr = reg0.fit(names)  # initial-state-free start for the newcomer
                    c_j = float(jr.coef[i])
                    if c_j == 0.0 and EFFECTS[j].reg_lo == 0.0:
                        c_j = max(float(jr.std[i]), 1e-6)
                    x0 = cur.coef.copy()
                    x0[i] = c_j
                    xs = cur.std.copy()
                    xs[i] = float(jr.std[i])
                    cand = fitter.fit(names, x0, xs, st.refine_max_nfev)
                    fitted[frozenset(names)] = (cand, fitter.effect_size(cand, j), float(jr.coef[i]))
                cand, size, c_reg = fitted[frozenset(names)]
                i_c = cand.names.index(j)
                dbic = trajectory_delta_bic(cur, cand)
                agrees = c_reg * float(cand.coef[i_c]) > 0.0
                ok = dbic >= st.bic_min_improvement and size >= size_min and agrees
                records.append({"out": k, "in": j, "model": list(cur.names), "rmse": cand.rmse,
                                "trajectory_delta_bic": dbic, "effect_size_rad": size,
                                "joint_residual_coefficient": c_reg,
                                "trajectory_coefficient": float(cand.coef[i_c]), "signs_agree": agrees,
                                "swapped": False})
                log.info("swap %s -> %s in %s: RMSE %.4f, delta BIC %.1f, size %.4f, acceptable %s", k, j,
                         cur.names, cand.rmse, dbic, size, ok)
                if ok and (best is None or cand.rss < best[0].rss):
                    best = (cand, records[-1], k)
        if best is None:
            return cur, records
        best[1]["swapped"] = True
        gone.add(best[2])
        cur = best[0]


def alternatives(swaps: list[dict[str, Any]], names: list[str], size_min: float, st: DiscoverySettings
                 ) -> list[dict[str, Any]]:
    """Replacements (``swap`` records) that the data do not tell apart from the named model
    ``names``: tried in that model, passing the entry tests (own size >= ``size_min``, signs
    agree) with |delta BIC| < ``bic_min_improvement``. Reported beside the named effects, not
    instead of them (three_effects, full config: viscous_drag for air_drag at RMSE 0.0134 vs
    0.0128 rad, delta BIC -9.6, both below the floor 0.0226)."""
    return [{"named": w["out"], "alternative": w["in"], "trajectory_delta_bic": w["trajectory_delta_bic"],
             "rmse": w["rmse"]} for w in swaps
            if names and w["model"] == list(names) and not w["swapped"] and w["signs_agree"]
            and abs(w["trajectory_delta_bic"]) < st.bic_min_improvement and w["effect_size_rad"] >= size_min]
