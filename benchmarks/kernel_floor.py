"""Benchmark: the Cholesky factorisation of a trained GP's kernel matrix, with and without a
kernel floor (off-diagonal entries below ``KERNEL_FLOOR`` noise2 / n stored as 0, as the
library's kernel fills do: docs/performance.md, "Subnormal numbers"), on one core.

    python benchmarks/kernel_floor.py [--model results/models/fd/dH_dtheta] [--n 12000] [--csv F]

``--model``: a gradient GP of a complete run (its .npz and .json: training inputs,
hyperparameters); its first n training inputs are used. Without the floor, far-apart inputs
give kernel entries that underflow to subnormal numbers, and the factorisation's arithmetic on
them runs many times slower. Prints (and with ``--csv`` writes) the seconds of each
factorisation, the fraction of stored zeros and the largest change of K^-1 v against the
unfloored solve, relative to its largest entry.
"""

from __future__ import annotations

import argparse
import csv
import time

import numpy as np
import scipy.linalg as sla
from threadpoolctl import threadpool_limits

from crgpr.gp import GP, kernel_matrix
from crgpr.gp._gpr import KERNEL_FLOOR


def _factor_seconds(K: np.ndarray) -> tuple[np.ndarray, float]:
    t0 = time.perf_counter()
    L = sla.cholesky(K, lower=True, overwrite_a=True, check_finite=False)
    return L, time.perf_counter() - t0


def _lower_fraction(K: np.ndarray, pred) -> float:
    """Fraction of the strictly lower triangle's entries where ``pred`` holds (row blocks)."""
    n, hits = K.shape[0], 0
    for i0 in range(0, n, 1000):
        rows = K[i0:i0 + 1000]
        mask = np.tril(np.ones(rows.shape, dtype=bool), k=i0 - 1)
        hits += int(np.count_nonzero(pred(rows) & mask))
    return hits / (n * (n - 1) / 2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", default="results/models/fd/dH_dtheta")
    ap.add_argument("--n", type=int, default=12000)
    ap.add_argument("--csv", default=None)
    args = ap.parse_args()
    threadpool_limits(1)  # as in every rule (threads: 1)
    gp = GP.load(args.model)
    n = min(args.n, gp.n)
    v = np.ravel(gp.y)[:n]
    sn2 = gp.sigma_n**2
    K = np.empty((n, n), order="F")
    for i0 in range(0, n, 2000):  # the kernel matrix (numpy kernel), noise on the diagonal
        i1 = min(i0 + 2000, n)
        K[i0:i1, :] = kernel_matrix(gp.kernel, gp.Xs[i0:i1], gp.Xs[:n], gp.sigma_f, gp.ell)
    K[np.diag_indices(n)] += sn2
    tiny = _lower_fraction(K, lambda r: (r > 0.0) & (r < np.finfo(float).tiny))
    Kf = K.copy(order="F")
    Kf[Kf < KERNEL_FLOOR * sn2 / n] = 0.0  # the diagonal is >= sn2: untouched
    zeros = _lower_fraction(Kf, lambda r: r == 0.0)
    L, t_floor = _factor_seconds(Kf)
    a_floor = sla.cho_solve((L, True), v, check_finite=False)
    del Kf, L
    L, t_plain = _factor_seconds(K)
    a_plain = sla.cho_solve((L, True), v, check_finite=False)
    rel = float(np.max(np.abs(a_floor - a_plain)) / np.max(np.abs(a_plain)))
    row = {"model": args.model, "n": n,
           "seconds_no_floor": round(t_plain, 2), "seconds_floor": round(t_floor, 2),
           "subnormal_fraction_no_floor": round(tiny, 4), "zero_fraction_floor": round(zeros, 4),
           "max_rel_change_of_solve": f"{rel:.2e}"}
    print(row)
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(row))
            w.writeheader()
            w.writerow(row)


if __name__ == "__main__":
    main()
