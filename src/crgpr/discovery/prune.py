"""The smallest model that reaches its own floor: effects a named model does not need are dropped.

Stepwise selection and the held-out test judge each effect by evidence on the record (trajectory
BIC, held-out blocks). Both count what a model's floor is made of (the smoothing of a few noisy
markers, the model's coarser grid) as signal: on a 1 s record of a rest curvature seen by 6
markers with 2 mm noise a uniform stiffness error and a cubic stiffening stayed beside the rest
curvature, with the three-effect model below its own floor. Here, after the held-out test, an
effect is dropped when the model without it (remaining coefficients and initial state refitted)
still closes the gap by the verdict's rule and reaches ITS OWN floor (its theta RMSE at most its
floor: the data cannot tell what the effect adds from what the floor is made of), unless the
search would add it back to that model: a model at its floor admits a candidate the
initial-state-free cut-moment residual shows (BIC gain >= ``bic_min_improvement``) whose own
size in the joint fit is at least hypot(floor, ``min_gap_rad``) (``stepwise.entry_threshold``).
The weakest such effect (smallest trajectory BIC contribution) is dropped first and the test
repeated.

The model without the effect must reach its floor, not only come within the verdict's allowance
``max(min_gap_rad, max_remaining * excess)`` of it: that allowance admits an imperfect law on a
large gap, and even a remainder of ``min_gap_rad`` would drop the drag of the config's
three-effect record (measured: the tip mass and the stiffness error alone fit it to 0.0257 rad
over their floor of 0.0170, an excess of 0.019; the drag's residual gain against that model is
8.7, under ``bic_min_improvement``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Any

from crgpr.discovery.effects import EFFECT_NAMES
from crgpr.discovery.regression import Regression
from crgpr.discovery.residual import residual
from crgpr.discovery.settings import DiscoverySettings
from crgpr.discovery.stepwise import drop_weakest
from crgpr.discovery.trajectory import TrajectoryFit, TrajectoryFitter, augmented_params
from crgpr.measured.kinematics import Kinematics
from crgpr.physics.params import RodParams

log = logging.getLogger(__name__)


def closes_gap(rmse: float, own_floor: float, gap_before: float, excess: float, hidden_nominal: bool,
               allowance: float, st: DiscoverySettings) -> bool:
    """The verdict's rule for a model of theta RMSE ``rmse`` and floor ``own_floor``: it closes at
    least ``min_explained`` of the nominal gap ``gap_before`` (of the nominal excess over the
    floor ``excess`` when the nominal gap was within ``min_gap_rad`` of its floor,
    ``hidden_nominal``) and leaves an excess over its own floor (in quadrature) <= ``allowance``."""
    remaining = math.sqrt(max(rmse**2 - own_floor**2, 0.0))
    if hidden_nominal:
        excess_frac = 1.0 - remaining / excess if excess > 0 else (1.0 if remaining == 0.0 else 0.0)
        closes = excess_frac >= st.min_explained
    else:
        closes = 1.0 - rmse / gap_before >= st.min_explained
    return closes and remaining <= allowance


def residual_gain(kin: Kinematics, params: RodParams, rows: slice, fit: TrajectoryFit, k: str) -> float:
    """BIC gain of candidate ``k`` in the cut-moment residual of the record ``kin`` (time rows
    ``rows``) against the model ``fit`` (the nominal ``params`` with its effects), the candidates
    being every effect it does not hold, as in a step of the search."""
    res = residual(kin.q, kin.v, kin.a, augmented_params(params, fit.names, fit.coef), float(kin.q[0, 0, 2]),
                   kin.base_segment_angle)
    reg = Regression(res, rows, candidates=tuple(c for c in EFFECT_NAMES if c not in fit.names))
    return reg.fit([]).bic - reg.fit([k]).bic


def smallest_model(fitter: TrajectoryFitter, cur: TrajectoryFit, floor_of: Callable[[TrajectoryFit], float],
                   residual_gain: Callable[[TrajectoryFit, str], float], gap_before: float, excess: float,
                   hidden_nominal: bool, st: DiscoverySettings) -> tuple[TrajectoryFit, list[dict[str, Any]]]:
    """``cur`` less every effect it does not need (module docstring), and a record per effect
    tested. ``floor_of(fit)`` is a model's own floor [rad]; ``residual_gain(fit, k)`` the BIC
    gain of candidate ``k`` in the cut-moment residual against the model ``fit``. Only a model
    that closes the gap by the verdict's rule is pruned."""
    allowance = max(st.min_gap_rad, st.max_remaining * excess)
    if not closes_gap(cur.rmse, floor_of(cur), gap_before, excess, hidden_nominal, allowance, st):
        return cur, []

    def judge(cur: TrajectoryFit, k: str, red: TrajectoryFit, dbic: float) -> tuple[dict[str, Any], bool]:
        fl = floor_of(red)
        at_floor = closes_gap(red.rmse, fl, gap_before, excess, hidden_nominal, 0.0, st)
        gain = residual_gain(red, k)
        size = fitter.effect_size(cur, k)
        reenters = gain >= st.bic_min_improvement and size >= math.hypot(fl, st.min_gap_rad)
        log.info("pruning %s from %s: RMSE without %.4f (floor %.4f), at floor %s, re-enters %s", k,
                 cur.names, red.rmse, fl, at_floor, reenters)
        closes = closes_gap(red.rmse, fl, gap_before, excess, hidden_nominal, allowance, st)
        return ({"effect": k, "model": list(cur.names), "rmse_without": red.rmse, "floor_without": fl,
                 "remaining_excess_without": math.sqrt(max(red.rmse**2 - fl**2, 0.0)),
                 "closes_without": closes,
                 "at_floor_without": at_floor, "residual_bic_gain": gain, "effect_size_rad": size,
                 "re_enters": reenters, "trajectory_delta_bic": dbic}, at_floor and not reenters)

    return drop_weakest(fitter, cur, judge, st)

