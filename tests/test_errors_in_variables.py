"""Errors in variables of the bending law's curvature inputs from positions
(``learning.camera.curvature_calibration``, config ``camera.learn.curvature_calibration``)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from crgpr.learning.camera import curvature_calibration
from crgpr.learning.gradient_models import KAPPA_CALIBRATION, training_data

EI = 1.47e-3


def _slope(k: np.ndarray, m: np.ndarray) -> float:
    return float(np.polyfit(k.ravel(), m.ravel(), 1)[0])


def test_a_linear_law_regressed_on_calibrated_curvatures_keeps_its_slope():
    """Segments of SNR 2 to 20 (rms curvature over the noise sd): on the rebuilt curvatures the
    fitted slope of m = EI kappa is attenuated (by 1 / (1 + 1/SNR^2) per segment); on the
    calibrated ones it is EI to the sampling error."""
    rng = np.random.default_rng(0)
    n_t, snr = 20000, np.array([2.0, 3.0, 5.0, 20.0])
    sigma = np.full(snr.size, 0.4)
    kappa = 1.5 + rng.standard_normal((n_t, snr.size)) * snr * sigma
    k_hat = kappa + rng.standard_normal(kappa.shape) * sigma
    m = EI * (kappa - 1.5)
    mu, lam = curvature_calibration(k_hat, sigma)
    np.testing.assert_allclose(lam, 1.0 / (1.0 + 1.0 / snr**2), rtol=0.03)
    np.testing.assert_allclose(mu, kappa.mean(axis=0), atol=0.02)
    raw = [_slope(k_hat[:, j], m[:, j]) / EI for j in range(snr.size)]
    cal = [_slope(mu[j] + lam[j] * (k_hat[:, j] - mu[j]), m[:, j]) / EI for j in range(snr.size)]
    assert raw[0] < 0.82 and raw[1] < 0.91  # the attenuation the calibration removes
    np.testing.assert_allclose(cal, 1.0, atol=0.02)


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 6), st.floats(0.0, 3.0), st.integers(0, 2**31 - 1))
def test_the_calibration_keeps_each_mean_shrinks_and_leaves_unknown_noise_alone(n_seg, noise, seed):
    rng = np.random.default_rng(seed)
    k_hat = rng.standard_normal((50, n_seg)) * rng.uniform(0.1, 5.0, n_seg) + rng.uniform(-3, 3, n_seg)
    sd = np.full(n_seg, noise)
    sd[0] = np.nan  # unknown: kept as rebuilt
    mu, lam = curvature_calibration(k_hat, sd)
    np.testing.assert_allclose(mu, k_hat.mean(axis=0))
    assert np.all((lam >= 0.0) & (lam <= 1.0)) and lam[0] == 1.0
    cal = mu + lam * (k_hat - mu)
    np.testing.assert_allclose(cal.mean(axis=0), mu, atol=1e-9)
    assert np.all(cal.std(axis=0) <= k_hat.std(axis=0) + 1e-12)


def test_training_data_applies_the_calibration_to_the_bending_inputs_only():
    """The arrays' calibration acts on obj_m's own curvature column, not on its neighbours' or
    on another model's inputs."""
    from crgpr.config import load_config, rod_params
    from crgpr.physics.rod import straight_rod

    params = rod_params(load_config("tests/smoke_config.yaml"))
    rng = np.random.default_rng(1)
    q = np.stack([straight_rod(0.3, params)] * 8)
    q[..., 2] += np.cumsum(rng.normal(0, 0.02, q[..., 2].shape), axis=1)
    arr = {"x": q[..., 0], "y": q[..., 1], "theta": q[..., 2], "t": np.arange(8) * 0.01}
    for k in ("p_x", "p_y", "p_theta", "dx_dt", "dy_dt", "dtheta_dt", "dp_x_dt", "dp_y_dt", "dp_theta_dt"):
        arr[k] = np.zeros_like(q[..., 0])
    X0, y0 = training_data(arr, params, "obj_m", None)
    n0, _ = training_data(arr, params, "obj_n1", None)
    mu, lam = rng.normal(size=params.N), rng.uniform(0.2, 1.0, params.N)
    arr[KAPPA_CALIBRATION] = np.stack([mu, lam])
    X1, y1 = training_data(arr, params, "obj_m", None)
    k0 = X0[:, 0].reshape(8, params.N)
    np.testing.assert_allclose(X1[:, 0].reshape(8, params.N), mu + lam * (k0 - mu))
    np.testing.assert_array_equal(X1[:, 1:], X0[:, 1:])
    np.testing.assert_array_equal(y1, y0)
    np.testing.assert_array_equal(training_data(arr, params, "obj_n1", None)[0], n0)
