"""The learned design's odds over the learned model's posterior (docs/control.md, "Odds from the
posterior").

The question: the controller is designed on a learned model that the data determine only up to
its posterior. Designed on each of K posterior samples of the learned force laws instead of on
their mean, does the same closed loop still converge on the true rod, and how far apart are the
steady-state errors it leaves? Each sample gives one regulation design (``design.hold``,
``design.regulation_policy``; only the static force balance enters the design, so only the force
laws' samples matter), run on one plant from one start (``closed_loop.run_closed_loop``). A
sample on which no design exists (no equilibrium, or one beyond the input limits) counts as not
converged.

Convergence: the tip error stays within the settling band over the whole steady-state window,
i.e. the run settles (``metrics.settling_time``) no later than ``t_end - window``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from crgpr.control import metrics
from crgpr.control.closed_loop import Plant, run_closed_loop
from crgpr.control.design import Gains, Solver, hold, regulation_policy
from crgpr.control.statics import UnreachableTarget
from crgpr.learning.learned import LearnedRod
from crgpr.physics.params import RodParams
from crgpr.uq.rollout import n_samples_of
from crgpr.uq.samples import select_samples


def sample_internals(components: Mapping[str, Any], features: str, params: RodParams,
                     theta_center: float | None) -> list[Callable[[np.ndarray], np.ndarray]]:
    """-dH/dq per unit length of each posterior sample alone: q (N+1, 3) -> (N+1, 3), one
    callable per sample s of the sample sets in ``components`` (deterministic components, e.g.
    the momentum maps' means or nominal laws, are shared by every sample; with none, the one
    deterministic rod)."""
    S = n_samples_of(components, default=1)

    def one(s: int) -> Callable[[np.ndarray], np.ndarray]:
        rod = LearnedRod({m: select_samples(c, np.array([s])) for m, c in components.items()},
                         features, params, theta_center)
        return lambda q: rod.internal(np.asarray(q, dtype=float)[None])[0]
    return [one(s) for s in range(S)]


@dataclass(frozen=True)
class PosteriorRuns:
    """Per sample: whether a design exists, whether its loop converged, its feedforward u_ff (K, 3),
    steady tip error, residual oscillation [m] and settling time [s] (nan where no design exists)."""

    designed: np.ndarray
    u_ff: np.ndarray
    converged: np.ndarray
    steady_error: np.ndarray
    oscillation: np.ndarray
    settling: np.ndarray

    @property
    def converged_fraction(self) -> float:
        """Fraction of all K samples whose design exists and whose loop converged."""
        return float(np.mean(self.converged))

    def median_converged(self, values: np.ndarray) -> float:
        """Median of per-sample ``values`` over the converged samples (nan if none converged)."""
        return float(np.median(values[self.converged])) if self.converged.any() else float("nan")

    def spread(self, point_mass: bool = False) -> float:
        """Sample standard deviation (ddof = 1) of the steady tip error over the converged samples
        [m] (nan for fewer than two). ``point_mass``: the runs are the one deterministic rod of a
        model without a learned force law (``sample_internals``), whose posterior is a point mass:
        0 where it converged (every sample would be that rod), else nan."""
        e = self.steady_error[self.converged]
        if point_mass:
            return 0.0 if e.size else float("nan")
        return float(np.std(e, ddof=1)) if e.size >= 2 else float("nan")


def converged(run: Any, band: float, window_s: float) -> bool:
    """The tip error within ``band`` [m] from ``t_end - window_s`` on."""
    ts = metrics.settling_time(run, band)
    return bool(np.isfinite(ts) and ts <= run.t[-1] - window_s + 1e-12)


def posterior_regulation(internals: Sequence[Callable[[np.ndarray], np.ndarray]], gravity: np.ndarray,
                         q_rest: np.ndarray, ds: float, target: tuple[float, float, float | None],
                         gains: Gains, solver: Solver, u_min: np.ndarray, u_max: np.ndarray, plant: Plant,
                         q0: np.ndarray, rate_hz: float, t_end: float, band: float, window_s: float
                         ) -> PosteriorRuns:
    """Design the regulation controller on each sampled model (its equilibrium at ``target``
    from the model rod ``q_rest``) and run it on ``plant`` from rest at ``q0``."""
    K = len(internals)
    designed, conv = np.zeros(K, bool), np.zeros(K, bool)
    err, osc, ts = (np.full(K, np.nan) for _ in range(3))
    u_ff = np.full((K, 3), np.nan)
    for s, internal in enumerate(internals):
        try:
            eq = hold(internal, gravity, q_rest, ds, target, solver, u_min, u_max)
        except UnreachableTarget:
            continue
        designed[s], u_ff[s] = True, eq.u
        run = run_closed_loop(regulation_policy(eq, target, gains, u_min, u_max), plant, q0,
                              np.zeros_like(q0), rate_hz, t_end, 10**9)
        conv[s] = converged(run, band, window_s)
        err[s] = metrics.steady_error(run, window_s)
        osc[s] = metrics.residual_oscillation(run, window_s)
        ts[s] = metrics.settling_time(run, band)
    return PosteriorRuns(designed, u_ff, conv, err, osc, ts)
