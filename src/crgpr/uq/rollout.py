"""Sampled rollouts: S posterior-sample models integrated as one batch (paper Sec. III-B,
"Uncertainty Quantification via RFF Sampling"; Sec. V, "Uncertainty Quantification Results").

The sampled model is a ``crgpr.learning.learned.LearnedRod`` whose components are the
posterior sample sets of ``crgpr.uq.samples`` (leading sample axis): the same assembly of the
learned H_z of eq. (17) and the same rollout (``learned.rollout`` -> the Stormer-Verlet scheme
of ``physics.integrator.run_hamiltonian``, dt, boundary conditions) as the mean models; sample
s drives rod s of the batch, so the state is (S, N+1, 3).

All angles form one batch (S x A rods, ``rollout_samples_angles``). Divergence: the integrator
decides what has left the physical range (its thresholds) and names the batch members; those
samples are recorded and dropped, and the rest resume from the last good record (a sample is
never silently kept or silently lost).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from crgpr.learning.learned import LearnedRod, rollout_members
from crgpr.physics.integrator import SimulationDiverged
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.rod import straight_rod
from crgpr.physics.simulate import TRAJECTORY_COLUMNS
from crgpr.uq.samples import SampleSet, is_sample_set, select_samples, unwrapped

log = logging.getLogger(__name__)

UQ_COLUMNS: tuple[str, ...] = ("sample", *TRAJECTORY_COLUMNS)


def n_samples_of(samples: Mapping[str, Any], default: int | None = None) -> int:
    """The common S of the components that are sample sets (deterministic ones, e.g. the nominal
    laws of a grey-box model, are shared by every sample); ``default`` where none is a sample set
    (a model whose force laws are all nominal: every sample is the same rod), else an error."""
    sizes = {m: unwrapped(s).n_samples for m, s in samples.items() if is_sample_set(s)}
    if not sizes and default is not None:
        return int(default)
    if len(set(sizes.values())) != 1:
        raise ValueError(f"UQ samples have different S per model (or none is sampled): {sizes}")
    return next(iter(sizes.values()))


def sampled_rod(samples: Mapping[str, Any], features: str, params: RodParams,
                theta_center: float | None, damping: float = 0.0) -> LearnedRod:
    """The learned rod whose components are posterior samples (state (S, N+1, 3)); components
    without a sample axis (nominal laws) act on every sample alike, and so does a learned bending
    damping c (``damping``, the mean model's: ``learning.damping``); with no sample set at all
    every member of the batch is the same rod."""
    n_samples_of(samples, default=0)
    return LearnedRod(samples, features, params, theta_center, damping)


def rollout_samples(samples: Mapping[str, SampleSet], features: str, params: RodParams,
                    theta_center: float | None, theta0_deg: float, settings: SimSettings, damping: float = 0.0
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
    """Integrate all S sampled models at once at one angle; returns t (n_t,), q and p
    (S', n_t, N+1, 3) of the S' samples that stayed in the physical range, their indices, and the
    divergence records of the others (sample, t_s, step). See ``rollout_samples_angles``."""
    res = rollout_samples_angles(samples, features, params, theta_center, [theta0_deg], settings, damping)
    return res[float(theta0_deg)]


def rollout_samples_angles(samples: Mapping[str, SampleSet], features: str, params: RodParams,
                           theta_center: float | None, theta0_degs: Sequence[float], settings: SimSettings,
                           damping: float = 0.0
                           ) -> dict[float, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                  list[dict[str, Any]]]]:
    """All S sampled models at every angle as ONE batch of S x A rods (member (a, s): sample s
    released at angle a; ``learned.rollout_members``), so the per-step work outside the compiled
    kernels is shared; per angle the result of ``rollout_samples``. A sample that leaves the
    physical range is recorded and dropped (the others resume, bit for bit the uninterrupted
    run); fewer than 2 samples left at an angle is an error."""
    angles = [float(a) for a in theta0_degs]
    S = n_samples_of(samples)
    members = np.array([(a, s) for a in range(len(angles)) for s in range(S)], dtype=int)
    q0 = np.stack([straight_rod(math.radians(angles[a]), params) for a, _ in members])

    def model_for(keys: np.ndarray) -> LearnedRod:
        return sampled_rod({m: select_samples(smp, keys) for m, smp in samples.items()}, features, params,
                           theta_center, damping)

    what = f"UQ rollout at theta0 = {', '.join(f'{a:g}' for a in angles)} deg"
    runs = rollout_members(model_for, q0, members[:, 1], params, settings, what)
    out = {}
    for a, angle in enumerate(angles):
        idx = np.flatnonzero(members[:, 0] == a)
        div = [{"sample": int(members[i, 1]), **{k: runs[i].diverged[k] for k in ("t_s", "step")}}
               for i in idx if runs[i].diverged is not None]
        for d in div:
            log.warning("sample %d at %g deg diverged at t = %.4g s; dropped", d["sample"], angle, d["t_s"])
        ok = [i for i in idx if runs[i].diverged is None]
        if len(ok) < 2:
            last = div[-1] if div else {"step": -1, "t_s": float("nan")}
            raise SimulationDiverged(f"UQ rollout at {angle:g} deg: fewer than 2 samples left ({div})",
                                     last["step"], last["t_s"], -1)
        out[angle] = (runs[ok[0]].t, np.stack([runs[i].q for i in ok]), np.stack([runs[i].p for i in ok]),
                      members[ok, 1], div)
    return out


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
