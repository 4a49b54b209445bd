"""The collocated ground truth against the variational one, and whether the
paper's features are exact for it.

    python benchmarks/collocated_vs_variational.py [--config config.yaml] [--angles 85 60 ...]
        [--variational-dir results/ground_truth] [--out CSV]

Per angle (simulation.scheme = collocated vs the config's variational ground truth, or a fresh
variational run when no file is given): RMSE(theta) between the two schemes over all samples and
free nodes, the tip distance at t_end, the energy balance max |H - H(0) + dissipated| of each
(zeta of the config) and with zeta = 0 the swing max |H - H(0)|, both over the largest kinetic
energy of the variational run (H(0) can be 0: at 180 deg the straight rod has none), and the
time of one in-process ``simulate`` call (compiled kernel warm; upper bounds on the shared
machine).

Feature exactness on the training angle: the discrete dH/dtheta at the free nodes of each scheme
against the best closed form in the paper's GPR 3 inputs (prefilter.spatial_derivatives
stencils): -EI theta''_i - c(theta_i, x'_i, y'_i) (the collocated scheme's own law; tip:
-EI theta''_N), and learning/oracle.py's ``ThetaDerivative`` ('rotated' and 'nodal'), each as
RMS error / target std. And the segment resultants q_x (GPR 1 in the project's segment form)
from the tip-to-base sums against the constitutive law in [theta_bar, x', y'].

With ``--convergence``: the tip position at t = 0.2 s (85 deg, dt = 1e-5 s) of each scheme at
N = 25, 50, 100, 200 against the variational rod at N = 400 (dt = 2.5e-6 s), and the static tip
under gravity (0 deg, zeta = 0.3, 8 s) of each scheme against the variational one at N = 25, 50, 100.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.config import load_config, rod_params, sim_settings
from crgpr.io import read_parquet
from crgpr.learning import features as ft
from crgpr.learning.oracle import ThetaDerivative
from crgpr.learning.prefilter import spatial_derivatives
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.rod import internal_forces, node_weights, strains
from crgpr.physics.simulate import Trajectory, energy, simulate, trajectory_from_frame


def _timed(theta0: float, params: RodParams, settings: SimSettings) -> tuple[Trajectory, float]:
    t0 = time.perf_counter()
    tr = simulate(theta0, params, settings)
    return tr, time.perf_counter() - t0


def _balance(tr: Trajectory, scale: float) -> float:
    H = energy(tr)["H"]
    return float(np.abs(H - H[0] + tr.dissipated).max() / scale)


def feature_exactness(tr: Trajectory, scheme: str, stride: int = 10) -> dict[str, float]:
    """RMS error / target std of the closed forms in the paper's inputs (module docstring)."""
    P = tr.params
    q = tr.q[1::stride]
    wds = node_weights(P.N) * P.ds
    F = np.array([internal_forces(qq, P, float(tr.q[0, 0, 2]), scheme)[0] for qq in q])
    target = (-F[..., 2] / wds)[:, 1:]
    x, y, th = q[..., 0], q[..., 1], q[..., 2]
    dx, dy, th2 = spatial_derivatives(x, y, th, P.ds)
    c, s = np.cos(th), np.sin(th)
    nu1, nu2 = c * dx + s * dy, -s * dx + c * dy
    couple = nu1 * P.GA * (nu2 - P.nu2_0) - nu2 * P.EA * (nu1 - P.nu1_0)
    couple[..., -1] = 0.0  # n = 0 at the free tip
    law = (-P.EI * th2 - couple)[:, 1:]
    X = ft.paper_theta_features(x, y, th, P.ds, None)
    sd = target.std()
    out = {"theta_target_std": float(sd),
           "theta_bending_term_rms_over_std": float(np.sqrt(np.mean((P.EI * th2[:, 1:]) ** 2)) / sd),
           "theta_nodal_law_rms_over_std": float(np.sqrt(np.mean((law - target) ** 2)) / sd)}
    for mode in ("rotated", "nodal"):
        pred = ThetaDerivative(P, mode)(X)
        out[f"theta_oracle_{mode}_rms_over_std"] = float(np.sqrt(np.mean((pred - target) ** 2)) / sd)
    qx = ft.q_from_hz(-F[..., 0] / wds, P)
    qx_law = strains(q, P)["q_x"]
    out["q_x_segment_law_rms_over_std"] = float(np.sqrt(np.mean((qx - qx_law) ** 2)) / qx.std())
    return out


SCHEMES = ("variational", "collocated", "collocated_nodal")


def convergence(P: RodParams) -> None:
    """Print the convergence tables of the module docstring."""
    T, dt = 0.2, 1e-5
    ref = simulate(85.0, P.replace(N=400), SimSettings(dt / 4, T, round(4 * T / dt), "variational"))
    for scheme in SCHEMES:
        tips = [simulate(85.0, P.replace(N=N), SimSettings(dt, T, round(T / dt), scheme)).q[-1, -1, :2]
                for N in (25, 50, 100, 200)]
        err = [np.hypot(*(tip - ref.q[-1, -1, :2])) for tip in tips]
        print(f"tip error at 0.2 s vs variational N=400, N = 25/50/100/200, {scheme}: "
              + " ".join(f"{e:.3g}" for e in err))
    for N, dt_s in ((25, 1e-4), (50, 5e-5), (100, 5e-5)):
        p = P.replace(N=N, zeta=0.3)
        tips = {s: simulate(0.0, p, SimSettings(dt_s, 8.0, round(8.0 / dt_s), s)).q[-1, -1, :2]
                for s in SCHEMES}
        print(f"static tip (0 deg) N = {N}: " + ", ".join(f"{s} {tips[s].round(4)}" for s in SCHEMES)
              + "; distance to variational: " + ", ".join(
                  f"{s} {np.hypot(*(tips[s] - tips['variational'])):.3g} m" for s in SCHEMES[1:]))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--angles", type=float, nargs="*", default=None,
                    help="default: the config's training and test angles")
    ap.add_argument("--variational-dir", default="results/ground_truth",
                    help="variational ground truth {angle}.parquet (missing: simulated here)")
    ap.add_argument("--out", default=None, help="CSV to write (default: print only)")
    ap.add_argument("--convergence", action="store_true", help="only the convergence tables")
    a = ap.parse_args(argv)
    cfg = load_config(a.config)
    P, st = rod_params(cfg), sim_settings(cfg)
    if a.convergence:
        convergence(P)
        return 0
    angles = a.angles or [float(cfg["angles"]["train_deg"]), *map(float, cfg["angles"]["test_deg"])]
    st_c = SimSettings(st.dt, st.t_end, st.record_every, "collocated")
    _timed(85.0, P, SimSettings(st.dt, 10 * st.dt, 1, "collocated"))  # compile outside the timing
    rows = []
    for ang in angles:
        col, sec = _timed(ang, P, st_c)
        path = Path(a.variational_dir) / f"{ang:g}.parquet"
        if path.exists():
            var = trajectory_from_frame(read_parquet(path), P)
            e_path = Path(a.variational_dir) / f"{ang:g}_energy.parquet"
            var.dissipated = read_parquet(e_path)["dissipated"].to_numpy()
        else:
            var = simulate(ang, P, st)
        cons = {s: simulate(ang, P.replace(zeta=0.0), SimSettings(st.dt, st.t_end, st.record_every, s))
                for s in ("collocated", "variational")}
        scale = float(energy(var)["kinetic"].max())
        swing = {s: float(np.abs(energy(t)["H"] - energy(t)["H"][0]).max() / scale) for s, t in cons.items()}
        rows.append({
            "theta0_deg": ang,
            "rmse_theta_collocated_vs_variational":
                float(np.sqrt(np.mean((col.q[:, 1:, 2] - var.q[:, 1:, 2]) ** 2))),
            "tip_distance_t_end_m": float(np.hypot(*(col.q[-1, -1, :2] - var.q[-1, -1, :2]))),
            "ke_max_variational_J": scale,
            "balance_collocated_over_ke": _balance(col, scale),
            "balance_variational_over_ke": _balance(var, scale),
            "swing_zeta0_collocated_over_ke": swing["collocated"],
            "swing_zeta0_variational_over_ke": swing["variational"],
            "simulate_seconds_collocated": sec,
        })
        print(rows[-1], flush=True)
    df = pd.DataFrame(rows)
    print(df.to_string(index=False))
    train = float(cfg["angles"]["train_deg"])
    for scheme in ("collocated", "variational"):
        tr = simulate(train, P, SimSettings(st.dt, st.t_end, st.record_every, scheme))
        print(scheme, feature_exactness(tr, scheme))
    if a.out:
        df.to_csv(a.out, index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
