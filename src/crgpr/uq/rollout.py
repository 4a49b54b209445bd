"""Sampled rollouts: S posterior-sample models integrated as one batch (paper Sec. III-B,
"Uncertainty Quantification via RFF Sampling"; Sec. V, "Uncertainty Quantification Results").

The sampled model is a ``crgpr.learning.learned.LearnedRod`` whose components are the
posterior sample sets of ``crgpr.uq.samples`` (leading sample axis): the same assembly of the
learned H_z of eq. (17) and the same rollout (``learned.rollout`` -> the Stormer-Verlet scheme
of ``physics.integrator.run_hamiltonian``, dt, boundary conditions) as the mean models; sample
s drives rod s of the batch, so the state is (S, N+1, 3).

Divergence: the integrator decides what has left the physical range (its thresholds) and names
the batch members; those samples are recorded and dropped, and the rest are integrated again
from t = 0 (a sample is never silently kept or silently lost).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from crgpr.learning.learned import LearnedRod, rollout
from crgpr.physics.integrator import SimulationDiverged
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.simulate import TRAJECTORY_COLUMNS
from crgpr.uq.samples import SampleSet, select_samples

log = logging.getLogger(__name__)

UQ_COLUMNS: tuple[str, ...] = ("sample", *TRAJECTORY_COLUMNS)


def sampled_rod(samples: Mapping[str, SampleSet], features: str, params: RodParams,
                theta_center: float | None) -> LearnedRod:
    """The learned rod whose components are posterior samples (state (S, N+1, 3))."""
    sizes = {m: s.n_samples for m, s in samples.items()}
    if len(set(sizes.values())) != 1:
        raise ValueError(f"UQ samples have different S per model: {sizes}")
    return LearnedRod(samples, features, params, theta_center)


def rollout_samples(samples: Mapping[str, SampleSet], features: str, params: RodParams,
                    theta_center: float | None, theta0_deg: float, settings: SimSettings,
                    max_restarts: int = 5
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
    """Integrate all S sampled models at once; returns t (n_t,), q and p (S', n_t, N+1, 3) of
    the S' samples that stayed in the physical range, their indices, and the divergence
    records of the others (sample, t_s, step)."""
    S = next(iter(samples.values())).n_samples
    keep = np.arange(S)
    diverged: list[dict[str, Any]] = []
    for _ in range(max_restarts + 1):
        comps = samples if len(keep) == S else {m: select_samples(s, keep) for m, s in samples.items()}
        rod = sampled_rod(comps, features, params, theta_center)
        try:
            traj = rollout(rod, theta0_deg, settings, what=f"UQ rollout at theta0 = {theta0_deg:g} deg",
                           n_batch=len(keep))
        except SimulationDiverged as exc:
            if exc.members is None or len(exc.members) == 0:
                raise
            bad = np.unique(exc.members[:, 0])
            for j in bad:
                diverged.append({"sample": int(keep[j]), "t_s": exc.t, "step": exc.step})
                log.warning("sample %d diverged at t = %.4g s; dropped, batch restarted", keep[j], exc.t)
            keep = np.delete(keep, bad)
            if len(keep) < 2:
                raise SimulationDiverged(f"UQ rollout at {theta0_deg:g} deg: fewer than 2 samples left "
                                         f"({diverged})", exc.step, exc.t, exc.node) from exc
            continue
        q = np.moveaxis(traj.q, 1, 0)  # (S', n_t, N+1, 3)
        p = np.moveaxis(traj.p, 1, 0)
        return traj.t, q, p, keep, diverged
    raise SimulationDiverged(f"UQ rollout at {theta0_deg:g} deg: more than {max_restarts} divergence "
                             f"restarts ({diverged})", -1, float("nan"), -1)


def uq_frame(theta0_deg: float, t: np.ndarray, q: np.ndarray, p: np.ndarray, samples: np.ndarray,
             ds: float) -> pd.DataFrame:
    """Tidy table, one row per (sample, t, node), columns ``UQ_COLUMNS``."""
    S, n_t, n_nodes, _ = q.shape
    n = S * n_t * n_nodes
    return pd.DataFrame({
        "sample": np.repeat(samples.astype(np.int32), n_t * n_nodes),
        "theta0_deg": np.full(n, float(theta0_deg)),
        "t": np.tile(np.repeat(t, n_nodes), S),
        "node": np.tile(np.arange(n_nodes, dtype=np.int32), S * n_t),
        "s": np.tile(np.arange(n_nodes) * ds, S * n_t),
        "x": q[..., 0].ravel(), "y": q[..., 1].ravel(), "theta": q[..., 2].ravel(),
        "p_x": p[..., 0].ravel(), "p_y": p[..., 1].ravel(), "p_theta": p[..., 2].ravel(),
    })
