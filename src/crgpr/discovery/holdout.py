"""Leave-one-effect-out on held-out time blocks: no effect is named that the others make
redundant out of sample.

Stepwise selection judges each entry by in-sample evidence (trajectory BIC, effect size); with
several effects correlated in their trajectory signatures (a uniform stiffness error and a
cubic stiffening both raise the frequency of a large swing) a second one can enter as a proxy
for the first one's imperfect fit. Here every named effect of a model of two or more must
predict held-out data: the record is cut into ``holdout_blocks`` equal time blocks, the model
and each model without one effect are fitted (coefficients and initial state) on the even
blocks only, and the effect stays if the full model predicts the odd blocks better by
``n_eff ln(RSS_without / RSS_with) >= holdout_min_evidence`` (twice the held-out log
likelihood ratio, the sample deflated by the residuals' autocorrelation time; 6 is "strong",
Kass and Raftery 1995). The weakest failing effect is dropped, the rest refitted on the whole
record, and the test repeated.
"""

from __future__ import annotations

import logging
import math
from typing import Any

import numpy as np

from crgpr.discovery.settings import DiscoverySettings
from crgpr.discovery.trajectory import TrajectoryFit, TrajectoryFitter

log = logging.getLogger(__name__)


def block_mask(n: int, blocks: int) -> np.ndarray:
    """1 on the even ones of ``blocks`` equal time blocks of n samples (the first included), else 0."""
    return ((np.arange(n) * blocks // n) % 2 == 0).astype(float)


def held_out_rss(fitter: TrajectoryFitter, fit: TrajectoryFit, test: np.ndarray) -> float:
    """Sum of squared theta errors at the markers on the samples where ``test`` is 1."""
    e = fit.q[..., 2] @ fitter.M.T - fitter.theta_m
    return float(np.sum((e * test[:, None]) ** 2))


def holdout_check(fitter: TrajectoryFitter, cur: TrajectoryFit, st: DiscoverySettings
                  ) -> tuple[TrajectoryFit, list[dict[str, Any]]]:
    """The model ``cur`` less every effect that fails the held-out test (module docstring), and
    a record per test (the held-out evidence of each effect in each model tried)."""
    records: list[dict[str, Any]] = []
    train = block_mask(fitter.n, st.holdout_blocks)
    test = 1.0 - train
    g = fitter.masked(train)
    n_test = float(np.sum(test)) * fitter.M.shape[0]
    while len(cur.names) > 1:
        full = g.fit(cur.names, cur.coef, cur.std, st.refine_max_nfev)
        rss_full = held_out_rss(fitter, full, test)
        n_eff = n_test / max(cur.tau, 1.0)
        worst = None
        for i, k in enumerate(cur.names):
            red = g.fit([n for n in cur.names if n != k], np.delete(full.coef, i), np.delete(cur.std, i),
                        st.refine_max_nfev)
            ev = n_eff * math.log(max(held_out_rss(fitter, red, test), 1e-300) / max(rss_full, 1e-300))
            stays = ev >= st.holdout_min_evidence
            records.append({"effect": k, "model": list(cur.names), "held_out_evidence": ev,
                            "held_out_rmse_with": math.sqrt(rss_full / n_test),
                            "held_out_rmse_without": math.sqrt(held_out_rss(fitter, red, test) / n_test),
                            "dropped": False})
            log.info("held-out test of %s in %s: evidence %.1f, stays %s", k, cur.names, ev, stays)
            if not stays and (worst is None or ev < worst[0]):
                worst = (ev, i, records[-1])
        if worst is None:
            break
        worst[2]["dropped"] = True
        i = worst[1]
        cur = fitter.fit([n for n in cur.names if n != cur.names[i]], np.delete(cur.coef, i),
                         np.delete(cur.std, i), st.refine_max_nfev)
    return cur, records
