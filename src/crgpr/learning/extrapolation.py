"""A learned bending law beyond the curvatures it was trained on (paper Sec. II: the law is unknown).

Outside its covered range [lo, hi] (the training inputs' min and max, mirrored samples
included) a GP law's mean is its basis trend plus the kernel's decay towards it: an
extrapolation the data did not check. Where the record bends the rod one way and the law is
not mirrored (its odd symmetry refused), the other side is pure extrapolation and the linear
trend fitted to the far side can be far off (a saturating law's trend, softened by the
saturation, halves the moment there). So, per side of the covered range:

* the **reach** r: the law is the GP's own mean out to the farthest grid point of the law table
  (``learning.law_tables``: ``pad`` x the range beyond each edge) up to which every grid point's
  95 % band half-width 1.96 sd stays within ``band`` |m|, counted outward from the edge; the
  edge itself where the first point beyond it fails. A law whose band stays narrow far out (a
  law mirrored over both signs of the curvature, learned from exact moments) keeps its GP
  extrapolation; one the data leave unconstrained (the band as wide as the moment) does not;
* beyond r, where the law has a rest curvature c between the two reaches (``rest_state``, or
  the curvature it is mirrored about): the shape of its mirror image about c, M(kappa) =
  2 m(c) - m(2 c - kappa), joined on at r (m(r) + M(kappa) - M(r)), for as far as the mirrored
  curvature 2 c - kappa stays within the other side's reach: a symmetric section's law is odd
  about its rest curvature, and the other side is what the data show of it. A record that bends
  the rod one way leaves one side short; mirrored laws (both sides reached alike) have no such
  piece;
* beyond that (or without c): the law continued by its tangent, with the slope k of the law's
  secant over the last ``tangent_span`` (hi - lo) inside the reach it ends on (the other side's,
  mirrored, after a mirror piece), never below 0: no negative stiffness; times the tail factor
  g > 0 (``Reach.slope_factor``: 1 unless the record fit sized it from the motion,
  ``learning.record_fit``). The moment stays a function of the curvature (and s), so the
  learned H_z keeps a potential (eq. (10)).

A law of s (a rod graded along its length): the reach of each side is the nearest over the
table's s slices. The band used is the table's (jackknife-scaled, with the record-fit warp's
share; where the record fit runs, the law's own band before it: the reach it fits with is the
one the model keeps), at the other inputs' training medians.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import pandas as pd

from crgpr.learning.laws import Z95


@dataclass(frozen=True)
class Reach:
    """How far each side of a bending law uses its GP mean, and the tangent's secant width (JSON-able)."""

    lo: float  # the GP mean is used down to this curvature [1/m]
    hi: float  # ... and up to this one [1/m]
    span: float  # secant width of the tangent continuation, tangent_span (hi_cov - lo_cov) [1/m]
    covered_lo: float  # the covered range's edges [1/m]
    covered_hi: float
    band: float  # the criterion: 1.96 sd <= band |m| [-]
    center: float | None = None  # the rest curvature the mirror piece is about (None: no mirror) [1/m]
    slope_factor: float = 1.0  # the tail factor g of the tangent's slope (the record fit's, else 1) [-]

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def side_reach(x: np.ndarray, mean: np.ndarray, sd: np.ndarray, lo: float, hi: float, band: float
               ) -> tuple[float, float]:
    """(r_lo, r_hi) of one law slice tabulated on the increasing grid ``x`` (module doc): from each
    edge of [lo, hi] outward, the last grid point of the run of points whose 1.96 ``sd`` is within
    ``band`` |``mean``|; the edge itself where the first point beyond it fails or none lies beyond."""
    x, mean, sd = (np.asarray(a, dtype=float).ravel() for a in (x, mean, sd))
    ok = Z95 * sd <= band * np.abs(mean)

    def walk(idx: np.ndarray, edge: float) -> float:
        r = edge
        for i in idx:
            if not ok[i]:
                break
            r = float(x[i])
        return r
    return walk(np.flatnonzero(x < lo)[::-1], lo), walk(np.flatnonzero(x > hi), hi)


def law_reach(table: pd.DataFrame, band: float, tangent_span: float, center: float | None = None
              ) -> Reach | None:
    """The ``Reach`` of the bending law in a law table (``learning.law_tables``: the rows of law
    ``obj_m``, input ``kappa``; one slice per ``at_s``, the nearest reach kept), ``center`` its
    rest curvature (None: unknown); None without such rows."""
    if not 0 < tangent_span <= 1 or band <= 0:
        raise ValueError(f"law_reach: band {band} must be > 0 and tangent_span {tangent_span} in (0, 1]")
    rows = table[(table["law"] == "obj_m") & (table["input"] == "kappa")] if not table.empty else table
    if rows.empty:
        return None
    lo, hi = float(rows["covered_lo"].iloc[0]), float(rows["covered_hi"].iloc[0])
    r_lo, r_hi = lo, hi
    slices = rows.groupby("at_s", dropna=False) if rows["at_s"].notna().any() else [(None, rows)]
    first = True
    for _, g in slices:
        g = g.sort_values("x")
        a, b = side_reach(g["x"].to_numpy(), g["mean"].to_numpy(), g["sd"].to_numpy(), lo, hi, band)
        r_lo, r_hi = (a, b) if first else (max(r_lo, a), min(r_hi, b))
        first = False
    return Reach(lo=r_lo, hi=r_hi, span=tangent_span * (hi - lo), covered_lo=lo, covered_hi=hi, band=band,
                 center=None if center is None else float(center))


def continued(kappa: np.ndarray, law: Callable[[np.ndarray], np.ndarray], reach: Reach,
              factor: np.ndarray | None = None) -> np.ndarray:
    """The law at curvatures ``kappa`` (any shape) inside the reach, continued beyond it by its
    mirror image about the rest curvature and then by its tangent (module doc); ``law(k)``
    evaluates it at curvatures of ``kappa``'s shape (broadcasting as the law's own output does);
    ``factor``: the tangent's tail factor, broadcast against ``kappa`` (None: the reach's)."""
    k = np.asarray(kappa, dtype=float)
    lo, hi, d = reach.lo, reach.hi, reach.span
    if not ((k > hi).any() or (k < lo).any()):
        return law(k)
    c = reach.center
    mirror = c is not None and lo < c < hi
    end_lo, end_hi = (min(lo, 2 * c - hi), max(hi, 2 * c - lo)) if mirror else (lo, hi)
    kc, ke = np.clip(k, lo, hi), np.clip(k, end_lo, end_hi)
    y = law(kc)
    if mirror and (ke != kc).any():  # m(r) + M(kappa) - M(r), M(kappa) = 2 m(c) - m(2 c - kappa)
        y = y + law(2 * c - kc) - law(2 * c - ke)
    if (k != ke).any():
        def secant(a: float, b: float) -> np.ndarray:
            return np.maximum((law(np.full_like(k, b)) - law(np.full_like(k, a))) / (b - a), 0.0)
        s_hi, s_lo = secant(hi - d, hi), secant(lo, lo + d)
        # the tangent of the piece each tail starts from: a mirror piece ends on the other side's edge
        slope = np.where(k > end_hi, s_lo if end_hi > hi else s_hi,
                         np.where(k < end_lo, s_hi if end_lo < lo else s_lo, 0.0))
        g = reach.slope_factor if factor is None else factor
        y = y + g * slope * (k - ke)
    return y


class TangentContinuation:
    """A bending-law component (``learned.Component``, objective m features: column 0 is kappa)
    continued beyond its ``Reach`` (mirror piece, tangent: module doc); a wrapper like
    ``warp.BendingWarp`` (``rewrap``: the same continuation of another component, e.g. its
    posterior samples, each continued from its own value and slope). ``factors`` (B,): each
    member of a batched rollout's own tail factor (the record fit's trials), else the reach's."""

    def __init__(self, component: Any, reach: Reach, factors: np.ndarray | None = None):
        self.component, self.reach = component, reach
        self.factors = None if factors is None else np.asarray(factors, dtype=float).ravel()
        self.meta = getattr(component, "meta", {})

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        k = X[..., 0]
        if k.size == 0 or (k.min() >= self.reach.lo and k.max() <= self.reach.hi):
            return self.component(X)  # inside the reach (every rollout step but a few): as it is

        def law(k: np.ndarray) -> np.ndarray:
            Xk = X.copy()
            Xk[..., 0] = k
            return self.component(Xk)
        g = None if self.factors is None else self.factors.reshape((-1,) + (1,) * (k.ndim - 1))
        return continued(k, law, self.reach, g)

    def rewrap(self, component: Any) -> TangentContinuation:
        return TangentContinuation(component, self.reach, self.factors)


def continue_table(table: pd.DataFrame, reach: Reach | None) -> pd.DataFrame:
    """The law table with the bending law's ``mean`` continued beyond ``reach`` (the law the
    rollouts integrate; each s slice from its own tabulated values, linearly interpolated) and a
    column ``continued`` (the row's mean is the tangent continuation); ``sd`` is the GP's."""
    out = table.copy()
    out["continued"] = False
    if reach is None or out.empty:
        return out
    sel = (out["law"] == "obj_m") & (out["input"] == "kappa")
    for _, g in out[sel].groupby("at_s", dropna=False):
        g = g.sort_values("x")
        x, m = g["x"].to_numpy(), g["mean"].to_numpy()
        out.loc[g.index, "mean"] = continued(x, lambda k, x=x, m=m: np.interp(k, x, m), reach)
        out.loc[g.index, "continued"] = (x > reach.hi) | (x < reach.lo)
    return out


def manifest_reach(man: dict[str, Any]) -> Reach | None:
    """The ``Reach`` recorded in a ``crgpr learn`` manifest (``bending_extrapolation``), else None
    (no learned bending law, or a manifest written before the reach was recorded)."""
    d = man.get("bending_extrapolation")
    if not d:
        return None
    return Reach(**{k: None if d[k] is None else float(d[k]) for k in Reach.__dataclass_fields__ if k in d})
