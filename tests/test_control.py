"""Control on the learned model (docs/control.md): the feedforward holds the model exactly, the
closed loop on the model dissipates its shaped energy, the policy file is portable."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import SMOKE
from hypothesis import given, settings
from hypothesis import strategies as st

from crgpr.commands.control import base_rod, gains, limits, solver, write_policy
from crgpr.config import load_config, rod_params
from crgpr.control.closed_loop import learned_plant, run_closed_loop
from crgpr.control.design import circle_path, hold, regulation_policy, tracking_policy
from crgpr.control.policy import from_document, tip_pose
from crgpr.control.statics import UnreachableTarget, nodal_residual
from crgpr.learning.learned import LearnedRod
from crgpr.learning.nominal import NominalLaw
from crgpr.learning.oracle import MomentumVelocity
from crgpr.physics.params import SimSettings
from crgpr.physics.ports import ports_from_config
from crgpr.physics.rod import internal_forces, node_weights


class NominalBending:
    """The nominal bending law m = EI (kappa - kappa0) on the objective m features."""

    def __init__(self, params):
        self.EI, self.k0 = float(params.EI), float(params.kappa0)

    def __call__(self, X):
        return self.EI * (np.asarray(X)[..., 0] - self.k0)


def analytic_rod(params) -> LearnedRod:
    """A learned rod whose components are the nominal laws (its H is the simulator's)."""
    comps = {"obj_n1": NominalLaw("n1", params), "obj_n2": NominalLaw("n2", params),
             "obj_m": NominalBending(params), **{m: MomentumVelocity(params, k) for k, m in
                                                 enumerate(("dH_dp_x", "dH_dp_y", "dH_dp_theta"))}}
    return LearnedRod(comps, "objective", params)


@pytest.fixture(scope="module")
def smoke():
    cfg = load_config(SMOKE)
    params = rod_params(cfg)
    return cfg, params, analytic_rod(params)


@pytest.mark.parametrize("target", [(0.25, 0.1, None), (0.3, 0.2, None), (0.25, 0.1, -1.0)])
def test_feedforward_holds_the_model_at_the_target_to_round_off(smoke, target):
    cfg, P, model = smoke
    lo, hi = limits(cfg)
    eq = hold(model.internal, model.gu, base_rod(cfg, P), P.ds, target, solver(cfg), lo, hi)
    r = nodal_residual(model.internal, model.gu, eq.q, eq.u, P.ds)[1:]
    weight = P.rhoA * P.g * P.L0
    assert np.abs(r).max() <= 1e-10 * weight
    pose = tip_pose(eq.q)
    assert np.hypot(pose[0] - target[0], pose[1] - target[1]) <= 1e-12 * P.L0
    if target[2] is None:
        assert eq.u[2] == 0.0
    else:
        assert abs(pose[2] - target[2]) <= 1e-10
    assert np.all(eq.q[0] == base_rod(cfg, P)[0])  # the clamp is not moved


def _shaped_energy(model, P, run, policy):
    """H_cl = H (elastic + gravity + kinetic of the model) - u_ff . pose + 1/2 e^T K_p e."""
    wds = node_weights(P.N) * P.ds
    out = []
    for q, v in zip(run.shapes, run.shape_rates, strict=True):
        V = internal_forces(q, P)[1]
        Ug = P.rhoA * P.g * (wds * q[:, 1]).sum()
        T = 0.5 * (wds[:, None] * v**2 * np.array([P.rhoA, P.rhoA, P.rhoI])).sum()
        pose = tip_pose(q)
        e = policy.target[0] - pose
        out.append(V + Ug + T - policy.u_ff[0, :2] @ q[-1, :2] + 0.5 * e @ policy.K_p @ e)
    return np.array(out)


def test_closed_loop_on_the_model_dissipates_its_shaped_energy(smoke):
    """Tip spring K_p: a conservative potential 1/2 e^T K_p e; K_d on the collocated rate: damping
    injection; so H_cl decreases (up to the zero-order hold's small sampling error)."""
    cfg, P, model = smoke
    lo, hi = np.full(3, -1e9), np.full(3, 1e9)
    target = (0.25, 0.1, None)
    eq = hold(model.internal, model.gu, base_rod(cfg, P), P.ds, target, solver(cfg), lo, hi)
    start = hold(model.internal, model.gu, base_rod(cfg, P), P.ds, (0.28, 0.12, None), solver(cfg), lo, hi)
    policy = regulation_policy(eq, target, gains(cfg), lo, hi)
    rate = 2000.0
    plant = learned_plant(model, SimSettings(1e-4, 1 / rate, 5, "variational"), ports_from_config(cfg))
    run = run_closed_loop(policy, plant, start.q, np.zeros_like(start.q), rate, 0.3, 1)
    H = _shaped_energy(model, P, run, policy)
    drop = H[0] - H.min()
    assert drop > 0 and H[-1] < H[0] - 0.5 * drop
    assert np.max(np.diff(H)) <= 1e-2 * drop  # no input power in beyond the sampling error
    err = np.hypot(*(run.pose[:, :2] - run.target[:, :2]).T)
    assert err[-1] < 0.5 * err[0]


def test_at_the_target_the_loop_puts_no_power_in(smoke):
    cfg, P, model = smoke
    lo, hi = limits(cfg)
    target = (0.25, 0.1, None)
    eq = hold(model.internal, model.gu, base_rod(cfg, P), P.ds, target, solver(cfg), lo, hi)
    policy = regulation_policy(eq, target, gains(cfg), lo, hi)
    plant = learned_plant(model, SimSettings(1e-4, 2e-3, 20, "variational"), ports_from_config(cfg))
    run = run_closed_loop(policy, plant, eq.q, np.zeros_like(eq.q), 500.0, 0.1, 10)
    assert np.abs(run.work).max() <= 1e-12 * P.rhoA * P.g * P.L0 * P.L0
    assert np.hypot(*(run.pose[:, :2] - run.target[:, :2]).T).max() <= 1e-9 * P.L0


def _policies(cfg, P, model):
    lo, hi = limits(cfg)
    target = (0.25, 0.1, -1.0)
    eq = hold(model.internal, model.gu, base_rod(cfg, P), P.ds, target, solver(cfg), lo, hi)
    reg = regulation_policy(eq, target, gains(cfg), lo, hi)
    t = np.linspace(0.0, 0.2, 4)
    xy, rate = circle_path((0.25, 0.1), 0.02, 0.5, t)
    track, _ = tracking_policy(model.internal, model.gu, base_rod(cfg, P), P.ds, t, xy, rate, gains(cfg),
                               solver(cfg), lo, hi)
    return {"regulation": reg, "tracking": track}


@pytest.fixture(scope="module")
def written(smoke, tmp_path_factory):
    cfg, P, model = smoke
    d = tmp_path_factory.mktemp("policy")
    pols = _policies(cfg, P, model)
    for name, pol in pols.items():
        write_policy(pol, d / f"{name}.json", {"model_dir": "analytic"})
    return d, pols


def _independent_law(doc: dict, base, t: float, pose: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """The documented law from the file alone (json + numpy)."""
    Kp, Kd = np.array(doc["K_p"]), np.array(doc["K_d"])
    if "u_ff" in doc:
        u_ff, tgt, dtgt = np.array(doc["u_ff"]), np.array(doc["target"]), np.zeros(3)
    else:
        uf = np.genfromtxt(base / doc["u_ff_file"], delimiter=",", names=True)
        tg = np.genfromtxt(base / doc["target_file"], delimiter=",", names=True)
        u_ff = np.array([np.interp(t, uf["t"], uf[c]) for c in doc["channels"]])
        tgt = np.array([np.interp(t, tg["t"], tg[c]) for c in ("x", "y", "phi")])
        dtgt = np.array([np.interp(t, tg["t"], tg[c]) for c in ("dx", "dy", "dphi")])
    e = tgt - pose
    e[2] = (e[2] + math.pi) % (2 * math.pi) - math.pi
    return np.clip(u_ff + Kp @ e + Kd @ (dtgt - rate), doc["u_min"], doc["u_max"])


@settings(max_examples=40, deadline=None)
@given(kind=st.sampled_from(["regulation", "tracking"]), t=st.floats(0.0, 0.3),
       pose=st.lists(st.floats(-0.5, 0.5), min_size=3, max_size=3),
       rate=st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3))
def test_policy_round_trips_and_an_independent_evaluation_agrees(written, kind, t, pose, rate):
    d, pols = written
    doc = json.loads((d / f"{kind}.json").read_text())
    assert doc["channels"] == ["tip_force_x", "tip_force_y", "tip_moment"]
    back = from_document(doc, d)
    pose, rate = np.array(pose), np.array(rate)
    u = pols[kind](t, pose, rate)
    np.testing.assert_allclose(back(t, pose, rate), u, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(_independent_law(doc, d, t, pose, rate), u, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("target", [(0.6, 0.0, None), (0.0, -0.5, None)])
def test_targets_outside_the_workspace_are_refused(smoke, target):
    cfg, P, model = smoke
    lo, hi = limits(cfg)
    with pytest.raises(UnreachableTarget, match="outside the workspace"):
        hold(model.internal, model.gu, base_rod(cfg, P), P.ds, target, solver(cfg), lo, hi)


def test_targets_needing_more_input_than_the_limit_are_refused(smoke):
    cfg, P, model = smoke
    lo, hi = np.full(3, -0.01), np.full(3, 0.01)
    with pytest.raises(UnreachableTarget, match="beyond the limit control.u_limits.tip_force"):
        hold(model.internal, model.gu, base_rod(cfg, P), P.ds, (0.25, 0.1, None), solver(cfg), lo, hi)


def test_a_control_rate_off_the_time_grid_is_a_config_error():
    from crgpr.config import ConfigError

    with pytest.raises(ConfigError, match="control.control_rate_hz"):
        load_config(SMOKE, {"control": {"control_rate_hz": 3000.0}})


def _tip_run(t, xy, target):
    from types import SimpleNamespace

    pose = np.column_stack([xy, np.zeros(len(t))])
    return SimpleNamespace(t=t, pose=pose, target=np.tile([target[0], target[1], 0.0], (len(t), 1)))


@settings(max_examples=40, deadline=None)
@given(offset=st.tuples(st.floats(-1e-3, 1e-3), st.floats(-1e-3, 1e-3)), amp=st.floats(0.0, 2e-3),
       period=st.floats(0.2, 0.6), phase=st.floats(0.0, 2 * math.pi), angle=st.floats(0.0, math.pi))
def test_steady_error_sees_the_offset_through_a_residual_oscillation(offset, amp, period, phase, angle):
    """Tip at target + offset + a sinusoid of period T <= W / 2.5 along any direction: the
    Hann-weighted steady error is the offset to 3 % of the amplitude (a plain mean over W can be
    off by A T / (pi W), about 13 % here)."""
    from crgpr.control.metrics import steady_error

    t = np.arange(0.0, 3.0 + 1e-9, 5e-4)
    osc = amp * np.sin(2 * math.pi * t / period + phase)
    xy = np.column_stack([0.25 + offset[0] + osc * math.cos(angle), 0.1 + offset[1] + osc * math.sin(angle)])
    err = steady_error(_tip_run(t, xy, (0.25, 0.1)), 1.5)
    assert abs(err - math.hypot(*offset)) <= 0.03 * amp + 1e-12


def test_predicted_offset_is_the_force_error_over_the_spring():
    from crgpr.control.metrics import predicted_offset

    assert predicted_offset(np.array([0.3, -0.4, 0.05]), np.zeros(3), 50.0) == pytest.approx(0.01, rel=1e-12)
    assert predicted_offset(np.array([0.1, 0.2, 0.0]), np.array([0.1, 0.2, 9.0]), 60.0) == 0.0
