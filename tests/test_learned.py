"""Step 4 (crgpr.learning.learned, integrator.run_hamiltonian): the learned-model rollout."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from paper_rod import paper_rod

from crgpr.config import load_config, rod_params, sim_settings
from crgpr.io import read_metadata, read_parquet
from crgpr.learning.gradient_models import train_model
from crgpr.learning.learned import LearnedRod, learned_energy, rollout, run_rollout
from crgpr.learning.prefilter import fd_prefilter
from crgpr.physics.integrator import SimulationDiverged, run_hamiltonian
from crgpr.physics.params import SimSettings
from crgpr.physics.rod import free_mask, internal_forces, node_weights, straight_rod
from crgpr.physics.simulate import simulate

SMOKE = Path(__file__).parent / "smoke_config.yaml"


def test_hamiltonian_variant_with_exact_hz_reproduces_simulate():
    P = paper_rod(N=8)
    S = SimSettings(dt=1e-4, t_end=0.1, record_every=5, scheme="variational")
    ref = simulate(125.0, P, S)
    wds = node_weights(P.N) * P.ds
    mass = np.array([P.rhoA, P.rhoA, P.rhoI])
    gu = np.array([0.0, -P.rhoA * P.g, 0.0])
    out = run_hamiltonian(straight_rod(math.radians(125.0), P), np.zeros((P.N + 1, 3)),
                          lambda q: internal_forces(q, P)[0] / wds[:, None] + gu, lambda p: p / mass,
                          free_mask(P), P.zeta, S.dt, S.n_steps, S.record_every, wds)
    np.testing.assert_allclose(out.q, ref.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out.v, ref.p, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out.dissipated[-1], ref.dissipated[-1], rtol=1e-2)


def test_divergence_reports_when_and_where():
    P = paper_rod(N=4)
    wds = node_weights(P.N) * P.ds

    def force(q):
        f = np.zeros_like(q)
        f[3, 1] = 1e3 * q[3, 1] ** 2 + 1.0  # runaway at node 3
        return f

    with pytest.raises(SimulationDiverged) as info:
        run_hamiltonian(straight_rod(0.0, P), np.zeros((P.N + 1, 3)), force, lambda p: p / P.rhoA,
                        free_mask(P), 0.0, 1e-4, 20000, 5, wds)
    assert info.value.node == 3 and 0 < info.value.t < 2.0


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    cfg = load_config(SMOKE)
    P, S = rod_params(cfg), sim_settings(cfg)
    traj = simulate(85.0, P, S)
    d = tmp_path_factory.mktemp("learned")
    df, _ = fd_prefilter(traj, int(cfg["prefilter"]["n_t_out"]))
    df.to_parquet(d / "fd85.parquet")
    for name in ("q_x", "q_y", "dH_dtheta", "dH_dp_x", "dH_dp_y", "dH_dp_theta", "obj_n1", "obj_n2", "obj_m"):
        train_model(cfg, name, d / "fd85.parquet", d / name, "fd")
    return cfg, traj, d


def test_objective_model_reproduces_its_training_trajectory(trained):
    cfg, traj, d = trained
    P, S = rod_params(cfg), sim_settings(cfg)
    model = LearnedRod.from_dir(d, "objective", P)
    roll = rollout(model, 85.0, S)
    err = roll.q[:, 1:, 2] - traj.q[:, 1:, 2]
    assert np.sqrt(np.mean(err**2)) < 0.02  # rad over the whole record
    tip = np.linalg.norm(roll.q[:, -1, :2] - traj.q[:, -1, :2], axis=-1)
    assert tip.max() < 0.02 * P.L0
    en = learned_energy(model, roll, S.dt)
    assert (en["dissipation_rate"] >= 0).all()  # E(t) = H_z^T R H_z >= 0 (paper Fig. 5)
    # the learned energy balance closes to a small fraction of the energy exchanged
    assert np.abs(en["balance_residual"]).max() < 0.05 * np.ptp(en["gravity"])


def test_paper_model_runs_and_tracks_training_start(trained):
    cfg, traj, d = trained
    P, S = rod_params(cfg), sim_settings(cfg)
    roll = rollout(LearnedRod.from_dir(d, "paper", P), 85.0,
                   SimSettings(S.dt, 0.05, S.record_every, scheme="variational"))
    n = roll.t.size
    err = roll.q[:, 1:, 2] - traj.q[:n, 1:, 2]
    assert np.all(np.isfinite(roll.q))
    assert np.sqrt(np.mean(err**2)) < 0.2


def test_run_rollout_writes_parquet_and_a_diverged_rollout_frozen(trained, tmp_path, monkeypatch):
    cfg, _, d = trained
    out = tmp_path / "cr_gpr_objective" / "60.parquet"
    run_rollout(cfg, "cr_gpr_objective", 60.0, d, out, tmp_path / "e.parquet")
    assert out.exists() and (tmp_path / "e.parquet").exists()
    assert read_metadata(out)["diverged"] is False

    calls = {"n": 0}
    force = LearnedRod.force

    def late_boom(self, q):  # plausible for 50 evaluations, then NaN
        calls["n"] += 1
        f = force(self, q)
        return f if calls["n"] < 50 else np.full_like(f, np.nan)

    monkeypatch.setattr(LearnedRod, "force", late_boom)
    bad = tmp_path / "cr_gpr_objective" / "125.parquet"
    traj = run_rollout(cfg, "cr_gpr_objective", 125.0, d, bad, tmp_path / "e125.parquet")
    meta = read_metadata(bad)
    S = sim_settings(cfg)
    assert meta["diverged"] is True and 0 < meta["t_diverged"] < S.t_end
    df = read_parquet(bad)
    # the whole simulated time is there, every value finite, the state held after the divergence
    assert df["t"].max() == pytest.approx(S.t_end) and np.isfinite(df[["x", "y", "theta"]].to_numpy()).all()
    late = traj.t > meta["t_diverged"] + S.dt * S.record_every
    assert late.any() and np.all(traj.q[late] == traj.q[late][-1])
    energy = read_parquet(tmp_path / "e125.parquet")
    assert energy["t"].max() <= meta["t_diverged"]
