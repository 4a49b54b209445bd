"""Step 2 prefilter (crgpr.learning.prefilter) on the smoke configuration and synthetic series."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from crgpr.commands.prefilter import prefilter as rule
from crgpr.config import load_config, rod_params, sim_settings
from crgpr.io import read_metadata
from crgpr.learning.prefilter import (
    PREFILTER_COLUMNS,
    PrefilterSettings,
    fd_prefilter,
    gp_prefilter,
    prefiltered_arrays,
    smooth_series,
    spatial_derivatives,
)
from crgpr.physics.simulate import simulate, trajectory_frame

SMOKE = Path(__file__).parent / "smoke_config.yaml"


@pytest.fixture(scope="module")
def smoke():
    cfg = load_config(SMOKE)
    traj = simulate(85.0, rod_params(cfg), sim_settings(cfg))
    return cfg, traj


def test_gp_and_fd_prefilter_recover_true_derivatives(smoke):
    cfg, traj = smoke
    st = PrefilterSettings.from_config(cfg)
    for df, _ in (gp_prefilter(traj, st, seed=1), fd_prefilter(traj, st.n_t_out)):
        assert list(df.columns) == list(PREFILTER_COLUMNS)
        a = prefiltered_arrays(df)
        idx = np.searchsorted(traj.t, a["t"])
        v_true = traj.p[idx] / np.array([traj.params.rhoA, traj.params.rhoA, traj.params.rhoI])
        # dq/dt must match the recorded velocities p / (rho A), p / (rho I)
        for k, c in enumerate(("dx_dt", "dy_dt", "dtheta_dt")):
            err = a[c][2:-2, 1:] - v_true[2:-2, 1:, k]
            scale = np.abs(v_true[..., k]).max()
            assert np.sqrt(np.mean(err**2)) < 0.02 * scale, c
        # smoothed states stay on the data
        assert np.abs(a["theta"] - traj.q[idx, :, 2]).max() < 1e-3
        # base node clamped: no motion
        assert np.allclose(a["dx_dt"][:, 0], 0.0)


def test_spatial_derivatives_exact_for_quadratics():
    ds = 0.1
    s = np.arange(8) * ds
    x = 1 + 2 * s + 3 * s**2
    th = 0.5 * s**2 - s
    dx, _, th2 = spatial_derivatives(x, x, th, ds)
    np.testing.assert_allclose(dx, 2 + 6 * s, atol=1e-10)
    np.testing.assert_allclose(th2[:-1], 1.0, atol=1e-9)
    # free tip (m = 0): half-cell second difference with a mirrored ghost node
    assert th2[-1] == pytest.approx(2 * (th[-2] - th[-1]) / ds**2)


def test_smooth_series_reusable_for_noisy_camera_data():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.002, 0.006, 400))
    y = 0.2 * np.cos(2 * t) + 0.002 * rng.standard_normal(t.size)
    m, d1, d2, _ = smooth_series(t, y, t[20:-20], noise_std_min=1e-3)
    tt = t[20:-20]
    assert np.sqrt(np.mean((d1 + 0.4 * np.sin(2 * tt)) ** 2)) < 0.02
    assert np.sqrt(np.mean((m - 0.2 * np.cos(2 * tt)) ** 2)) < 1e-3


def test_rule_writes_parquet_with_metadata(smoke, tmp_path):
    cfg, traj = smoke
    gt = tmp_path / "85.parquet"
    trajectory_frame(traj).to_parquet(gt)
    out = tmp_path / "gp" / "85.parquet"
    rule(cfg, "gp", 85, str(gt), str(out))
    meta = read_metadata(out)
    assert meta["method"] == "gp" and "hyperparameters" in meta
    with pytest.raises(ValueError, match="unknown prefilter method"):
        rule(cfg, "spline", 85, str(gt), str(tmp_path / "x.parquet"))


def test_the_lengthscale_never_falls_below_the_spacing_of_its_samples():
    """Full config, 80 deg training trajectory: the LML over the 200 hyperparameter samples
    (0.01 s apart) prefers, for p_x, a lengthscale of 0.00058 s, a white-noise fit between its
    samples whose time derivatives are noise (the objective targets came out 170x too large and
    the learned rod froze). The bound (``prefilter.ell_min_over_spacing``) refits it; every
    momentum derivative then matches the finite-difference one of the noise-free record."""
    cfg = load_config(Path(__file__).parents[1] / "config.yaml")
    traj = simulate(80.0, rod_params(cfg), sim_settings(cfg))
    st = PrefilterSettings.from_config(cfg)
    df, meta = gp_prefilter(traj, st, seed=3)
    hyp = meta["hyperparameters"]
    assert hyp["p_x"]["lengthscale_bounded"]  # the premise: this record has the bad optimum
    assert all(h["lengthscale_s"] >= meta["lengthscale_min_s"] * (1 - 1e-9) for h in hyp.values())
    a, f = prefiltered_arrays(df), prefiltered_arrays(fd_prefilter(traj, st.n_t_out)[0])
    for c in ("dp_x_dt", "dp_y_dt", "dp_theta_dt"):
        err = a[c][5:-5, 1:] - f[c][5:-5, 1:]
        assert np.sqrt(np.mean(err**2)) < 0.05 * np.std(f[c][5:-5, 1:]), c
