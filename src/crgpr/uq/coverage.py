"""Coverage of the ground truth by the sampled-trajectory bands, at several nominal levels
(paper Sec. V, "Uncertainty Quantification Results"; the paper shows a 95 % band of S = 10).

Band of nominal level L (%) from S sampled trajectories: the (50 - L/2, 50 + L/2) percentiles
over the samples (numpy's linear interpolation) at every (t, node). ``theta_coverage``: the
fraction of ground-truth theta values inside it over t > 0 and nodes 1..N (the clamped base and
t = 0 are identical in every run); ``tip_coverage``: tip x and y both inside their bands.

The reference ``expected_coverage``. With S samples the interpolated percentile band is not
an L % interval: if the truth were an (S+1)-th draw of the same distribution it would lie
inside with probability e(S, L) < L (0.79 for S = 10 and L = 95: the 2.5 / 97.5 % percentiles
of 10 samples lie just inside the sample range, and even the range holds an 11th draw only
with probability 9 / 11). A calibrated model therefore reaches e(S, L), not L; the table gives
both. e -> L / 100 as S grows.

Monte Carlo error. For a calibrated model the probability mass inside the band at one point is
Beta-distributed with variance e (1 - e) / (S + 2) (order statistics of S uniform draws); the
coverage averages such points, correlated along the trajectory, so sqrt(e (1 - e) / (S + 2))
bounds its Monte Carlo standard error (``mc_se_bound``). ``mc_se`` is the measured one: the
spread of the coverage over ``K`` disjoint sub-ensembles, scaled from S / K to S samples by
the same 1 / (S + 2) law.

The spread of ONE truth (``calibrated_coverage_sd``, ``calibrated_fraction_at_least``). The
Monte Carlo error above is that of the S samples only. But the ground truth is one
realisation: if the model is calibrated, the truth's trajectory is one more draw of the law's
error, the same draw at every time, node and angle (one fitted law is integrated at every
angle), so the coverage of that one truth scatters around e(S, L) far more than mc_se says,
and averaging over the angles does not shrink that scatter. It is measured leave-one-out: each
sample s in turn is the 'truth', covered by the band of the other S - 1 (the coverage a
calibrated model shows for a truth that is exactly such a draw, reference e(S - 1, L));
``calibrated_coverage_sd`` is their sd over s, ``calibrated_fraction_at_least`` the fraction of
them >= the ground truth's coverage (a one-sided calibration p-value with resolution 1 / S:
near 0 the band is too wide, near 1 too narrow). In the mean over the angles the same sample s
is the truth at every angle (samples matched by id), so both describe the angle-mean coverage.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache
from typing import Any

import numpy as np
import pandas as pd

from crgpr.uq.settings import band_percentiles

COVERAGE_COLUMNS: tuple[str, ...] = (
    "method", "theta0_deg", "n_samples", "level", "theta_coverage", "expected_coverage",
    "theta_coverage_minus_expected", "mc_se", "mc_se_bound", "tip_coverage", "tip_x_coverage",
    "tip_y_coverage", "theta_band_width_mean", "tip_band_width_mean", "theta_rmse_median",
    "theta_rmse_mean_model", "calibrated_coverage_sd", "calibrated_fraction_at_least", "n_diverged",
)
N_SUBSETS = 4  # K disjoint sub-ensembles for the measured Monte Carlo error


@cache
def expected_coverage(n_samples: int, level: float, n_mc: int = 200_000) -> float:
    """e(S, L): probability that an (S+1)-th draw lies inside the interpolated percentile band
    of level L (%) of S draws of the same continuous distribution. Monte Carlo with Gaussian
    draws, fixed seed, ``n_mc`` replications (standard error <= 0.0011); the dependence on the
    distribution enters only through the linear interpolation between neighbouring order
    statistics (uniform draws give (S - 1) L / 100 / (S + 1) exactly: 0.777 for S = 10, L = 95,
    against 0.790 for Gaussian draws)."""
    lo, hi = band_percentiles(level)
    S = n_samples
    rng = np.random.default_rng(0)
    # numpy's linear percentile p of S sorted draws: position h = p / 100 (S - 1), interpolated
    # between the order statistics floor(h) and floor(h) + 1 (0-based)
    pos = [p / 100.0 * (S - 1) for p in (lo, hi)]
    ks = sorted({int(np.floor(h)) for h in pos} | {min(int(np.floor(h)) + 1, S - 1) for h in pos})
    hits = 0
    for n in (n_mc // 8,) * 8:  # blocks keep the memory bounded
        x = rng.standard_normal((n, S + 1))
        part = np.partition(x[:, :S], ks, axis=1)
        q = []
        for h in pos:
            k = int(np.floor(h))
            k1 = min(k + 1, S - 1)
            q.append(part[:, k] + (h - k) * (part[:, k1] - part[:, k]))
        hits += int(np.sum((x[:, -1] >= q[0]) & (x[:, -1] <= q[1])))
    return hits / (8 * (n_mc // 8))


def sample_arrays(df: pd.DataFrame, cols: Sequence[str]) -> np.ndarray:
    """(S, n_t, n_nodes, len(cols)) from a UQ table (rows of the full (sample, t, node) grid)."""
    df = df.sort_values(["sample", "t", "node"])
    S, n_t, n_nodes = df["sample"].nunique(), df["t"].nunique(), df["node"].nunique()
    if len(df) != S * n_t * n_nodes:
        raise ValueError(f"UQ table has {len(df)} rows, expected S x n_t x n_nodes = {S} x {n_t} x {n_nodes}")
    return df[list(cols)].to_numpy(dtype=float).reshape(S, n_t, n_nodes, len(cols))


def truth_arrays(gt: pd.DataFrame, t: np.ndarray, cols: Sequence[str]) -> np.ndarray:
    """Ground truth (n_t, n_nodes, len(cols)) at the UQ record times ``t`` (a subset of its grid)."""
    gt = gt.sort_values(["t", "node"])
    t_gt = np.sort(gt["t"].unique())
    idx = np.searchsorted(t_gt, t - 1e-9)
    if np.any(idx >= t_gt.size) or not np.allclose(t_gt[np.minimum(idx, t_gt.size - 1)], t, atol=1e-9):
        raise ValueError("the UQ record times are not on the ground-truth time grid")
    n_nodes = gt["node"].nunique()
    g = gt[list(cols)].to_numpy(dtype=float).reshape(t_gt.size, n_nodes, len(cols))
    return g[idx]


def _coverages(arr: np.ndarray, g: np.ndarray, level: float) -> dict[str, float]:
    """Coverage numbers of one band (arr: (S, n_t, n_nodes, 3) = x, y, theta)."""
    lo, hi = band_percentiles(level)
    qlo, qmed, qhi = np.percentile(arr, [lo, 50.0, hi], axis=0)
    inside = (g >= qlo) & (g <= qhi)
    tip_x, tip_y = inside[1:, -1, 0], inside[1:, -1, 1]
    err_med = qmed[..., 2] - g[..., 2]
    return {
        "theta_coverage": float(inside[1:, 1:, 2].mean()),
        "tip_coverage": float((tip_x & tip_y).mean()),
        "tip_x_coverage": float(tip_x.mean()), "tip_y_coverage": float(tip_y.mean()),
        "theta_band_width_mean": float((qhi[1:, 1:, 2] - qlo[1:, 1:, 2]).mean()),
        "tip_band_width_mean": float(np.hypot(qhi[1:, -1, 0] - qlo[1:, -1, 0],
                                              qhi[1:, -1, 1] - qlo[1:, -1, 1]).mean()),
        "theta_rmse_median": float(np.sqrt(np.mean(err_med[:, 1:] ** 2))),
    }


def loo_coverages(arr: np.ndarray, level: float) -> np.ndarray:
    """(S,) theta coverage of sample s by the band of the other S - 1 samples (arr: (S, n_t,
    n_nodes, 3)): the coverage of a truth that is itself a draw of the sampled law."""
    lo, hi = band_percentiles(level)
    th = arr[:, 1:, 1:, 2]
    out = np.empty(th.shape[0])
    for s in range(th.shape[0]):
        qlo, qhi = np.percentile(np.delete(th, s, axis=0), [lo, hi], axis=0)
        out[s] = np.mean((th[s] >= qlo) & (th[s] <= qhi))
    return out


def coverage_rows(arr: np.ndarray, g: np.ndarray, levels: Sequence[float], sizes: Sequence[int],
                  mean_model: np.ndarray | None = None) -> list[dict[str, Any]]:
    """Rows (one per S used and level) for one method and angle.

    ``arr`` (S, n_t, n_nodes, 3) sampled x, y, theta in sample order; ``g`` (n_t, n_nodes, 3) the
    truth; ``sizes``: the S values to report (the first S samples each); ``mean_model``
    (n_t, n_nodes, 3): the mean-model rollout for ``theta_rmse_mean_model``. Each row also holds
    ``loo`` (S,), the leave-one-out coverages (``loo_coverages``), for ``summary_rows``.
    """
    rows = []
    rmse_mean = (float(np.sqrt(np.mean((mean_model[:, 1:, 2] - g[:, 1:, 2]) ** 2)))
                 if mean_model is not None else float("nan"))
    for S in sizes:
        if S > arr.shape[0]:
            raise ValueError(f"{S} samples requested, {arr.shape[0]} available")
        sub = arr[:S]
        for level in levels:
            e = expected_coverage(S, level)
            row = {"n_samples": int(S), "level": float(level), **_coverages(sub, g, level),
                   "expected_coverage": e, "mc_se_bound": float(np.sqrt(e * (1 - e) / (S + 2))),
                   "theta_rmse_mean_model": rmse_mean}
            row["theta_coverage_minus_expected"] = row["theta_coverage"] - e
            loo = loo_coverages(sub, level)
            row["loo"] = loo
            row["calibrated_coverage_sd"] = float(np.std(loo, ddof=1))
            row["calibrated_fraction_at_least"] = float(np.mean(loo >= row["theta_coverage"]))
            k = S // N_SUBSETS
            if k >= 2:
                parts = [_coverages(sub[j * k:(j + 1) * k], g, level)["theta_coverage"]
                         - expected_coverage(k, level) for j in range(N_SUBSETS)]
                row["mc_se"] = float(np.std(parts, ddof=1) * np.sqrt((k + 2) / (S + 2)))
            else:
                row["mc_se"] = float("nan")
            rows.append(row)
    return rows


def summary_rows(df: pd.DataFrame, loo: dict[tuple[str, int, float], list[dict[int, float]]] | None = None
                 ) -> pd.DataFrame:
    """Mean over the angles per (method, n_samples, level); ``theta0_deg`` is NaN there and the
    Monte Carlo errors are combined as for fully correlated angles (the same samples drive every
    angle), i.e. averaged, an upper bound. ``loo``: per key, one {sample id: leave-one-out
    coverage} per angle; the one-truth columns are then those of the angle-mean coverage of the
    same sample (ids present at every angle), else NaN."""
    keys = ["method", "n_samples", "level"]
    mean = df.groupby(keys, sort=False).mean(numeric_only=True).reset_index()
    mean["theta0_deg"] = np.nan
    mean["calibrated_coverage_sd"] = np.nan
    mean["calibrated_fraction_at_least"] = np.nan
    for i, r in mean.iterrows():
        per_angle = (loo or {}).get((r["method"], int(r["n_samples"]), float(r["level"])))
        if not per_angle:
            continue
        ids = sorted(set.intersection(*(set(a) for a in per_angle)))
        if len(ids) < 2:
            continue
        m = np.array([np.mean([a[s] for a in per_angle]) for s in ids])
        mean.loc[i, "calibrated_coverage_sd"] = float(np.std(m, ddof=1))
        mean.loc[i, "calibrated_fraction_at_least"] = float(np.mean(m >= r["theta_coverage"]))
    return mean[list(df.columns)]
