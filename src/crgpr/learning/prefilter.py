"""Step 2: prefilter, the derivative data set E of eq. (12) (paper Sec. III-B, step 2).

Two methods write the same schema to ``results/prefilter/{method}/{angle}.parquet``:

``gp``  (paper Table II, state-variable GPs): for every node and state component a 1D GP in
        time with a Matern-5/2 kernel and an explicit quadratic basis [1, t, t^2] estimated
        jointly (R&W Sec. 2.7), standardised input and output, noise variance >= 1e-9
        (standardised), hyperparameters by maximising the log marginal likelihood. The GP is
        conditioned on every ``stride``-th recorded sample (4001 / 5 -> 801 points, the paper's
        "800/stride"). Hyperparameters: one set per state component, fitted by the JOINT
        marginal likelihood of a few representative nodes (``prefilter.hyper_nodes``, as
        fractions of N) on ``hyper_points`` evenly spaced samples, then shared by all nodes of
        that component (one Cholesky factor serves all 26 nodes). Posterior mean and its
        analytic first and second time derivatives are evaluated on the output grid.
``fd``  (the ablation, paper Table V): z itself and central differences in time,
        dz/dt = (z_{k+1} - z_{k-1}) / (2 dt), d2z/dt2 = (z_{k+1} - 2 z_k + z_{k-1}) / dt^2, on
        the FULL recorded data (one-sided second-order at the two ends).

Output grid: N_t' = ``prefilter.n_t_out`` times taken from the recorded samples (evenly
spaced in index) and every node (N_s' = N + 1). Spatial derivatives on the grid of the
(smoothed) nodal values: dx/ds, dy/ds central differences (second-order one-sided at the
ends), d2theta/ds2 central; at the free tip the natural boundary condition m = 0 gives
d2theta/ds2 = 2 (theta_{N-1} - theta_N) / ds^2 (half cell), at the base a one-sided stencil.
The gradient models (features.py) build their segment features from the smoothed nodal
x, y, theta in this file.

``smooth_series`` (re-exported from gp) smooths and differentiates one noisy, possibly
non-uniformly sampled time series (used by the camera-data / missing-physics workflow).
"""

from __future__ import annotations

import functools
import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.config import ConfigError
from crgpr.gp import ELL_BOUNDS_STD, fit_gp, smooth_series  # noqa: F401  (smooth_series is part of this module's API)
from crgpr.io import frame_to_grid, read_parquet
from crgpr.physics.rod import STATE_NAMES
from crgpr.physics.simulate import TRAJECTORY_COLUMNS, Trajectory

log = logging.getLogger(__name__)

METHODS: tuple[str, ...] = ("gp", "fd")
D1_COLUMNS = tuple(f"d{c}_dt" for c in STATE_NAMES)
D2_COLUMNS = tuple(f"d2{c}_dt2" for c in STATE_NAMES)
SPATIAL_COLUMNS = ("dx_ds", "dy_ds", "d2theta_ds2")
PREFILTER_COLUMNS: tuple[str, ...] = (*TRAJECTORY_COLUMNS, *D1_COLUMNS, *D2_COLUMNS, *SPATIAL_COLUMNS)


@dataclass(frozen=True)
class PrefilterSettings:
    """Section ``prefilter`` of config.yaml (see its schema for units and ranges)."""

    stride: int  # condition the state GPs on every stride-th recorded sample
    n_t_out: int  # output time grid N_t'
    kernel: str
    basis: str
    noise_var_min: float  # lower bound on the noise variance (standardised units)
    hyper_nodes: tuple[float, ...]  # fractions of N
    hyper_points: int
    n_restarts: int
    ell_min_over_spacing: float  # lengthscale >= this x the spacing of the LML samples

    @classmethod
    def from_config(cls, cfg: dict[str, Any]) -> PrefilterSettings:
        if "prefilter" not in cfg:
            raise ConfigError("config: missing section 'prefilter'")
        c = cfg["prefilter"]
        return cls(stride=int(c["stride"]), n_t_out=int(c["n_t_out"]), kernel=c["kernel"],
                   basis=c["basis"], noise_var_min=float(c["noise_var_min"]),
                   hyper_nodes=tuple(float(v) for v in c["hyper_nodes"]),
                   hyper_points=int(c["hyper_points"]), n_restarts=int(c["n_restarts"]),
                   ell_min_over_spacing=float(c["ell_min_over_spacing"]))


def output_indices(n_rec: int, n_out: int) -> np.ndarray:
    """Indices of the recorded samples forming the output grid (evenly spaced, unique)."""
    n_out = min(n_out, n_rec)
    return np.unique(np.linspace(0, n_rec - 1, n_out).round().astype(int))


def spatial_derivatives(x: np.ndarray, y: np.ndarray, theta: np.ndarray, ds: float
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """dx/ds, dy/ds, d2theta/ds2 at the nodes (last axis = node), see module docstring."""

    def d1(f: np.ndarray) -> np.ndarray:
        g = np.empty_like(f)
        g[..., 1:-1] = (f[..., 2:] - f[..., :-2]) / (2 * ds)
        g[..., 0] = (-3 * f[..., 0] + 4 * f[..., 1] - f[..., 2]) / (2 * ds)
        g[..., -1] = (3 * f[..., -1] - 4 * f[..., -2] + f[..., -3]) / (2 * ds)
        return g

    th2 = np.empty_like(theta)
    th2[..., 1:-1] = (theta[..., 2:] - 2 * theta[..., 1:-1] + theta[..., :-2]) / ds**2
    th2[..., -1] = 2.0 * (theta[..., -2] - theta[..., -1]) / ds**2
    th2[..., 0] = (2 * theta[..., 0] - 5 * theta[..., 1] + 4 * theta[..., 2] - theta[..., 3]) / ds**2
    return d1(x), d1(y), th2


def _frame(traj: Trajectory, t: np.ndarray, z: np.ndarray, d1: np.ndarray, d2: np.ndarray) -> pd.DataFrame:
    """Long table (t, node) with the PREFILTER_COLUMNS; z, d1, d2 are (n_t, N+1, 6)."""
    n_t, n_nodes, _ = z.shape
    ds = traj.params.ds
    dxs, dys, th2 = spatial_derivatives(z[..., 0], z[..., 1], z[..., 2], ds)
    cols: dict[str, np.ndarray] = {
        "theta0_deg": np.full(n_t * n_nodes, traj.theta0_deg),
        "t": np.repeat(t, n_nodes),
        "node": np.tile(np.arange(n_nodes, dtype=np.int32), n_t),
        "s": np.tile(np.arange(n_nodes) * ds, n_t),
    }
    for k, name in enumerate(STATE_NAMES):
        cols[name] = z[..., k].ravel()
    for k, name in enumerate(D1_COLUMNS):
        cols[name] = d1[..., k].ravel()
    for k, name in enumerate(D2_COLUMNS):
        cols[name] = d2[..., k].ravel()
    cols["dx_ds"], cols["dy_ds"], cols["d2theta_ds2"] = dxs.ravel(), dys.ravel(), th2.ravel()
    return pd.DataFrame(cols)


def fd_time_derivatives(z: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """First and second derivatives along axis 0 (uniform step h): central differences,
    second-order one-sided at the two ends (needs >= 3 samples; >= 4 for one-sided d2)."""
    if z.shape[0] < 3:
        raise ValueError("finite differences need at least 3 samples")
    d1 = np.empty_like(z)
    d2 = np.empty_like(z)
    d1[1:-1] = (z[2:] - z[:-2]) / (2 * h)
    d1[0] = (-3 * z[0] + 4 * z[1] - z[2]) / (2 * h)
    d1[-1] = (3 * z[-1] - 4 * z[-2] + z[-3]) / (2 * h)
    d2[1:-1] = (z[2:] - 2 * z[1:-1] + z[:-2]) / h**2
    d2[0] = (2 * z[0] - 5 * z[1] + 4 * z[2] - z[3]) / h**2 if len(z) > 3 else d2[1]
    d2[-1] = (2 * z[-1] - 5 * z[-2] + 4 * z[-3] - z[-4]) / h**2 if len(z) > 3 else d2[-2]
    return d1, d2


def fd_prefilter(traj: Trajectory, n_t_out: int) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Central finite differences in time on the full recorded data (ablation, Table V)."""
    z = traj.z
    t = traj.t
    if len(t) < 3:
        raise ValueError("fd prefilter needs at least 3 recorded samples")
    dt = np.diff(t)
    if not np.allclose(dt, dt[0], rtol=1e-6, atol=1e-12):
        raise ValueError("fd prefilter needs uniformly sampled data")
    h = float(dt[0])
    d1, d2 = fd_time_derivatives(z, h)
    idx = output_indices(len(t), n_t_out)
    meta = {"method": "fd", "dt_data_s": h, "n_t_out": int(idx.size)}
    return _frame(traj, t[idx], z[idx], d1[idx], d2[idx]), meta


def gp_prefilter(traj: Trajectory, settings: PrefilterSettings, seed: int = 0
                 ) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Matern-5/2 + quadratic-basis GP in time per node and state component (Table II)."""
    z = traj.z
    t = traj.t
    n_rec, n_nodes, _ = z.shape
    fit_idx = np.arange(0, n_rec, settings.stride)
    if fit_idx[-1] != n_rec - 1:
        fit_idx = np.append(fit_idx, n_rec - 1)
    if fit_idx.size < 8:
        raise ValueError(f"prefilter: only {fit_idx.size} samples after stride {settings.stride}; "
                         "lower prefilter.stride")
    out_idx = output_indices(n_rec, settings.n_t_out)
    t_fit, t_out = t[fit_idx], t[out_idx]
    N = n_nodes - 1
    hyper_nodes = sorted({min(N, max(1, round(f * N))) for f in settings.hyper_nodes})
    h_idx = np.unique(np.linspace(0, fit_idx.size - 1, min(settings.hyper_points, fit_idx.size))
                      .round().astype(int))
    # a lengthscale shorter than the spacing of the samples that set it is not determined by
    # them: the LML can prefer such a white-noise fit, whose derivatives are noise (80 deg,
    # p_x: 0.00058 s at 0.01 s spacing, targets 170x too large); bound it in standardised time
    t_h = t_fit[h_idx]
    ell_lo = settings.ell_min_over_spacing * float(np.median(np.diff(t_h))) / float(np.std(t_h))
    ell_bounds = (np.array([max(ell_lo, ELL_BOUNDS_STD[0])]), np.array([ELL_BOUNDS_STD[1]]))
    zs = np.empty((out_idx.size, n_nodes, 6))
    d1s = np.empty_like(zs)
    d2s = np.empty_like(zs)
    hypers: dict[str, Any] = {}
    for k, name in enumerate(STATE_NAMES):
        t0 = time.perf_counter()
        Yfit = z[fit_idx, :, k]
        # shared hyperparameters from the joint LML of the representative nodes
        # (the lengthscale bound enters only where the unconstrained optimum violates it: an
        # interior optimum is the same, the optimiser's path, and so the last digits, are not)
        hyper_fit = functools.partial(fit_gp, t_fit[h_idx], Yfit[h_idx][:, hyper_nodes],
                                      kernel=settings.kernel, basis=settings.basis,
                                      noise_var_min_std=settings.noise_var_min,
                                      n_restarts=settings.n_restarts, seed=seed + k,
                                      init={"lengthscales": 0.2, "sigma_f": 1.0, "sigma_n": 1e-3})
        hgp = hyper_fit()
        bounded = bool(hgp.lengthscales[0] < ell_bounds[0][0])
        if bounded:
            log.warning("prefilter gp %s: LML lengthscale %.3g s is below the sample spacing bound "
                        "%.3g s (prefilter.ell_min_over_spacing): refitted with the bound", name,
                        float(hgp.lengthscales[0] * hgp.x_scale[0]), float(ell_bounds[0][0] * np.std(t_h)))
            hgp = hyper_fit(ell_bounds=ell_bounds)
        fixed = {"sigma_f": hgp.sigma_f, "lengthscales": hgp.lengthscales, "sigma_n": hgp.sigma_n}
        gp = fit_gp(t_fit, Yfit, kernel=settings.kernel, basis=settings.basis,
                    noise_var_min_std=settings.noise_var_min, fixed=fixed)
        m, g1, g2 = gp.predict_derivatives(t_out)
        zs[..., k], d1s[..., k], d2s[..., k] = m, g1, g2
        hypers[name] = {"sigma_f_std": hgp.sigma_f,
                        "lengthscale_s": float(hgp.lengthscales[0] * hgp.x_scale[0]),
                        "lengthscale_std": float(hgp.lengthscales[0]), "sigma_n_std": hgp.sigma_n,
                        "lml_hyper_nodes": hgp.lml, "n_fit": int(t_fit.size), "lengthscale_bounded": bounded,
                        "hyper_nodes": hyper_nodes, "hyper_points": int(h_idx.size),
                        "seconds": time.perf_counter() - t0}
        # the clamp: base node stays exactly at its recorded value
        log.info("prefilter gp %s: lengthscale %.4g s, sigma_n %.3g (std), %.1f s", name,
                 hypers[name]["lengthscale_s"], hgp.sigma_n, hypers[name]["seconds"])
    zs[:, 0, :] = z[out_idx, 0, :]
    d1s[:, 0, :] = 0.0
    d2s[:, 0, :] = 0.0
    meta = {"method": "gp", "kernel": settings.kernel, "basis": settings.basis, "stride": settings.stride,
            "n_fit": int(t_fit.size), "n_t_out": int(out_idx.size),
            "noise_var_min_std": settings.noise_var_min,
            "lengthscale_min_s": float(ell_bounds[0][0] * np.std(t_h)),
            "hyperparameters": hypers,
            "hyperparameter_sharing": "one set per state component from the joint LML of hyper_nodes"}
    return _frame(traj, t_out, zs, d1s, d2s), meta


def prefilter(traj: Trajectory, method: str, settings: PrefilterSettings, seed: int = 0
              ) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Run one prefilter method ('gp' or 'fd') on a trajectory."""
    if method == "gp":
        return gp_prefilter(traj, settings, seed)
    if method == "fd":
        return fd_prefilter(traj, settings.n_t_out)
    raise ValueError(f"unknown prefilter method {method!r}; expected one of {METHODS}")


def read_prefiltered(path: str | Path) -> pd.DataFrame:
    """Read a prefilter Parquet file, checking its columns; sorted by (t, node)."""
    return read_parquet(path, required=PREFILTER_COLUMNS).sort_values(["t", "node"]).reset_index(drop=True)


def prefiltered_arrays(df: pd.DataFrame) -> dict[str, np.ndarray]:
    """Arrays (n_t, N+1) per column of a prefilter table, plus 't' (n_t,)."""
    cols = [c for c in PREFILTER_COLUMNS if c not in ("theta0_deg", "t", "node")]
    t, g = frame_to_grid(df, cols, "prefilter table")
    out = {c: np.ascontiguousarray(g[..., k]) for k, c in enumerate(cols)}
    out["t"] = t
    return out
