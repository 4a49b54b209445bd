"""Time-step convergence of a Kelvin-Voigt rod: the exact rotational flow against a Strang split.

The simulator (``physics.integrator``) integrates a Kelvin-Voigt rod's rotational half-kicks
and their damping as one exact affine flow (``dissipation.kelvin_voigt_flow``). This script
measures why: the materials study's viscoelastic rod (``materials_study.cases.viscoelastic``
of config.yaml), released at the given angles for ``materials_study.rollout_t_end_s``, with

* ``exact_flow``: ``physics.simulate`` (the scheme in use), and
* ``strang_split``: the same Stormer-Verlet kicks and drifts with the damping split around them
  as exact flows, D(dt/2) K(dt/2) drift K(dt/2) D(dt/2), D the diagonal zeta flow followed by
  the Kelvin-Voigt flow exp(-M^-1 K h) (this script's own loop; the scheme the simulator used
  for these rods before),

at dt / k for k = 1, 2, 4, 8 (dt = ``simulation.dt_s``), each against ``exact_flow`` at dt / 32:
RMSE and max |error| of theta over the nodes 1..N and the records.

    python benchmarks/kv_step_convergence.py [--angles 60,125] [--csv benchmarks/kv_step_convergence.csv]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from numba import njit

from crgpr.config import load_config, material_case_rod
from crgpr.physics.dissipation import kelvin_voigt_flow
from crgpr.physics.kernels import _forces
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.rod import free_mask, masses, straight_rod
from crgpr.physics.simulate import dissipation_coefficients, rod_kernel_args, simulate


@njit(cache=True)
def _split_run(q, v, free, m_t, m_r, ft, fr, P, grav, args, dt, n_steps, every, out):
    """The Strang-split scheme (module docstring) for the variational rod; records q."""
    ds, EA, GA, EI, kap, law, k0, n10, n20, bnl, kb, thb = args
    n = q.shape[0]
    F = np.zeros((n, 3))
    w = np.empty(n)
    h = 0.5 * dt
    _forces(0, q, ds, EA, GA, EI, kap, law, k0, n10, n20, bnl, kb, thb, F)
    out[0] = q
    for k in range(1, n_steps + 1):
        for half in range(2):
            if half == 1:
                for i in range(n):
                    v[i, 0] += h * F[i, 0] / m_t[i] * free[i, 0]
                    v[i, 1] += h * (F[i, 1] + grav[i]) / m_t[i] * free[i, 1]
                    v[i, 2] += h * F[i, 2] / m_r[i] * free[i, 2]
            for i in range(n):  # D: the diagonal flow, then the Kelvin-Voigt flow
                v[i, 0] *= ft[i] * free[i, 0]
                v[i, 1] *= ft[i] * free[i, 1]
                v[i, 2] *= fr[i] * free[i, 2]
            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc += P[i, j] * v[j, 2]
                w[i] = acc
            for i in range(n):
                v[i, 2] = w[i]
            if half == 0:
                for i in range(n):
                    v[i, 0] += h * F[i, 0] / m_t[i] * free[i, 0]
                    v[i, 1] += h * (F[i, 1] + grav[i]) / m_t[i] * free[i, 1]
                    v[i, 2] += h * F[i, 2] / m_r[i] * free[i, 2]
                    for c in range(3):
                        q[i, c] += dt * v[i, c]
                _forces(0, q, ds, EA, GA, EI, kap, law, k0, n10, n20, bnl, kb, thb, F)
        if k % every == 0:
            out[k // every] = q


def strang_split(theta0_deg: float, rod: RodParams, st: SimSettings) -> np.ndarray:
    """Positions (n_rec, N+1, 3) of the Strang-split scheme (module docstring)."""
    q = straight_rod(math.radians(theta0_deg), rod)
    m_t, m_r = masses(rod)
    lam_t, lam_r, _ = dissipation_coefficients(rod)
    free = free_mask(rod).astype(float)
    h = 0.5 * st.dt
    P = kelvin_voigt_flow(rod.internal_damping, rod.ds, m_r, 0.0, free[:, 2], h)[0]
    out = np.zeros((st.n_steps // st.record_every + 1, q.shape[0], 3))
    _split_run(q, np.zeros_like(q), free, m_t, m_r, np.exp(-lam_t * h), np.exp(-lam_r * h), P,
               -m_t * rod.g, rod_kernel_args(rod, float(q[0, 2])), st.dt, st.n_steps, st.record_every, out)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--angles", default="60,125", help="release angles [deg], comma-separated")
    ap.add_argument("--csv", default=None, help="write the rows here")
    args = ap.parse_args(argv)
    cfg = load_config(args.config)
    ms = cfg["materials_study"]
    rod = material_case_rod(cfg, "viscoelastic")
    dt = float(cfg["simulation"]["dt_s"])
    t_end = float(ms["rollout_t_end_s"])
    every = int(cfg["simulation"]["record_every"])

    def settings(k: int) -> SimSettings:
        return SimSettings(dt=dt / k, t_end=t_end, record_every=every * k, scheme="variational")

    rows = []
    for a in (float(x) for x in args.angles.split(",")):
        ref = simulate(a, rod, settings(32)).q
        for k in (1, 2, 4, 8):
            for scheme, q in (("exact_flow", simulate(a, rod, settings(k)).q),
                              ("strang_split", strang_split(a, rod, settings(k)))):
                e = q[:, 1:, 2] - ref[:, 1:, 2]
                rmse = float(np.sqrt(np.mean(e**2)))
                rows.append({"theta0_deg": a, "scheme": scheme, "dt_s": dt / k, "rmse_theta": rmse,
                             "max_abs_theta": float(np.abs(e).max())})
                print(f"{a:6.1f} deg  {scheme:13s} dt/{k}: RMSE(theta) {rmse:.3g} rad", flush=True)
    if args.csv:
        pd.DataFrame(rows).to_csv(Path(args.csv), index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
