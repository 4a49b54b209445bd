"""The rest curvature from bending samples (crgpr.learning.rest_curvature) and its use by
``crgpr learn`` (``camera.learn.bending_symmetry: odd_estimated``): a pre-curved rod's rest
curvature is recovered from its trajectory, where the nominal kappa0 would be wrong."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crgpr.commands.learn import learn, read_manifest
from crgpr.config import rod_params
from crgpr.io import write_parquet
from crgpr.learning.rest_curvature import rest_curvature_estimate
from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import simulate, trajectory_frame


@settings(max_examples=30, deadline=None)
@given(k0=st.floats(-20.0, 20.0), EI=st.floats(1e-4, 1e-1), lo=st.floats(1.0, 10.0),
       hi=st.floats(1.0, 10.0), seed=st.integers(0, 2**16))
def test_linear_law_root_is_exact(k0, EI, lo, hi, seed):
    """m = EI (kappa - kappa0) sampled anywhere around kappa0: the estimate is kappa0 (round-off)."""
    kappa = np.random.default_rng(seed).uniform(k0 - lo, k0 + hi, 200)
    assert rest_curvature_estimate(kappa, EI * (kappa - k0)) == pytest.approx(k0, abs=1e-9 * (1 + abs(k0)))


@pytest.mark.parametrize("law", ["saturating", "exponential"])
def test_nonlinear_odd_law_root_is_close(law):
    """Odd nonlinear laws about kappa0, sampled unevenly (3/4 of the samples below kappa0): the
    cubic fit's root is within 5 % of the sampled half-range of kappa0 (an approximation: the
    cubic is not the law)."""
    rng = np.random.default_rng(1)
    k0 = 3.0
    dk = np.concatenate([rng.uniform(-4.0, 0.0, 300), rng.uniform(0.0, 8.0, 100)])
    m = np.tanh(dk / 3.0) if law == "saturating" else np.sinh(0.3 * dk)
    est = rest_curvature_estimate(k0 + dk, m + 1e-3 * rng.standard_normal(dk.size))
    assert abs(est - k0) < 0.05 * 6.0


def test_no_zero_crossing_is_an_error():
    kappa = np.linspace(1.0, 2.0, 50)
    with pytest.raises(ValueError, match="do not cross m = 0"):
        rest_curvature_estimate(kappa, 1.0 + kappa)


@pytest.mark.parametrize("columns", [None, ["t", "node", "x", "y"]], ids=["full_state", "positions"])
def test_learn_recovers_a_pre_curved_rods_rest_curvature(smoke_training_run, tmp_path, columns):
    """The smoke rod cast with kappa0 = 2 1/m, learned with the nominal (straight) rod's config
    from its full state or its positions only: odd_estimated centres the bending law on the
    data's rest curvature (within 0.1 1/m; measured 0.01 and 0.003), where the nominal odd
    symmetry would take 0."""
    cfg, _ = smoke_training_run
    true_k0 = 2.0
    tr = simulate(85.0, rod_params(cfg).replace(kappa0=true_k0),
                  SimSettings(dt=1e-4, t_end=0.4, record_every=40, scheme="variational"))
    data = tmp_path / "precurved.parquet"
    frame = trajectory_frame(tr).drop(columns=["theta0_deg", "s"])
    write_parquet(frame if columns is None else frame[columns], data)
    cfg = copy.deepcopy(cfg)
    cfg["camera"]["learn"]["bending_symmetry"] = "odd_estimated"
    man = learn(data, tmp_path / "m", cfg, "objective", "gp")
    assert man["bending_symmetry"] == "odd_estimated"
    assert man["bending_odd_about"] == pytest.approx(true_k0, abs=0.1)
    assert read_manifest(tmp_path / "m")["bending_odd_about"] == man["bending_odd_about"]
    assert cfg["rod"]["kappa0"] == 0.0  # the nominal rod is straight: "odd" would mirror about 0
