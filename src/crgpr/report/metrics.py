"""Accuracy metrics of any rollout method against ground truth (paper Sec. V, "Baseline Comparisons").

Definitions (global over the N free nodes 1..N and all recorded time samples):
    RMSE(theta)     = sqrt(mean(eps_theta^2))
    R^2(theta)      = 1 - sum eps_theta^2 / sum (theta - mean(theta))^2   (ground-truth mean)
    RMSE_tip / L    = sqrt(mean(|e_tip|^2)) / L0,  e_tip the Euclidean tip-position error
    Group-nRMSE     = mean over the six groups g in (x, y, theta, p_x, p_y, p_theta) of
                      sqrt(mean(eps_g^2)) / range(z_g),  range over the ground truth.
``accuracy.parquet`` has one row per (method, theta0_deg) with columns ``ACCURACY_COLUMNS``;
``diverged`` / ``t_diverged`` come from the rollout's metadata (a diverged learned rollout is
scored frozen after its last plausible record: ``learning.learned.run_rollout``).
The functions are generic in the method name, so baselines and UQ reuse them.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.io import frame_to_grid, read_metadata, read_parquet
from crgpr.physics.rod import STATE_NAMES
from crgpr.physics.simulate import TRAJECTORY_COLUMNS

log = logging.getLogger(__name__)

ACCURACY_COLUMNS: tuple[str, ...] = ("method", "theta0_deg", "rmse_theta", "r2_theta", "tip_rmse_over_L",
                                     "group_nrmse", "diverged", "t_diverged")
PAPER_TABLE1 = {"rmse_theta": {60: 0.316, 125: 0.244, 160: 0.224, 180: 0.210, 225: 0.144, 325: 0.193,
                               "mean": 0.222},
                "r2_theta": {60: 0.924, 125: 0.951, 160: 0.934, 180: 0.928, 225: 0.900, 325: 0.876,
                             "mean": 0.919}}
PAPER_TABLE4 = {"two-step (GP dz/dt)": {"rmse_theta": 0.2218, "tip_rmse_over_L": 0.1278,
                                        "group_nrmse": 0.0540,
                                        "r2_theta": 0.9186},
                "single-step (FD dz/dt)": {"rmse_theta": 0.2107, "tip_rmse_over_L": 0.1248,
                                           "group_nrmse": 0.0530, "r2_theta": 0.9840}}


def _grid(df: pd.DataFrame, path: str) -> tuple[np.ndarray, np.ndarray]:
    return frame_to_grid(df, STATE_NAMES, path)


def accuracy(gt: pd.DataFrame, pred: pd.DataFrame, L0: float, gt_name: str = "ground truth",
             pred_name: str = "rollout") -> dict[str, float]:
    """The four metrics of one rollout (see module docstring); interpolates pred onto gt times if needed."""
    tg, zg = _grid(gt, gt_name)
    tp, zp = _grid(pred, pred_name)
    if zg.shape[1] != zp.shape[1]:
        raise ValueError(f"{pred_name}: {zp.shape[1]} nodes, ground truth has {zg.shape[1]}")
    if tp.shape != tg.shape or not np.allclose(tp, tg, atol=1e-9):
        if tp[0] > tg[0] + 1e-9 or tp[-1] < tg[-1] - 1e-9:
            raise ValueError(f"{pred_name}: covers t in [{tp[0]:g}, {tp[-1]:g}] s, ground truth "
                             f"[{tg[0]:g}, {tg[-1]:g}] s")
        zp = np.stack([np.stack([np.interp(tg, tp, zp[:, i, k]) for k in range(6)], -1)
                       for i in range(zp.shape[1])], 1)
    if not np.all(np.isfinite(zp)):
        raise ValueError(f"{pred_name}: non-finite states")
    g, p = zg[:, 1:], zp[:, 1:]  # free nodes 1..N
    e = p - g
    th = g[..., 2]
    rmse_theta = float(np.sqrt(np.mean(e[..., 2] ** 2)))
    r2 = float(1.0 - np.sum(e[..., 2] ** 2) / np.sum((th - th.mean()) ** 2))
    tip = float(np.sqrt(np.mean(np.sum(e[:, -1, :2] ** 2, axis=-1))) / L0)
    ranges = g.reshape(-1, 6).max(0) - g.reshape(-1, 6).min(0)
    rms = np.sqrt(np.mean(e.reshape(-1, 6) ** 2, axis=0))
    gn = float(np.mean(rms / np.where(ranges > 0, ranges, np.nan)))
    return {"rmse_theta": rmse_theta, "r2_theta": r2, "tip_rmse_over_L": tip, "group_nrmse": gn}


def accuracy_table(pairs: list[tuple[str, float, str, str]], L0: float) -> pd.DataFrame:
    """Rows for (method, angle, ground-truth path, rollout path) tuples; missing rollouts are skipped."""
    rows = []
    for method, angle, gt_path, pred_path in pairs:
        if not Path(pred_path).exists():
            log.warning("no rollout %s; skipped", pred_path)
            continue
        gt = read_parquet(gt_path, required=TRAJECTORY_COLUMNS)
        pred = read_parquet(pred_path, required=("t", "node", *STATE_NAMES))
        meta = read_metadata(pred_path)
        rows.append({"method": method, "theta0_deg": float(angle),
                     **accuracy(gt, pred, L0, str(gt_path), str(pred_path)),
                     "diverged": bool(meta.get("diverged", False)),
                     "t_diverged": float(meta["t_diverged"]) if meta.get("diverged") else math.nan})
    return pd.DataFrame(rows, columns=list(ACCURACY_COLUMNS))


def table1(acc: pd.DataFrame, method: str, angles: list[int]) -> pd.DataFrame:
    """Table III (file table1_accuracy.csv): RMSE(theta) and R^2 per angle and mean, paper beside ours."""
    sel = acc[acc["method"] == method].set_index("theta0_deg")
    rows = []
    for metric in ("rmse_theta", "r2_theta"):
        for source in ("paper", "ours"):
            row: dict[str, Any] = {"metric": metric, "source": source if source == "paper" else method}
            vals = []
            for a in angles:
                v = PAPER_TABLE1[metric].get(a, np.nan) if source == "paper" else (
                    float(sel.loc[float(a), metric]) if float(a) in sel.index else np.nan)
                row[f"{a}"] = v
                vals.append(v)
            row["mean"] = PAPER_TABLE1[metric]["mean"] if source == "paper" else float(np.mean(vals))
            rows.append(row)
    return pd.DataFrame(rows)


def table4(acc: pd.DataFrame, methods: list[str]) -> pd.DataFrame:
    """Table V (ablation): metrics averaged over the test angles per pipeline, paper beside ours."""
    labels = list(PAPER_TABLE4)
    rows = []
    for i, m in enumerate(methods):
        sel = acc[acc["method"] == m]
        label = labels[i] if i < len(labels) else m
        row: dict[str, Any] = {"pipeline": label, "method": m, "n_angles": int(len(sel))}
        for c in ("rmse_theta", "tip_rmse_over_L", "group_nrmse", "r2_theta"):
            row[c] = float(sel[c].mean()) if len(sel) else np.nan
            row[f"paper_{c}"] = PAPER_TABLE4.get(label, {}).get(c, np.nan)
        rows.append(row)
    return pd.DataFrame(rows)


def law_accuracy(mean: np.ndarray, sd: np.ndarray, truth: np.ndarray, where: np.ndarray,
                 z: float = 1.959963984540054) -> dict[str, float]:
    """A learned law against the true one on a grid (the materials study, docs/materials.md).

    ``mean``, ``sd`` (n,) or (n, J): the learned law's posterior mean and sd at n grid points (per
    segment where the law depends on s); ``truth``
    (n, J): the true law at the same points for each of J segments (its own s); ``where`` (n, J):
    the points compared. ``law_rmse`` = sqrt(mean((mean - truth)^2)) / (max truth - min truth)
    over ``where`` (the error in units of the true law's spread); ``law_band_coverage`` = the
    fraction of those points where |truth - mean| <= z sd (z = 1.96: the 95 % band). NaN for
    both if no point is compared or the true law is constant there."""
    truth = np.asarray(truth, dtype=float)
    mean = np.asarray(mean, dtype=float)
    sd = np.asarray(sd, dtype=float)
    mean, sd = (a[:, None] if a.ndim == 1 else a for a in (mean, sd))
    where = np.broadcast_to(np.asarray(where, dtype=bool), truth.shape)
    err = np.broadcast_to(mean, truth.shape)[where] - truth[where]
    if err.size == 0 or np.ptp(truth[where]) <= 0:
        return {"law_rmse": math.nan, "law_band_coverage": math.nan}
    inside = np.abs(err) <= z * np.broadcast_to(sd, truth.shape)[where]
    return {"law_rmse": float(np.sqrt(np.mean(err**2)) / np.ptp(truth[where])),
            "law_band_coverage": float(np.mean(inside))}
