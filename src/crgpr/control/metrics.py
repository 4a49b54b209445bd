"""Closed-loop figures of merit (docs/control.md, results/tables/control.csv)."""

from __future__ import annotations

import numpy as np

from crgpr.control.closed_loop import ClosedLoop


def tip_error(run: ClosedLoop) -> np.ndarray:
    """Tip position error |p* - p| [m] at every sample."""
    return np.hypot(*(run.target[:, :2] - run.pose[:, :2]).T)


def steady_error(run: ClosedLoop, window_s: float) -> float:
    """Steady-state tip error [m]: the distance from the target of the Hann-weighted mean tip
    position over the last ``window_s`` seconds (the offset, with what still oscillates averaged
    out). A plain mean over W of a residual oscillation of period T and amplitude A is off by up
    to A T / (pi W); the Hann taper's error falls off as (T / W)^3 once W > 2 T."""
    last = run.t >= run.t[-1] - window_s
    w = np.hanning(int(last.sum()) + 2)[1:-1]
    return float(np.hypot(*(w @ (run.target[last, :2] - run.pose[last, :2])) / w.sum()))


def residual_oscillation(run: ClosedLoop, window_s: float) -> float:
    """RMS [m] of the tip position about its mean over the last ``window_s`` seconds."""
    last = run.t >= run.t[-1] - window_s
    d = run.pose[last, :2] - run.pose[last, :2].mean(axis=0)
    return float(np.sqrt(np.mean((d**2).sum(axis=1))))


def settling_time(run: ClosedLoop, band: float) -> float:
    """First time [s] after which the tip error stays within ``band`` [m] (nan if it never does)."""
    out = np.flatnonzero(tip_error(run) > band)
    if out.size == 0:
        return 0.0
    return float(run.t[out[-1] + 1]) if out[-1] + 1 < run.t.size else float("nan")


def overshoot(run: ClosedLoop) -> float:
    """Largest travel [m] of the tip past the target along the approach direction (initial tip
    to target); 0 if it never passes it."""
    d = run.target[0, :2] - run.pose[0, :2]
    n = float(np.hypot(*d))
    if n == 0.0:
        return 0.0
    past = ((run.pose[:, :2] - run.target[:, :2]) @ (d / n))
    return float(max(0.0, past.max()))


def predicted_offset(u_ff: np.ndarray, u_hold: np.ndarray, kp_force: float) -> float:
    """The steady tip offset [m] the tip spring leaves for a feedforward error: |Δu| / k_p, with
    Δu the force channels' difference between the design's u_ff and the plant's own static input
    holding its tip at the target (the spring is far stiffer than the rod at its tip)."""
    return float(np.hypot(*(np.asarray(u_ff)[:2] - np.asarray(u_hold)[:2])) / kp_force)


def peak_force(run: ClosedLoop) -> float:
    """Largest tip force magnitude |(u_x, u_y)| [N] over the run."""
    return float(np.hypot(run.u[:, 0], run.u[:, 1]).max())


def tracking_rmse(run: ClosedLoop, skip_s: float) -> float:
    """RMS tip position error [m] from ``skip_s`` on."""
    e = tip_error(run)[run.t >= skip_s]
    return float(np.sqrt(np.mean(e**2)))
