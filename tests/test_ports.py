"""Input ports of the rod (paper eqs. (9), (13): dz/dt = (J - R) dH/dz + G(z) u): the simulator
with actuation inputs, its energy balance with the port work, and the input files."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from paper_rod import paper_rod

from crgpr.physics.params import SimSettings
from crgpr.physics.ports import CHANNELS, Ports
from crgpr.physics.signals import InputsError, SignalInputs, TabulatedInputs, read_inputs
from crgpr.physics.simulate import energy, simulate, velocities

GRID = SimSettings(dt=1.0e-4, t_end=0.5, record_every=5, scheme="variational")
PORTS = Ports(0.005)
# one signal per channel, of the size the study uses (the weight of the rod is 0.38 N, its
# weight moment at the base 0.1 N m)
SIGNALS = {
    "tip_force_x": {"kind": "sine", "amplitude": 0.1, "frequency_hz": 2.0, "phase_rad": 0.0, "offset": 0.0},
    "tip_force_y": {"kind": "step", "value": -0.1, "t_s": 0.2},
    "tip_moment": {"kind": "multisine", "amplitude": 0.005, "f_min_hz": 0.5, "f_max_hz": 5.0,
                   "n_tones": 4, "seed": 1},
    "tendon_tension": {"kind": "chirp", "amplitude": 1.0, "f0_hz": 0.5, "f1_hz": 4.0, "t1_s": 0.5},
}


def _balance(tr):
    e = energy(tr)
    res = e["H"] - e["H"][0] - tr.input_work + tr.dissipated
    scale = e["kinetic"].max() + np.abs(tr.input_work).max()
    return res, scale, e


def test_zero_inputs_reproduce_the_unactuated_rod_bit_for_bit():
    """All channels zero (signals, or a file of zeros): the same trajectory, to the last bit."""
    rod = paper_rod(N=10)
    ref = simulate(85.0, rod, GRID)
    zero = SignalInputs({c: {"kind": "constant", "value": 0.0} for c in CHANNELS})
    table = TabulatedInputs(np.array([0.0, 1.0]), np.zeros((2, len(CHANNELS))))
    for inputs in (zero, table):
        tr = simulate(85.0, rod, GRID, inputs=inputs, ports=PORTS)
        assert np.array_equal(tr.q, ref.q) and np.array_equal(tr.p, ref.p)
        assert np.array_equal(tr.dissipated, ref.dissipated)
        assert np.all(tr.input_work == 0.0)


@pytest.mark.parametrize("channel", CHANNELS)
@pytest.mark.parametrize("zeta", [0.0, 1.0e-3])
def test_energy_balance_per_channel(channel, zeta):
    """H(T) - H(0) = input work - dissipated, to the scheme's O(dt^2) energy error.

    Stormer-Verlet conserves a modified energy that differs from H by O(dt^2) without drift;
    the port work is booked exactly as each kick's kinetic-energy change, so the residual is
    that bounded O(dt^2) difference: below 1e-4 of the energy scale (largest kinetic energy
    plus largest |work|; measured 1e-7 to 1e-5 of it at dt = 1e-4 s), and it falls about
    fourfold when dt halves (second order; a first-order error in the bookkeeping, such as
    splitting a kick's cross term, would halve it at most)."""
    rod = paper_rod(N=10, zeta=zeta)
    inputs = SignalInputs({channel: SIGNALS[channel]})
    tr = simulate(85.0, rod, GRID, inputs=inputs, ports=PORTS)
    res, scale, e = _balance(tr)
    assert np.abs(tr.input_work).max() > 1e-2 * e["kinetic"].max()  # the input does work
    assert np.abs(res).max() < 1e-4 * scale
    fine = SimSettings(dt=0.5e-4, t_end=GRID.t_end, record_every=10, scheme="variational")
    res2, _, _ = _balance(simulate(85.0, rod, fine, inputs=inputs, ports=PORTS))
    assert np.abs(res2).max() < 0.35 * np.abs(res).max()


def test_port_work_is_the_integral_of_output_times_input():
    """The booked work equals int y^T u dt with y = G(z)^T dH/dz the collocated output (tip
    velocity for the tip force): trapezoid over the recorded samples, within 1 %."""
    tr = simulate(85.0, paper_rod(N=10), GRID, inputs=SignalInputs({"tip_force_x": SIGNALS["tip_force_x"]}),
                  ports=PORTS)
    y = PORTS.outputs(tr.q, velocities(tr))
    power = (y * tr.u).sum(axis=1)
    w = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(tr.t))])
    assert w[-1] == pytest.approx(tr.input_work[-1], rel=0.01)


@settings(max_examples=30, deadline=None)
@given(theta=st.floats(-10, 10), d=st.floats(-0.02, 0.02),
       u=st.lists(st.floats(-5, 5), min_size=4, max_size=4),
       v=st.lists(st.floats(-3, 3), min_size=3, max_size=3))
def test_output_is_g_transpose_velocity_and_power_is_force_dot_velocity(theta, d, u, v):
    """y^T u = (G u) . v_tip: the collocated output is dual to the nodal forces."""
    ports = Ports(d)
    q = np.zeros((4, 3))
    q[-1, 2] = theta
    vel = np.zeros((4, 3))
    vel[-1] = v
    f = ports.nodal_forces(q, np.array(u))
    assert np.all(f[:-1] == 0.0)
    assert ports.outputs(q, vel) @ np.array(u) == pytest.approx((f * vel).sum(), abs=1e-12)
    # the tendon: a compressive follower force along the tip tangent and the couple T d
    t_only = ports.nodal_forces(q, np.array([0.0, 0.0, 0.0, 1.0]))[-1]
    assert t_only == pytest.approx([-np.cos(theta), -np.sin(theta), d])


def _write(tmp_path, df, name="u.csv"):
    p = tmp_path / name
    if name.endswith(".csv"):
        df.to_csv(p, index=False)
    else:
        df.to_parquet(p)
    return p


@pytest.mark.parametrize("name", ["u.csv", "u.parquet"])
def test_input_file_is_interpolated_and_missing_channels_are_zero(tmp_path, name):
    t = np.linspace(0.0, 1.0, 11)
    p = _write(tmp_path, pd.DataFrame({"t": t, "tip_moment": 2.0 * t}), name)
    u = read_inputs(p, t_end=1.0).values(np.array([0.05, 0.5]))
    assert u[:, CHANNELS.index("tip_moment")] == pytest.approx([0.1, 1.0])
    assert np.all(np.delete(u, CHANNELS.index("tip_moment"), axis=1) == 0.0)


@pytest.mark.parametrize("df, words", [
    (pd.DataFrame({"t": [0.0, 1.0], "tip_torque": [0.0, 1.0]}), "unknown column 'tip_torque'"),
    (pd.DataFrame({"t": [0.0, 0.6, 0.5, 1.0], "tip_moment": 0.0}), "not strictly increasing"),
    (pd.DataFrame({"t": [0.0, 0.5, 1.0], "tip_moment": [0.0, np.nan, 1.0]}), "'tip_moment' has 1 non-finite"),
    (pd.DataFrame({"t": [0.0, 0.5], "tip_moment": [0.0, 1.0]}), "does not cover [0, 1] s"),
    (pd.DataFrame({"time": [0.0, 1.0]}), "no column 't'"),
])
def test_bad_input_file_is_one_line_naming_file_and_column(tmp_path, df, words):
    p = _write(tmp_path, df)
    with pytest.raises(InputsError) as exc:
        read_inputs(p, t_end=1.0)
    msg = str(exc.value)
    assert words in msg and str(p) in msg and "\n" not in msg


def test_cli_simulate_with_a_named_signal_records_the_port_work(tmp_path):
    """crgpr simulate --signal NAME: the energy file has the port work and every channel's u and y,
    and its balance closes (H(T) - H(0) = W - D to the scheme's error)."""
    from conftest import SMOKE

    from crgpr.cli import main
    from crgpr.io import read_metadata, read_parquet

    out, en = tmp_path / "r.parquet", tmp_path / "e.parquet"
    assert main(["simulate", "--theta0", "85", "--t-end", "0.2", "--signal", "tendon_step", "--out", str(out),
                 "--energy-out", str(en), "--config", str(SMOKE)]) == 0
    e = read_parquet(en)
    assert {"input_work", "u_tendon_tension", "y_tendon_tension", "u_tip_moment"} <= set(e.columns)
    assert e["u_tendon_tension"].iloc[-1] > 0 and e["input_work"].abs().max() > 0
    res = e["H"] - e["H"].iloc[0] - e["input_work"] + e["dissipated"]
    assert res.abs().max() < 1e-4 * (e["kinetic"].max() + e["input_work"].abs().max())
    assert read_metadata(out)["inputs"]["name"] == "tendon_step"
    assert main(["simulate", "--theta0", "85", "--signal", "nope", "--out", str(tmp_path / "x.parquet"),
                 "--config", str(SMOKE)]) == 2
    assert not (tmp_path / "x.parquet").exists()
