"""Oracle components of the paper's features: where the constitutive law is
expressible in the inputs it must equal the discrete rod's targets to round-off."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from paper_rod import paper_rod

from crgpr.learning import features as ft
from crgpr.learning.learned import LearnedRod, rollout
from crgpr.learning.oracle import oracle_components
from crgpr.physics.params import SimSettings
from crgpr.physics.rod import variational_derivative
from crgpr.physics.simulate import simulate

P = paper_rod(N=10)


def _random_state(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    s = P.s
    th = 0.4 + 2.0 * s + 0.05 * rng.standard_normal(P.N + 1)
    q = np.stack([s * 1.01 + 0.002 * rng.standard_normal(P.N + 1),
                  0.3 * s**2 + 0.002 * rng.standard_normal(P.N + 1), th], axis=-1)
    return q, 0.01 * rng.standard_normal((P.N + 1, 3))


@given(st.integers(0, 2**31 - 1))
@settings(max_examples=25, deadline=None)
def test_segment_and_momentum_oracles_equal_discrete_targets(seed):
    q, p = _random_state(np.random.default_rng(seed))
    hz = variational_derivative(q, p, P)
    comps = oracle_components(P)
    Xq = ft.paper_q_features(q[:, 0], q[:, 1], q[:, 2], P.ds, None)
    for k, name in enumerate(("q_x", "q_y")):
        tgt = ft.q_from_hz(hz[:, k], P)
        assert np.allclose(comps[name](Xq), tgt, rtol=1e-12, atol=1e-12 * np.abs(tgt).max())
    for k, name in enumerate(("dH_dp_x", "dH_dp_y", "dH_dp_theta")):
        assert np.allclose(comps[name](p[:, k]), hz[:, 3 + k], rtol=1e-14, atol=0)
        assert np.allclose(comps[name].slope(p[:, k]) * p[:, k], hz[:, 3 + k], rtol=1e-14, atol=0)


@pytest.mark.parametrize("gamma", [0.0, 2e-3, -5e-3])
def test_theta_oracle_exact_on_uniform_arc(gamma):
    """Constant curvature, equal stretch and shear on every segment: the closure assumption
    holds, so the nodal-stencil oracle equals the discrete dH/dtheta at every node, tip included."""
    k, stretch = 3.0, 1.0 + 1e-3
    th = 0.7 + k * P.s
    tb = 0.5 * (th[1:] + th[:-1])
    e = stretch * np.stack([np.cos(tb + gamma), np.sin(tb + gamma)], axis=-1) * P.ds
    xy = np.vstack([[0.0, 0.0], np.cumsum(e, axis=0)])
    q = np.column_stack([xy, th])
    hz = variational_derivative(q, np.zeros_like(q), P)
    Xt = ft.paper_theta_features(q[:, 0], q[:, 1], q[:, 2], P.ds, None)
    pred = oracle_components(P)["dH_dtheta"](Xt)
    scale = np.abs(P.GA * gamma) + P.EI * k / P.ds
    assert np.allclose(pred, hz[1:, 2], rtol=0, atol=1e-9 * scale)
    naive = oracle_components(P, "nodal")["dH_dtheta"](Xt)
    assert np.abs(naive - hz[1:, 2]).max() > 1e3 * np.abs(pred - hz[1:, 2]).max()


def test_all_oracle_rollout_tracks_ground_truth():
    """The oracle model, integrated like any learned rod, stays close to the simulator."""
    p = paper_rod(N=10)
    s = SimSettings(dt=1e-4, t_end=0.1, record_every=10, scheme="variational")
    gt = simulate(100.0, p, s)
    tr = rollout(LearnedRod(oracle_components(p), "paper", p, None), 100.0, s)
    err = np.sqrt(np.mean((tr.q[..., 2] - gt.q[..., 2]) ** 2))
    assert np.isfinite(err) and err < 0.05 * math.radians(100.0)
