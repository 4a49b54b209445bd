"""Levenberg-Marquardt on residuals that come from batched rollouts (``learning.record_fit``).

Every evaluation of the residual function takes rows of parameters (B, n) and returns residuals
(B, m), or None where a rod of the batch left the physical range; a point and its forward-difference
perturbations are one call (the Jacobian by forward differences of step ``FD_STEP``), and several
problems on the same residual function share the calls (``levenberg_marquardt_batch``): a learned
rollout's cost is mostly per time step, not per rod.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

FD_STEP = 1e-3  # forward-difference step of every parameter (warp: relative stiffness; start: rad, rad/s)
MAX_DIVERGED = 8  # trials of one problem that may leave the physical range (lambda x10 each) before it stops


def levenberg_marquardt(residuals: Callable[[np.ndarray], np.ndarray | None], a0: np.ndarray,
                        free: np.ndarray, iterations: int, tolerance: float,
                        final: dict[str, np.ndarray] | None = None) -> tuple[np.ndarray, float]:
    """Minimise mean(r^2) over the parameters where ``free`` (bool, like a0), the others held at
    a0: Levenberg-Marquardt with forward-difference Jacobians, each evaluation (a point and its
    perturbations) one call of ``residuals``. Returns (parameters, RMS residual); the start's
    RMS is inf where the first evaluation diverges. ``final`` (a dict) receives the residuals
    ``r`` and the Jacobian ``J`` (columns: the free parameters) at the returned point. One
    problem of ``levenberg_marquardt_batch``."""
    (a, rms), = levenberg_marquardt_batch(residuals, [a0], [free], iterations, tolerance,
                                          None if final is None else [final])
    return a, rms


class _Problem:
    """The state of one problem of ``levenberg_marquardt_batch``."""

    def __init__(self, a0: np.ndarray, free: np.ndarray):
        self.a = np.asarray(a0, dtype=float).copy()
        self.idx = np.flatnonzero(free)
        self.r = self.J = self.trial = None
        self.cost, self.lam, self.it, self.tries, self.done = math.inf, 1e-3, 0, 0, False
        self.diverged = 0  # trials that left the physical range

    def rows(self, point: np.ndarray) -> np.ndarray:
        """The point and its forward-difference perturbations (1 + free parameters rows)."""
        A = np.repeat(point[None], self.idx.size + 1, axis=0)
        A[1 + np.arange(self.idx.size), self.idx] += FD_STEP
        return A

    def converged(self, tolerance: float) -> bool:
        """Whether the Gauss-Newton step at the current point, the linear model's best, would lower
        the cost by less than ``tolerance`` of it: the fit has nothing left to gain (unlike a short,
        damped step that gains little far from the optimum)."""
        step = np.linalg.lstsq(self.J, -self.r, rcond=None)[0]
        predicted = float(np.sum(self.r**2) - np.sum((self.r + self.J @ step) ** 2))
        return predicted < tolerance * float(np.sum(self.r**2))

    def propose(self) -> np.ndarray:
        JTJ, g = self.J.T @ self.J, self.J.T @ self.r
        step = np.linalg.solve(JTJ + self.lam * np.diag(np.diag(JTJ) + 1e-12), -g)
        self.trial = self.a.copy()
        self.trial[self.idx] += step
        return self.rows(self.trial)


def evaluate_all(residuals: Callable[[np.ndarray], np.ndarray | None], blocks: list[np.ndarray]
                  ) -> list[np.ndarray | None]:
    """``residuals`` of each block of rows, all in one call; where a rod leaves the physical range,
    block by block (a block with a diverged rod gives None)."""
    if not blocks:
        return []
    R = residuals(np.concatenate(blocks))
    if R is None:
        return [residuals(b) for b in blocks] if len(blocks) > 1 else [None]
    return np.split(R, np.cumsum([b.shape[0] for b in blocks])[:-1])


def levenberg_marquardt_batch(residuals: Callable[[np.ndarray], np.ndarray | None],
                              starts: list[np.ndarray], frees: list[np.ndarray], iterations: int,
                              tolerance: float, finals: list[dict[str, np.ndarray]] | None = None
                              ) -> list[tuple[np.ndarray, float]]:
    """``levenberg_marquardt`` of several problems on the same residual function, each problem's
    points and Jacobian perturbations evaluated together in one call per round (a rollout's
    cost is mostly per time step, not per rod: problems fitted side by side cost little more
    than one). Each problem takes the steps it would take alone: per iteration up to four trial
    damping factors lambda (x10 after a trial that does not lower the cost), /3 after an accepted
    step; a trial that leaves the physical range is refused too (lambda x10) but counts apart,
    up to ``MAX_DIVERGED`` in all (far from the fit, a long step can throw the rod out of range
    where a shorter one lowers the cost). It stops at convergence, where the Gauss-Newton step at
    the current point predicts a gain below ``tolerance`` of the cost (``_Problem.converged``),
    or after ``iterations`` accepted steps (the cap of a fit that starts far from its optimum),
    four refused trials in a row or ``MAX_DIVERGED`` diverged ones. Returns (parameters, RMS
    residual) per problem."""
    probs = [_Problem(a0, f) for a0, f in zip(starts, frees, strict=True)]
    active = [p for p in probs if p.idx.size]
    for p in probs:
        if not p.idx.size:  # nothing to fit: one evaluation
            r = residuals(p.a[None])
            p.cost = math.inf if r is None else float(np.mean(r**2))
            p.done = True
    for p, ev in zip(active, evaluate_all(residuals, [p.rows(p.a) for p in active]), strict=True):
        if ev is None:
            p.done = True
        else:
            p.r, p.J = ev[0], ((ev[1:] - ev[0]) / FD_STEP).T
            p.cost = float(np.mean(p.r**2))
            p.done = iterations <= 0 or p.converged(tolerance)
    while True:
        live = [p for p in active if not p.done]
        if not live:
            break
        for p, ev in zip(live, evaluate_all(residuals, [p.propose() for p in live]), strict=True):
            new = math.inf if ev is None else float(np.mean(ev[0] ** 2))
            if new < p.cost:
                p.a, p.r, p.J = p.trial, ev[0], ((ev[1:] - ev[0]) / FD_STEP).T
                p.cost, p.lam, p.it, p.tries = new, p.lam / 3.0, p.it + 1, 0
                p.done = p.it >= iterations or p.converged(tolerance)
            elif ev is None:  # the trial left the physical range: a shorter step, up to MAX_DIVERGED times
                p.lam, p.diverged = p.lam * 10.0, p.diverged + 1
                p.done = p.diverged >= MAX_DIVERGED
            else:
                p.lam, p.tries = p.lam * 10.0, p.tries + 1
                p.done = p.tries >= 4
    for k, p in enumerate(probs):
        if finals is not None and p.J is not None:
            finals[k].update(r=p.r, J=p.J)
    return [(p.a, math.sqrt(p.cost)) for p in probs]


__all__ = ["FD_STEP", "evaluate_all", "levenberg_marquardt", "levenberg_marquardt_batch"]
