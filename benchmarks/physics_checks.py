"""Print the ground truth's physics figures (the tests assert bounds; this prints the values).

    python benchmarks/physics_checks.py

Energy drift without damping, energy drop vs integrated dissipation with damping, the static
cantilever against Euler-Bernoulli, and the observed order of spatial convergence; the same
settings as tests/test_rod_physics.py. Last, the decomposition of the discrete dH/dtheta on
the 85 deg trajectory into its bending and shear-couple parts (why cr_gpr is ill-conditioned:
two large terms that cancel to a small residual; see environment-notes.md).
"""

from __future__ import annotations

import math

import numpy as np

from crgpr.config import load_config, rod_params, sim_settings
from crgpr.physics.params import SimSettings
from crgpr.physics.rod import node_weights, strains
from crgpr.physics.simulate import energy, simulate


def main() -> None:
    cfg = load_config("config.yaml")  # the paper's rod and time grid
    rod = rod_params(cfg)
    paper = sim_settings(cfg)
    e = energy(simulate(85.0, rod.replace(zeta=0.0), paper))
    print(f"zeta = 0, 2 s: max |H - H0| / |H0| = {np.abs(e['H'] - e['H'][0]).max() / abs(e['H'][0]):.2e}")
    tr = simulate(85.0, rod, paper)
    e = energy(tr)
    drop = e["H"][0] - e["H"][-1]
    integ = np.trapezoid(e["dissipation_rate"], tr.t)
    print(f"zeta = 1e-3, 2 s: H(0) - H(T) = {drop:.5f} J, integrated dissipation = {integ:.5f} J "
          f"({abs(integ / drop - 1):.2%} apart)")
    p = rod.replace(E=3.0e8, g=0.0981, zeta=1.0)
    st = simulate(0.0, p, SimSettings(dt=1.0e-5, t_end=1.5, record_every=5000, scheme="variational"))
    w_eb = p.rhoA * p.g * p.L0**4 / (8.0 * p.EI)
    print(f"static cantilever: tip deflection / (q L^4 / 8EI) = {-st.q[-1, -1, 1] / w_eb:.5f}")
    fine = SimSettings(dt=2.0e-5, t_end=0.5, record_every=250, scheme="variational")
    runs = {N: simulate(85.0, rod.replace(N=N), fine).q[:, :: N // 10, 2] for N in (20, 40, 80)}
    d1, d2 = np.abs(runs[40] - runs[20]).max(), np.abs(runs[80] - runs[40]).max()
    print(f"spatial convergence of theta (N = 20, 40, 80): observed order {math.log2(d1 / d2):.2f}")
    p = tr.params
    sg = strains(tr.q, p)
    pad = np.zeros(sg["m"].shape[:-1] + (1,))
    m = np.concatenate([sg["m"], pad], axis=-1)  # m_N = 0 at the free tip
    c = np.concatenate([sg["nu1"] * sg["n2"] - sg["nu2"] * sg["n1"], pad], axis=-1)
    wds = node_weights(p.N)[1:] * p.ds
    bend = (m[..., 1:] - m[..., :-1]) / wds
    couple = 0.5 * p.ds * (c[..., :-1] + c[..., 1:]) / wds
    print(f"dH/dtheta at 85 deg, free nodes: std of bending part {bend.std():.4f}, of shear-couple part "
          f"{couple.std():.4f}, of their sum {(bend + couple).std():.4f}")


if __name__ == "__main__":
    main()
