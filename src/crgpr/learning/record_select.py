"""Forward selection of the record fit's warp (``learning.record_fit``): which number of terms the
record's held-out blocks support, each candidate fitted by Levenberg-Marquardt on the record's
first part."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from crgpr.learning.lm import evaluate_all, levenberg_marquardt_batch
from crgpr.learning.record_stats import decide


def select_terms(part: Callable[[np.ndarray], np.ndarray | None],
                 full: Callable[[np.ndarray], np.ndarray | None], a0: np.ndarray, terms: list[int],
                 free_of: Callable[[int], np.ndarray], lm: tuple[int, float], n_fit: int, n_t: int,
                 blocks: int, base: np.ndarray | None = None
                 ) -> tuple[list[np.ndarray], np.ndarray, int, list[tuple[int, float, float, bool]]] | None:
    """Forward selection of the warp's number of terms among ``terms`` (ascending) on the
    held-out blocks (frames from ``n_fit`` of ``n_t``): a candidate replaces the current choice
    where it forecasts them consistently better (``decide``); the current choice is at first the
    fit ``base`` (parameters (n,), no warp: the start alone), without one the first candidate.
    Each candidate is fitted from ``a0`` on the first part, the first two side by side
    (``levenberg_marquardt_batch``: a second costs little more than one), each further one only
    where the one before it was chosen: a larger warp is offered only while the held-out blocks
    keep taking more terms (offered unconditionally, a fifth term was taken on a small held-out
    gain over three where four had not been, and forecast unseen inputs worse;
    docs/learned-laws.md).

    ``part``, ``full``: the record's residuals (``record_fit.record_residuals``) on its first
    part and on all of it; ``free_of(k)``: the free parameters with k terms; ``lm``:
    (iterations, tolerance). Returns the fits made, the residual rows (base first where given,
    then each fit; a fit whose rod left the physical range at pi), the index of the choice among
    those rows and each candidate's comparison with the choice before it (that choice's row, the
    log ratio, its standard error, taken); None where the first row left the physical range."""
    fits: list[np.ndarray] = []
    steps: list[tuple[int, float, float, bool]] = []
    res = np.empty((0, 0))
    chosen = 0

    def held(i: int) -> np.ndarray:
        return res[i].reshape(n_t, -1)[n_fit:] ** 2

    while len(fits) < len(terms):
        n = len(fits)
        batch = terms[n:n + 2] if n == 0 else terms[n:n + 1]
        new = [a for a, _ in levenberg_marquardt_batch(part, [a0] * len(batch), [free_of(k) for k in batch],
                                                        *lm)]
        rows = batch_rows(full, np.stack(([base] if n == 0 and base is not None else []) + new))
        if rows is None:
            if n == 0:
                return None
            rows = np.full((1, res.shape[1]), math.pi)
        res = rows if n == 0 else np.concatenate([res, rows])
        fits += new
        for i in range(max(len(res) - len(new), 1), len(res)):
            step = decide(held(chosen), held(i), blocks)
            steps.append((chosen, *step))
            if step[2]:
                chosen = i
        if chosen != len(res) - 1:
            break
    return fits, res.reshape(len(res), n_t, -1), chosen, steps


def batch_rows(residuals: Callable[[np.ndarray], np.ndarray | None], A: np.ndarray) -> np.ndarray | None:
    """``residuals`` of the rows of A in one batch (``evaluate_all``, one block per row); a
    diverged row's residuals set to pi (a forecast no better than any angle); None where the
    first row (the start alone) diverges."""
    out = evaluate_all(residuals, [a[None] for a in A])
    if out[0] is None:
        return None
    return np.stack([np.full_like(out[0][0], math.pi) if r is None else r[0] for r in out])


__all__ = ["batch_rows", "select_terms"]
