"""PINN baselines (paper Sec. V): physics residual of eq. (9) (Sec. III-A), constraints, smoke training."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch
from paper_rod import paper_rod

from crgpr.baselines import pinn
from crgpr.commands.pinn import pinn_rollout, pinn_train
from crgpr.config import load_config, rod_params, sim_settings
from crgpr.io import read_metadata, read_parquet, write_parquet
from crgpr.physics.params import RodParams
from crgpr.physics.rod import variational_derivative
from crgpr.physics.simulate import TRAJECTORY_COLUMNS, simulate, trajectory_frame

SMOKE = Path(__file__).parent / "smoke_config.yaml"


def _closed_form_state(params: RodParams, th0: float):
    """A smooth, bent and slightly stretched rod with momenta; exact s-derivatives by autograd."""
    s = torch.tensor(params.s, dtype=torch.float64, requires_grad=True)
    th = th0 + 0.8 * s**2 - 0.3 * torch.sin(4 * s)
    x = s * math.cos(th0) + 0.004 * torch.sin(5 * s) - 0.02 * s**2
    y = s * math.sin(th0) + 0.003 * s**3 + 0.01 * s**2

    def d(f):
        return torch.autograd.grad(f.sum(), s, create_graph=True)[0]

    xs, ys, ths = d(x), d(y), d(th)
    xss, yss, thss = d(xs), d(ys), d(ths)
    q = np.stack([x.detach().numpy(), y.detach().numpy(), th.detach().numpy()], 1)
    p = np.stack([0.1 * np.sin(3 * params.s), -0.05 * params.s, 1e-6 * np.cos(2 * params.s)], 1)
    L = params.L0
    z_s = torch.stack([xs, ys, ths * L], 1).detach()  # d/d(s/L0) of x/L0, y/L0, theta
    z_ss = torch.stack([xss * L, yss * L, thss * L * L], 1).detach()
    return q, p, z_s, z_ss


def _simulator_rate(q, p, params):
    """dz/dt of the simulator's own right-hand side (J - R) H_z + G u at the nodes, SI units."""
    hz = variational_derivative(q, p, params)
    dp = -hz[:, :3] - params.zeta * hz[:, 3:]
    dp[:, 1] -= params.rhoA * params.g
    return np.concatenate([hz[:, 3:], dp], 1)


def _residual_of(q, p, rate, z_s, z_ss, params):
    sc = pinn.Scales.from_params(params)
    scale = sc.state_scale()
    z = torch.tensor(np.concatenate([q, p], 1) / scale)
    z_t = torch.tensor(rate / scale * sc.T)
    return pinn.ph_residual(z, z_t, z_s, z_ss, sc).numpy(), z_t.numpy()


def test_residual_vanishes_on_the_simulator_right_hand_side():
    """The continuous residual of the exact field is small where dz/dt is the simulator's RHS.

    On a fine grid the discrete H_z of crgpr.physics.rod converges to the continuous one (O(ds^2)), so
    the residual must be tiny compared with the size of the terms; a 10 % change of the momentum
    rate, or the paper's sign of the couple term, gives an O(1) residual.
    """
    params = paper_rod(N=800)
    q, p, z_s, z_ss = _closed_form_state(params, math.radians(125))
    rate = _simulator_rate(q, p, params)
    r, z_t = _residual_of(q, p, rate, z_s, z_ss, params)
    inner = slice(5, -5)  # the one-sided stencils at base and tip are first order
    rms = np.sqrt((r[inner] ** 2).mean(0))
    size = np.sqrt((z_t[inner] ** 2).mean(0))
    size[5] *= pinn.Scales.from_params(params).eps  # row 6 carries eps d_t p_theta
    assert np.all(rms[:3] < 1e-12)
    assert np.all(rms[3:5] < 1e-4 * size[3:5])
    assert rms[5] < 1e-3  # angular row: terms O(1) in units of rho A g L0

    bad = rate.copy()
    bad[:, 3:] *= 1.1
    r_bad, _ = _residual_of(q, p, bad, z_s, z_ss, params)
    rms_bad = np.sqrt((r_bad[inner] ** 2).mean(0))
    assert np.all(rms_bad[3:] > 100 * rms[3:])
    assert np.all(rms_bad[3:5] > 0.05 * size[3:5])

    # perturbing the state (not the rate) breaks the balance as well
    q2 = q.copy()
    q2[:, 2] += 0.05 * np.sin(7 * params.s)
    r2, _ = _residual_of(q2, p, rate, z_s, z_ss, params)
    assert np.sqrt((r2[inner, 5] ** 2).mean()) > 0.1


def test_residual_sign_of_the_couple_is_variational():
    """With the paper's printed sign (+ (nu1 n_y - nu2 n_x) in dH/dtheta) the angular row fails."""
    params = paper_rod(N=800)
    q, p, z_s, z_ss = _closed_form_state(params, math.radians(60))
    rate = _simulator_rate(q, p, params)
    sc = pinn.Scales.from_params(params)
    scale = sc.state_scale()
    z = torch.tensor(np.concatenate([q, p], 1) / scale)
    z_t = torch.tensor(rate / scale * sc.T)
    r = pinn.ph_residual(z, z_t, z_s, z_ss, sc)[5:-5, 5]
    res = pinn.stress_resultants(z, z_s, sc)
    couple = (res["nu1"] * res["n2"] - res["nu2"] * res["n1"])[5:-5]
    flipped = r - 2 * couple  # residual if the couple entered with the other sign
    assert float(r.abs().max()) < 1e-2 * float(couple.abs().max())
    assert float(flipped.abs().max()) > 1.0 * float(couple.abs().max())


def test_forward_mode_derivatives_match_autograd():
    torch.manual_seed(0)
    for act in ("tanh", "sin"):
        model = pinn.PINN(12, 2, act, 3, 8.0).double()
        t = torch.rand(40, dtype=torch.float64) * 8
        s = torch.rand(40, dtype=torch.float64)
        th = torch.rand(40, dtype=torch.float64) * 6
        fwd = model.forward_derivatives(t, s, th)
        ref = pinn.derivatives(model, t, s, th, create_graph=False)
        for a, b in zip(fwd, ref, strict=True):
            assert torch.allclose(a, b, atol=1e-10)


def test_hard_constraints_clamp_and_initial_state():
    torch.manual_seed(1)
    model = pinn.PINN(16, 2, "tanh", 2, 8.0)
    th = torch.tensor([0.3, 2.0, 4.5])
    # clamped base at all times
    z0 = model(torch.tensor([0.5, 3.0, 7.0]), torch.zeros(3), th)
    assert torch.allclose(z0[:, :2], torch.zeros(3, 2), atol=1e-7)
    assert torch.allclose(z0[:, 2], th) and torch.allclose(z0[:, 3:], torch.zeros(3, 3))
    # straight rod at rest at t = 0
    s = torch.tensor([0.2, 0.7, 1.0])
    zi = model(torch.zeros(3), s, th)
    assert torch.allclose(zi[:, 0], s * torch.cos(th), atol=1e-7)
    assert torch.allclose(zi[:, 1], s * torch.sin(th), atol=1e-7)
    assert torch.allclose(zi[:, 2], th) and torch.allclose(zi[:, 3:], torch.zeros(3, 3))


@pytest.fixture(scope="module")
def smoke_data(tmp_path_factory):
    cfg = load_config(SMOKE)
    params, settings = rod_params(cfg), sim_settings(cfg)
    d = tmp_path_factory.mktemp("gt")
    ang = cfg["angles"]
    angles = sorted({ang["train_deg"], *ang["test_deg"], *ang["pinn_train_deg"]})
    paths = {}
    for a in angles:
        paths[a] = str(d / f"{a}.parquet")
        write_parquet(trajectory_frame(simulate(a, params, settings)), paths[a])
    return cfg, paths


@pytest.mark.parametrize("variant", sorted(pinn.VARIANTS))
def test_each_pinn_trains_and_predicts_on_the_smoke_config(smoke_data, tmp_path, variant):
    cfg, paths = smoke_data
    data = {a: paths[a] for a in pinn.variant_angles(cfg, variant)}
    w, h = tmp_path / f"{variant}.pt", tmp_path / f"{variant}_loss.parquet"
    pinn_train(cfg, variant, data, str(w), str(h))
    hist = read_parquet(h, required=["iteration", "loss", "loss_momentum", "loss_data"])
    assert hist["iteration"].iloc[-1] == cfg["baselines"]["pinn"]["iterations"]
    assert np.all(np.isfinite(hist["loss"]))
    assert hist["loss"].iloc[-1] < hist["loss"].iloc[0]
    if variant == "pinn_physics":
        assert np.all(hist["loss_data"] == 0)
    state = torch.load(w, weights_only=True)  # plain tensors only
    assert all(isinstance(v, torch.Tensor) for v in state.values())
    angles = list(cfg["angles"]["test_deg"])  # every test angle in one call, one file each
    outs = [str(tmp_path / f"{a}.parquet") for a in angles]
    pinn_rollout(cfg, variant, str(w), [paths[a] for a in angles], angles, outs)
    for angle, out in zip(angles, outs, strict=True):
        pred = read_parquet(out, required=TRAJECTORY_COLUMNS)
        gt = read_parquet(paths[angle])
        assert list(pred.columns) == list(TRAJECTORY_COLUMNS)
        assert len(pred) == len(gt)
        np.testing.assert_allclose(pred["t"], gt["t"])
        assert read_metadata(out)["theta0_deg"] == angle
        np.testing.assert_allclose(pred[pred["t"] == 0]["theta"], np.radians(angle), atol=1e-6)
        assert np.all(np.isfinite(pred[["x", "y", "theta", "p_x", "p_y", "p_theta"]].to_numpy()))
    base = pred[pred["node"] == 0]
    assert np.allclose(base[["x", "y"]], 0.0, atol=1e-6)
    assert np.allclose(base["theta"], math.radians(angle), atol=1e-6)


def test_unknown_variant_and_missing_data_fail_clearly(smoke_data):
    cfg, paths = smoke_data
    with pytest.raises(ValueError, match="unknown PINN variant"):
        pinn.variant_angles(cfg, "pinn_data_3")
    with pytest.raises(ValueError, match="no ground-truth file"):
        pinn.train_pinn(cfg, "pinn_data_8", {85: paths[85]})
