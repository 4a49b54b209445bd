"""Momentum maps H_p(p) that are linear or piecewise linear, compiled (eq. (9), (17)).

A learned rod's momentum maps dH/dp (one per component p_x, p_y, p_theta) are either the
nominal rod's, H_p = p / (rho A) or p / (rho I), or a GP tabulated on a grid and interpolated
linearly, 0 outside it (``gp.evaluators.Table1D``). Every time step evaluates them a dozen
times on a few dozen nodes: the damping half-steps (``integrator.run_hamiltonian``) and the
drift. ``MomentumMaps`` holds the three as arrays and evaluates them, and the whole damping
half-step, in one compiled pass each; the values are those of ``np.interp`` and of
``Table1D.slope`` (the same formulas and comparisons).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numba import njit


@njit(cache=True)
def _value(x, xs, ys, a, b, lin, st):
    """H_p of one component at x: st x (linear), else ``np.interp`` on xs[a:b], 0 outside."""
    if lin:
        return st * x
    if x < xs[a] or x > xs[b - 1]:
        return 0.0
    if x == xs[b - 1]:
        return ys[b - 1]
    lo, hi = a, b - 1  # xs[lo] <= x < xs[hi]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xs[mid] <= x:
            lo = mid
        else:
            hi = mid
    if xs[lo] == x:
        return ys[lo]
    return (ys[lo + 1] - ys[lo]) / (xs[lo + 1] - xs[lo]) * (x - xs[lo]) + ys[lo]


@njit(cache=True)
def _slope(x, xs, ys, a, b, lin, st):
    """dH_p/dp of one component at x: st (linear), else the slope of the piece xs[i-1] < x <=
    xs[i] (``Table1D.slope``), 0 at or left of the first knot and right of the last."""
    if lin:
        return st
    if x <= xs[a] or x > xs[b - 1]:
        return 0.0
    lo, hi = a, b - 1  # xs[lo] < x <= xs[hi]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xs[mid] < x:
            lo = mid
        else:
            hi = mid
    return (ys[lo + 1] - ys[lo]) / (xs[lo + 1] - xs[lo])


@njit(cache=True)
def _velocity(p, xs, ys, off, lin, st, out):
    """out (B, n, 3) = H_p(p) componentwise for p (B, n, 3)."""
    for b in range(p.shape[0]):
        for i in range(p.shape[1]):
            for k in range(3):
                out[b, i, k] = _value(p[b, i, k], xs, ys, off[k], off[k + 1], lin[k], st[k])


@njit(cache=True)
def _damp(p, xs, ys, off, lin, st, free, zeta, h, wds, out, lost):
    """``run_hamiltonian``'s generic damping half-step for the maps (its formulas, per rod b):
    p1 = p - f(s) H_p(p) free, f = (1 - exp(-zeta s h)) / s (zeta h where |zeta s h| < 1e-12),
    s = dH_p/dp at p; lost = sum_i w_i ds (H_p(p) + H_p(p1)) (p - p1) / 2. out (B, n, 3) = p1,
    lost (B,)."""
    n = p.shape[1]
    for b in range(p.shape[0]):
        e = 0.0
        for i in range(n):
            for k in range(3):
                x = p[b, i, k]
                v0 = _value(x, xs, ys, off[k], off[k + 1], lin[k], st[k])
                s = _slope(x, xs, ys, off[k], off[k + 1], lin[k], st[k]) * zeta
                fac = zeta * h if abs(s * h) < 1e-12 else -np.expm1(-s * h) / s * zeta
                d = fac * v0 * free[i, k]
                x1 = x - d
                vv = _value(x1, xs, ys, off[k], off[k + 1], lin[k], st[k])
                e += 0.5 * wds[i] * (v0 + vv) * d
                out[b, i, k] = x1
        lost[b] = e


class MomentumMaps:
    """The three momentum maps of a learned rod as arrays: component k linear with slope
    ``stiffness[k]``, or a table (knots xs[off[k]:off[k+1]], values ys there)."""

    def __init__(self, maps: Sequence[float | tuple[np.ndarray, np.ndarray]]):
        if len(maps) != 3:
            raise ValueError(f"three momentum maps expected, got {len(maps)}")
        xs, ys, off = [], [], [0]
        self.linear = np.zeros(3, dtype=np.bool_)
        self.stiffness = np.zeros(3)
        for k, m in enumerate(maps):
            if isinstance(m, tuple):
                x, y = (np.asarray(v, dtype=float) for v in m)
                if x.ndim != 1 or x.shape != y.shape or x.size < 2 or np.any(np.diff(x) <= 0):
                    raise ValueError(f"momentum map {k}: a table needs two or more increasing knots")
                xs.append(x)
                ys.append(y)
                off.append(off[-1] + x.size)
            else:
                self.linear[k], self.stiffness[k] = True, float(m)
                off.append(off[-1])
        self.xs = np.concatenate(xs) if xs else np.zeros(1)
        self.ys = np.concatenate(ys) if ys else np.zeros(1)
        self.offsets = np.asarray(off, dtype=np.int64)

    @classmethod
    def of(cls, components: Sequence[Any]) -> MomentumMaps | None:
        """The maps of components that are each linear (``stiffness`` and ``slope``, a nominal
        law) or a ``Table1D`` (``tx``, ``ty``); None where any is neither (a kernel sum, a
        sample set)."""
        maps: list[float | tuple[np.ndarray, np.ndarray]] = []
        for c in components:
            if hasattr(c, "tx") and hasattr(c, "ty") and getattr(c, "dim", 1) == 1:
                maps.append((c.tx, c.ty))
            elif getattr(c, "col", 0) is None and hasattr(c, "stiffness"):
                maps.append(float(c.stiffness))
            else:
                return None
        return cls(maps)

    def _args(self) -> tuple[Any, ...]:
        return self.xs, self.ys, self.offsets, self.linear, self.stiffness

    def velocity(self, p: np.ndarray) -> np.ndarray:
        """H_p(p) (..., n, 3) componentwise."""
        p = np.asarray(p, dtype=float)
        p2 = np.ascontiguousarray(p.reshape(-1, *p.shape[-2:]))
        out = np.empty_like(p2)
        _velocity(p2, *self._args(), out)
        return out.reshape(p.shape)

    def damping(self, free: np.ndarray, zeta: float, h: float, wds: np.ndarray
                ) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """p -> (p after the damping half-step of length h on the entries ``free`` marks, energy
        removed per rod): ``run_hamiltonian``'s generic step for these maps."""
        fr = np.ascontiguousarray(np.asarray(free, dtype=float))
        w = np.ascontiguousarray(np.asarray(wds, dtype=float))
        args = self._args()

        def damp(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            p2 = np.ascontiguousarray(p.reshape(-1, *p.shape[-2:]), dtype=float)
            out, lost = np.empty_like(p2), np.empty(p2.shape[0])
            _damp(p2, *args, fr, float(zeta), float(h), w, out, lost)
            return out.reshape(p.shape), lost.reshape(p.shape[:-2])
        return damp


__all__ = ["MomentumMaps"]
