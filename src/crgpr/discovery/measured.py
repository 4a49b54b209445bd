"""Measured (camera) rod data: loading, validation, angles from positions, GP smoothing.

A measured file is Parquet with one row per (t, node): ``t`` [s], ``node`` (0 = base,
s = node * ds), ``x``, ``y`` [m] and optionally ``theta`` [rad]. Following the paper's
Remark in Sec. III-B, theta is derived from positions and the momenta from the known mass
distribution: segment angles phi_j = atan2(y_{j+1} - y_j, x_{j+1} - x_j) (unwrapped in time
and along s) are the mid-segment angles theta_bar_j of ``rod.py``; nodal angles are their
averages theta_i = (phi_{i-1} + phi_i) / 2 in the interior and the linear extrapolations
theta_0 = (3 phi_0 - phi_1) / 2, theta_N = (3 phi_{N-1} - phi_{N-2}) / 2 at the ends.
Positions are smoothed and differentiated per node with the project's GP prefilter
(``crgpr.gp.smooth_series``: Matern-5/2 GP with a quadratic basis, analytic derivatives);
angle rates follow analytically from the smoothed position derivatives.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.io import read_parquet

REQUIRED_COLUMNS: tuple[str, ...] = ("t", "node", "x", "y")


class MeasuredDataError(ValueError):
    """The measured data file is unusable; the message names the file and the problem."""


@dataclass
class Measured:
    """Positions on a uniform time grid: t (n_t,), x, y (n_t, N+1); theta optional."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray | None
    source: str

    @property
    def n_segments(self) -> int:
        return self.x.shape[1] - 1

    @property
    def dt(self) -> float:
        return float(np.median(np.diff(self.t)))

    @property
    def rate_hz(self) -> float:
        return 1.0 / self.dt


@dataclass
class Kinematics:
    """Smoothed configuration q, velocity v, acceleration a: (n_t, N+1, 3) = (x, y, theta)."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    noise_std_m: float  # GP noise level of the positions (mean over nodes) [m]
    base_segment_angle: np.ndarray | None = None  # phi_0(t), smoothed in time only [rad]


def validate_frame(df: pd.DataFrame, source: str, min_rate_hz: float = 200.0,
                   min_samples: int = 20, rel_dt_tol: float = 1.0e-3) -> Measured:
    """Check a measured table and reshape it to a (t, node) grid; raise MeasuredDataError."""
    missing = [c for c in REQUIRED_COLUMNS if c not in df.columns]
    if missing:
        raise MeasuredDataError(f"{source}: missing column(s) {missing}; has {list(df.columns)}")
    cols = list(REQUIRED_COLUMNS) + (["theta"] if "theta" in df.columns else [])
    for c in cols:
        vals = pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(vals)
        if bad.any():
            raise MeasuredDataError(f"{source}: column {c!r} has {int(bad.sum())} NaN/non-finite or "
                                    f"non-numeric value(s) (first at row {int(np.argmax(bad))})")
    node = df["node"].to_numpy(dtype=float)
    if np.any(node != np.round(node)) or node.min() < 0:
        raise MeasuredDataError(f"{source}: column 'node' must hold non-negative integers")
    node = node.astype(int)
    n_nodes = int(node.max()) + 1
    if n_nodes < 4:
        raise MeasuredDataError(f"{source}: need at least 4 nodes (3 segments), got {n_nodes}")
    present = np.unique(node)
    if present.size != n_nodes:
        gaps = sorted(set(range(n_nodes)) - set(present.tolist()))[:5]
        raise MeasuredDataError(f"{source}: nodes must be 0..{n_nodes - 1} without gaps; missing {gaps}")
    t = df["t"].to_numpy(dtype=float)
    for i in range(n_nodes):
        ti = t[node == i]
        d = np.diff(ti)
        if np.any(d <= 0):
            k = int(np.argmax(d <= 0))
            raise MeasuredDataError(f"{source}: time is not strictly increasing for node {i} "
                                    f"(t = {ti[k]:.6g} s followed by {ti[k + 1]:.6g} s)")
    times = np.unique(t)
    counts = np.bincount(node, minlength=n_nodes)
    if np.any(counts != times.size):
        i = int(np.argmax(counts != times.size))
        raise MeasuredDataError(f"{source}: node {i} has {counts[i]} samples but there are "
                                f"{times.size} distinct times; every node needs every time")
    if times.size < min_samples:
        raise MeasuredDataError(f"{source}: only {times.size} time samples; need at least {min_samples}")
    dts = np.diff(times)
    dt = float(np.median(dts))
    if np.max(np.abs(dts - dt)) > rel_dt_tol * dt:
        k = int(np.argmax(np.abs(dts - dt)))
        raise MeasuredDataError(f"{source}: uneven time sampling: step {dts[k]:.6g} s at "
                                f"t = {times[k]:.6g} s "
                                f"vs median {dt:.6g} s (uniform sampling required)")
    if 1.0 / dt < min_rate_hz * (1.0 - 1e-9):
        raise MeasuredDataError(f"{source}: sampling rate {1.0 / dt:.4g} Hz is below the minimum "
                                f"{min_rate_hz:g} Hz")
    order = np.lexsort((node, t))
    n_t = times.size
    x = df["x"].to_numpy(dtype=float)[order].reshape(n_t, n_nodes)
    y = df["y"].to_numpy(dtype=float)[order].reshape(n_t, n_nodes)
    th = df["theta"].to_numpy(dtype=float)[order].reshape(n_t, n_nodes) if "theta" in df.columns else None
    seg = np.hypot(np.diff(x, axis=1), np.diff(y, axis=1))
    if np.any(seg <= 0):
        raise MeasuredDataError(f"{source}: two neighbouring nodes coincide (zero segment length)")
    return Measured(times, x, y, th, source)


def load_measured(path: str | Path, min_rate_hz: float = 200.0, min_samples: int = 20) -> Measured:
    """Read and validate a measured Parquet file (see module docstring)."""
    try:
        df = read_parquet(path)
    except ValueError as exc:
        raise MeasuredDataError(str(exc)) from exc
    return validate_frame(df, str(path), min_rate_hz, min_samples)


def segment_angles(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Segment angles phi (n_t, N) from node positions, unwrapped in time and along s."""
    phi = np.arctan2(np.diff(y, axis=-1), np.diff(x, axis=-1))
    phi = np.unwrap(phi, axis=0)  # continuous in time per segment
    first = np.unwrap(phi[0])  # continuous along s at the first sample
    phi += 2.0 * math.pi * np.round((first - phi[0]) / (2.0 * math.pi))
    return phi


def node_angles(phi: np.ndarray) -> np.ndarray:
    """Nodal angles from segment (mid-segment) angles; linear operator, also for rates."""
    n = phi.shape[-1]
    out = np.empty(phi.shape[:-1] + (n + 1,))
    out[..., 1:-1] = 0.5 * (phi[..., 1:] + phi[..., :-1])
    if n >= 2:
        out[..., 0] = 1.5 * phi[..., 0] - 0.5 * phi[..., 1]
        out[..., -1] = 1.5 * phi[..., -1] - 0.5 * phi[..., -2]
    else:
        out[..., 0] = out[..., -1] = phi[..., 0]
    return out


def angle_kinematics(x, y, vx, vy, ax, ay) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Segment angle phi and its first two time derivatives from position kinematics."""
    dx, dy = np.diff(x, axis=-1), np.diff(y, axis=-1)
    dvx, dvy = np.diff(vx, axis=-1), np.diff(vy, axis=-1)
    dax, day = np.diff(ax, axis=-1), np.diff(ay, axis=-1)
    r2 = dx**2 + dy**2
    phi = segment_angles(x, y)
    w = (dx * dvy - dy * dvx) / r2
    alpha = (dx * day - dy * dax) / r2 - 2.0 * w * (dx * dvx + dy * dvy) / r2
    return phi, w, alpha


def smooth_kinematics(meas: Measured, noise_std_min: float = 0.0, seed: int = 0,
                      max_points: int = 1500, n_restarts: int = 1, spatial: bool = True,
                      hyper_points: int = 120,
                      spatial_fit_times: int = 40) -> Kinematics:
    """GP prefilter in time (the project's ``crgpr.gp``) -> q, v, a on the measured times.

    Per position component (x, y) one Matern-5/2 GP with a quadratic basis (paper Table II
    state GPs) whose hyperparameters are shared by all nodes and fitted by their joint log
    marginal likelihood (R&W Sec. 2.7) on the outputs in metres (not standardised), so that
    the noise level sigma_n is the camera's, common to every node; the posterior mean and its
    analytic first and second time derivatives give positions, velocities and accelerations.
    The hyperparameters are searched on ``hyper_points`` random samples (seeded), the GP then
    conditions on all samples.
    theta and its rates follow analytically from the smoothed positions unless a ``theta``
    column was given, which is then smoothed the same way.

    ``spatial``: the segment angles are also smoothed along s (the rod is a smooth curve):
    one Matern-5/2 GP with a quadratic basis in s whose hyperparameters maximise the joint
    LML of ``spatial_fit_times`` evenly spaced frames; its posterior mean is a fixed linear
    smoother S, applied to phi and to its time derivatives alike (so they stay consistent).
    """
    from crgpr.gp import fit_gp  # issue 3's GP (Matern-5/2, explicit basis, analytic derivatives)

    t = meas.t
    n_t = t.size
    idx = np.arange(n_t)
    if n_t > max_points:
        idx = np.unique(np.linspace(0, n_t - 1, max_points).round().astype(int))
    init = {"lengthscales": 0.2, "sigma_f": 0.1, "sigma_n": max(noise_std_min, 1e-3)}

    def smooth(Y: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        gp = fit_gp(t[idx], Y[idx], kernel="matern52", basis="quadratic", standardise_y=False,
                    sigma_n_min=noise_std_min or None, n_restarts=n_restarts, seed=seed + k, init=init,
                    hyper_subset=hyper_points if idx.size > hyper_points else None)
        m, d1, d2 = gp.predict_derivatives(t)
        return m, d1, d2, gp.sigma_n

    x, vx, ax, nx = smooth(meas.x, 0)
    y, vy, ay, ny = smooth(meas.y, 1)
    phi0 = None
    if meas.theta is not None:
        th, w, al, _ = smooth(meas.theta, 2)
    else:
        phi, dphi, ddphi = angle_kinematics(x, y, vx, vy, ax, ay)
        phi0 = phi[:, 0].copy()
        if spatial and phi.shape[1] >= 6:
            phi, dphi, ddphi = _smooth_along_s(phi, dphi, ddphi, spatial_fit_times, seed)
        th, w, al = node_angles(phi), node_angles(dphi), node_angles(ddphi)
    q = np.stack([x, y, th], axis=-1)
    v = np.stack([vx, vy, w], axis=-1)
    a = np.stack([ax, ay, al], axis=-1)
    return Kinematics(t, q, v, a, 0.5 * (nx + ny), phi0)


def _smooth_along_s(phi: np.ndarray, dphi: np.ndarray, ddphi: np.ndarray, n_fit: int, seed: int
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Apply one GP smoother along s (hyperparameters from the joint LML of some frames)."""
    from crgpr.gp import fit_gp

    n_t, n_seg = phi.shape
    s = (np.arange(n_seg) + 0.5) / n_seg  # segment midpoints, in units of L0
    rows = np.unique(np.linspace(0, n_t - 1, min(n_fit, n_t)).round().astype(int))
    hgp = fit_gp(s, phi[rows].T, kernel="matern52", basis="quadratic", standardise_y=False,
                 n_restarts=1, seed=seed + 7, init={"lengthscales": 0.5, "sigma_f": 0.5, "sigma_n": 0.01})
    fixed = {"sigma_f": hgp.sigma_f, "lengthscales": hgp.lengthscales, "sigma_n": hgp.sigma_n}
    out = []
    for arr in (phi, dphi, ddphi):
        gp = fit_gp(s, arr.T, kernel="matern52", basis="quadratic", standardise_y=False, fixed=fixed)
        out.append(gp.predict(s).T)
    return out[0], out[1], out[2]


def camera_frame(t: np.ndarray, q: np.ndarray, noise_std_m: float, rng: np.random.Generator,
                 node_stride: int = 1) -> pd.DataFrame:
    """Camera-like measurement of a trajectory: positions only, every ``node_stride``-th node,
    Gaussian position noise of ``noise_std_m`` [m] on x and y. Node indices are renumbered
    0..N_camera so that s = node * (L0 / N_camera)."""
    qs = q[:, ::node_stride, :2]
    n_t, n_nodes, _ = qs.shape
    noisy = qs + noise_std_m * rng.standard_normal(qs.shape)
    return pd.DataFrame({
        "t": np.repeat(t, n_nodes),
        "node": np.tile(np.arange(n_nodes, dtype=np.int32), n_t),
        "x": noisy[..., 0].ravel(),
        "y": noisy[..., 1].ravel(),
    })
