"""Learning and rolling out under actuation inputs (paper eq. (13): the targets subtract G(z) u;
eq. (17) with the inputs' G u): ``crgpr learn --inputs``, ``crgpr rollout --inputs --initial``."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from conftest import SMOKE

from crgpr.cli import main
from crgpr.commands.learn import learn, load_learned, read_manifest
from crgpr.commands.rollout import initial_state
from crgpr.config import load_config, rod_params
from crgpr.io import read_parquet, write_parquet
from crgpr.learning import features as ft
from crgpr.learning.learned import LearnedRod, learned_energy, rollout, rollout_members
from crgpr.learning.nominal import NominalLaw
from crgpr.learning.oracle import MomentumVelocity
from crgpr.physics.params import SimSettings
from crgpr.physics.ports import ports_from_config
from crgpr.physics.signals import SignalInputs, inputs_frame
from crgpr.physics.simulate import simulate, trajectory_frame
from crgpr.report.actuated import balance_residual

RECORD = SimSettings(dt=1e-4, t_end=0.4, record_every=10, scheme="variational")


class NominalBending:
    """The nominal bending law m = EI (kappa - kappa0) on the objective m features (kappa first)."""

    def __init__(self, params):
        self.EI, self.k0 = float(params.EI), float(params.kappa0)

    def __call__(self, X):
        return self.EI * (np.asarray(X)[..., 0] - self.k0)


def nominal_rod(params) -> LearnedRod:
    comps = {"obj_n1": NominalLaw("n1", params), "obj_n2": NominalLaw("n2", params),
             "obj_m": NominalBending(params), **{m: MomentumVelocity(params, k) for k, m in
                                                 enumerate(("dH_dp_x", "dH_dp_y", "dH_dp_theta"))}}
    return LearnedRod(comps, "objective", params)


@pytest.fixture(scope="module")
def actuated(tmp_path_factory):
    """The smoke rod driven by the smoke config's training multisine (tip couple and tip force),
    as a full-state file and its inputs file, and the models learned with and without the inputs."""
    cfg = load_config(SMOKE)
    cfg["camera"]["learn"]["nominal_laws"] = []  # every law learned: the test is of the targets
    params, ports = rod_params(cfg), ports_from_config(cfg)
    inputs = SignalInputs(cfg["ports"]["signals"]["train_multisine"], "train_multisine")
    tr = simulate(85.0, params, RECORD, inputs=inputs, ports=ports)
    d = tmp_path_factory.mktemp("actuated")
    write_parquet(trajectory_frame(tr).drop(columns=["theta0_deg", "s"]), d / "full.parquet")
    write_parquet(inputs_frame(inputs, np.linspace(0.0, RECORD.t_end, 401)), d / "u.parquet")
    learn(d / "full.parquet", d / "with", cfg, "objective", "fd", d / "u.parquet")
    learn(d / "full.parquet", d / "without", cfg, "objective", "fd")
    return cfg, tr, d


def _law_errors(model_dir, tr):
    """Relative RMSE (over the nominal law's std) of the learned n1, n2, m on the record's states."""
    model, _ = load_learned(model_dir)
    P, c = tr.params, model.components
    x, y, th = tr.q[1:, :, 0], tr.q[1:, :, 1], tr.q[1:, :, 2]
    sg = ft.segments(x, y, th, P.ds)
    xn = np.stack([sg["nu1"], sg["nu2"], sg["kappa"]], axis=-1)
    pairs = {"n1": (c["obj_n1"](xn), P.EA * (sg["nu1"] - P.nu1_0)),
             "n2": (c["obj_n2"](xn), P.GA * (sg["nu2"] - P.nu2_0)),
             "m": (c["obj_m"](ft.objective_m_features(x, y, th, P.ds)), P.EI * (sg["kappa"] - P.kappa0))}
    return {k: float(np.sqrt(np.mean((a - b) ** 2)) / np.std(b)) for k, (a, b) in pairs.items()}


def test_learning_with_the_inputs_recovers_the_nominal_laws(actuated):
    """Targets that subtract G(z) u (eq. (13)): n1, n2 and m within 2 % of the nominal laws
    (measured 0.1-0.7 %); leaving the inputs out leaves the tip load in the laws (m off by > 20 %)."""
    _, tr, d = actuated
    err = _law_errors(d / "with", tr)
    assert max(err.values()) < 0.02, err
    assert _law_errors(d / "without", tr)["m"] > 0.2


def test_manifest_records_the_channels_and_the_g_used(actuated):
    cfg, _, d = actuated
    man = read_manifest(d / "with")
    assert man["ports"]["tendon_offset_m"] == cfg["ports"]["tendon_offset_m"]
    assert man["ports"]["channels"] == ["tip_force_x", "tip_force_y", "tip_moment", "tendon_tension"]
    assert man["inputs"]["channels"] == ["tip_force_x", "tip_moment"]
    assert read_manifest(d / "without")["inputs"] is None


def test_rollout_from_the_simulators_frame_with_the_nominal_model_equals_the_simulator(actuated, tmp_path):
    """Start at t = 0.2 s of an actuated record (the file's first frame) under the same inputs:
    the nominal model's rollout is the simulator's trajectory (the same scheme; round-off)."""
    cfg, _, _ = actuated
    params, ports = rod_params(cfg), ports_from_config(cfg)
    inputs = SignalInputs({"tip_moment": cfg["ports"]["signals"]["train_multisine"]["tip_moment"],
                           "tendon_tension": {"kind": "sine", "amplitude": 0.5, "frequency_hz": 3.0,
                                              "phase_rad": 0.0, "offset": 0.5}})
    full = SimSettings(dt=1e-4, t_end=0.4, record_every=5, scheme="variational")
    ref = simulate(85.0, params, full, inputs=inputs, ports=ports)
    k0 = 400  # t = 0.2 s
    frame = trajectory_frame(ref)
    late = frame[frame["t"] >= ref.t[k0] - 1e-12].drop(columns=["theta0_deg", "s"])
    write_parquet(late, tmp_path / "m.parquet")
    q0, p0, t0, _ = initial_state(tmp_path / "m.parquet", cfg, params)
    assert t0 == pytest.approx(0.2, abs=1e-12)
    rest = SimSettings(dt=1e-4, t_end=0.2, record_every=5, scheme="variational")
    out = rollout(nominal_rod(params), np.nan, rest, inputs=inputs, ports=ports, initial=(q0, p0, t0))
    np.testing.assert_allclose(out.t, ref.t[k0:], rtol=0, atol=1e-12)
    np.testing.assert_allclose(out.q, ref.q[k0:], rtol=0, atol=1e-9)
    np.testing.assert_allclose(out.p, ref.p[k0:], rtol=0, atol=1e-9)
    np.testing.assert_allclose(out.input_work, ref.input_work[k0:] - ref.input_work[k0],
                               rtol=1e-6, atol=1e-12)


def test_rollout_cli_under_inputs_from_a_measured_start(actuated, tmp_path):
    """crgpr rollout --initial FILE --inputs U: t starts at the file's first frame, the energy
    file reports the port work, and the learned model follows the simulator (tip within 1 % of L)."""
    _, tr, d = actuated
    out, en = tmp_path / "r.parquet", tmp_path / "e.parquet"
    rc = main(["rollout", "--models", str(d / "with"), "--initial", str(d / "full.parquet"), "--inputs",
               str(d / "u.parquet"), "--t-end", "0.3", "--out", str(out), "--energy-out", str(en),
               "--config", str(SMOKE)])
    assert rc == 0
    r = read_parquet(out)
    e = read_parquet(en)
    assert r["t"].min() == 0.0 and r["t"].max() == pytest.approx(0.3)
    assert np.abs(e["input_work"]).max() > 0
    tip = r[r["node"] == 10].sort_values("t")
    k = np.searchsorted(tr.t, tip["t"].to_numpy() - 1e-9)
    err = np.hypot(tip["x"].to_numpy() - tr.q[k, -1, 0], tip["y"].to_numpy() - tr.q[k, -1, 1])
    assert err.max() < 0.01 * tr.params.L0


@pytest.mark.parametrize("table, words", [
    (pd.DataFrame({"t": [0.0, 1.0], "tip_torque": [0.0, 1.0]}), "unknown column 'tip_torque'"),
    (pd.DataFrame({"t": [0.0, 0.7, 0.6, 1.0], "tip_moment": 0.0}), "'t' is not strictly increasing"),
    (pd.DataFrame({"t": [0.0, 0.5, 1.0], "tip_force_x": [0.0, np.nan, 1.0]}),
     "'tip_force_x' has 1 non-finite"),
    (pd.DataFrame({"t": [0.0, 0.1], "tip_moment": [0.0, 1.0]}), "does not cover"),
])
def test_bad_inputs_file_is_one_line_exit_2_nothing_written(actuated, tmp_path, capsys, table, words):
    _, _, d = actuated
    bad = tmp_path / "bad.csv"
    table.to_csv(bad, index=False)
    runs = {"learn": ["learn", "--measured", str(d / "full.parquet"), "--out", str(tmp_path / "m"),
                      "--prefilter", "fd", "--inputs", str(bad), "--config", str(SMOKE)],
            "rollout": ["rollout", "--models", str(d / "with"), "--initial", str(d / "full.parquet"),
                        "--inputs", str(bad), "--t-end", "0.3", "--out", str(tmp_path / "r.parquet"),
                        "--energy-out", str(tmp_path / "e.parquet"), "--config", str(SMOKE)],
            "simulate": ["simulate", "--theta0", "85", "--t-end", "0.3", "--inputs", str(bad),
                         "--out", str(tmp_path / "s.parquet"), "--config", str(SMOKE)]}
    for argv in runs.values():
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert words in err and str(bad) in err and "\n" not in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]


CHANNEL_SINES = {"tip_force_x": 0.05, "tip_force_y": 0.05, "tip_moment": 1e-3, "tendon_tension": 0.05}


def _balance(model, ports, channel, dt):
    """The learned rollout's balance residual max |H(t) - H(0) - W(t) + D(t)| / (max |W| + D(T))
    under a 3 Hz sine on one channel (0.2 s; ``learned_energy``)."""
    u = SignalInputs({channel: {"kind": "sine", "amplitude": CHANNEL_SINES[channel], "frequency_hz": 3.0,
                                "phase_rad": 0.3, "offset": 0.0}}, channel)
    tr = rollout(model, 85.0, SimSettings(dt=dt, t_end=0.2, record_every=5, scheme="variational"),
                 inputs=u, ports=ports)
    en = learned_energy(model, tr, dt)
    W = np.abs(en["input_work"]).max()
    assert W > 0.05 * (W + en["dissipated"].iloc[-1])  # the port carries the energy
    return balance_residual(en["H_learned"], en["input_work"], en["dissipated"])


@pytest.mark.parametrize("channel", list(CHANNEL_SINES))
def test_learned_port_energy_balance_is_exact_for_an_affine_momentum_map(actuated, channel):
    """dH/dt = -H_p^T R H_p + y^T u holds along any rollout of eq. (17), gradient field or not (J
    is skew): the learned n1, n2, m (independent GPs, not a gradient) with the affine H_p of the
    rod close the balance to round-off."""
    cfg, _, d = actuated
    learned, _ = load_learned(d / "with")
    params = learned.params
    comps = {**learned.components, **{m: MomentumVelocity(params, k) for k, m in
                                      enumerate(("dH_dp_x", "dH_dp_y", "dH_dp_theta"))}}
    model = LearnedRod(comps, "objective", params)
    assert _balance(model, ports_from_config(cfg), channel, 1e-4) < 1e-10


@pytest.mark.parametrize("channel", list(CHANNEL_SINES))
def test_learned_port_energy_balance_is_second_order_with_the_learned_tables(actuated, channel):
    """The learned model as ``crgpr learn`` saves it (H_p tabulated, piecewise affine): the
    residual is within the simulator's own O(dt^2) bound (1e-4 of the energy that flowed,
    tests/test_ports.py) and falls at least 2.9-fold when dt halves (second order). The sines
    stay inside the training record's momenta (the tables are 0 outside their grid)."""
    cfg, _, d = actuated
    model, _ = load_learned(d / "with")
    ports = ports_from_config(cfg)
    r1, r2 = _balance(model, ports, channel, 1e-4), _balance(model, ports, channel, 5e-5)
    assert r1 < 1e-4
    assert r2 < r1 / 2.9 or r2 < 1e-10, (r1, r2)


def test_batched_members_under_inputs_are_each_the_single_rollout(actuated):
    """The UQ path's batch (``rollout_members``, one rod per posterior sample) under inputs: every
    member is the single rollout of its own model under the same inputs (the port acts on each
    rod of the batch alike), here two members with different models."""
    cfg, _, d = actuated
    params, ports = rod_params(cfg), ports_from_config(cfg)
    inputs = SignalInputs(cfg["ports"]["signals"]["train_multisine"], "train_multisine")
    st = SimSettings(dt=1e-4, t_end=0.2, record_every=10, scheme="variational")
    learned = load_learned(d / "with")[0]
    models = {0: nominal_rod(params), 1: learned}
    q0 = np.stack([rollout(nominal_rod(params), 85.0, SimSettings(dt=1e-4, t_end=0.0, record_every=1,
                                                                   scheme="variational")).q[0]] * 2)

    class Pair:
        """Members 0 and 1: the nominal and the learned rod, stacked on a batch axis."""

        def __init__(self, keys):
            self.rods = [models[int(k)] for k in keys]
            self.wds = learned.wds

        def force(self, q):
            return np.stack([r.force(q[i]) for i, r in enumerate(self.rods)])

        def velocity(self, p):
            return np.stack([r.velocity(p[i]) for i, r in enumerate(self.rods)])

        def velocity_slope(self, p):
            return np.stack([r.velocity_slope(p[i]) for i, r in enumerate(self.rods)])

        def bending(self):
            return None  # no learned bending damping in either member

    runs = rollout_members(Pair, q0, np.array([0, 1]), params, st, "pair", inputs=inputs, ports=ports)
    for k in (0, 1):
        one = rollout(models[k], 85.0, st, inputs=inputs, ports=ports)
        assert runs[k].diverged is None
        np.testing.assert_allclose(runs[k].q, one.q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(runs[k].p, one.p, rtol=0, atol=1e-12)
    # and the inputs act: without them the learned member moves differently
    free = rollout_members(Pair, q0, np.array([0, 1]), params, st, "pair")
    assert np.abs(free[1].q - runs[1].q).max() > 1e-4
