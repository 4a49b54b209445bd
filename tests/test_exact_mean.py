"""gp.exact.ExactMean: the fitted GP's own posterior mean (issue 11, part 3)."""

from __future__ import annotations

import numpy as np
import pytest

from crgpr.gp import fit_gp
from crgpr.gp.exact import ExactMean, cutoff_radius


@pytest.mark.parametrize(("kernel", "basis", "d"), [("se", "pure_quadratic", 3), ("se", "constant", 6),
                                                    ("matern52", "none", 2), ("se", "none", 1)])
def test_exact_mean_equals_dense_posterior_mean(kernel, basis, d, tmp_path):
    rng = np.random.default_rng(3)
    n = 400
    X = rng.uniform(-2, 2, (n, d)) * (1 + np.arange(d))
    y = np.sin(X).sum(1) + 0.3 * X[:, 0] ** 2 + 0.01 * rng.standard_normal(n)
    gp = fit_gp(X, y, kernel=kernel, basis=basis, ard=d > 1, n_restarts=0, seed=1,
                fixed={"sigma_f": 1.3, "lengthscales": np.full(d if d > 1 else 1, 0.4), "sigma_n": 0.05})
    gp.save(tmp_path / "m")
    ev = ExactMean(tmp_path / "m")
    Xs = rng.uniform(-2.5, 2.5, (300, d)) * (1 + np.arange(d))
    dense = gp.predict(Xs)
    got = ev(Xs)
    assert np.max(np.abs(got - dense)) <= 1e-10 * np.max(np.abs(dense))
    if d == 1:
        _, d1, _ = gp.predict_derivatives(Xs[:, 0])
        assert np.allclose(ev.slope(Xs[:, 0]), d1, rtol=1e-8, atol=1e-10 * np.abs(d1).max())
        assert ev(Xs[:, 0]).shape == (300,)


def test_cutoff_radius_is_the_tolerance():
    r = cutoff_radius("se", 1e-12)
    assert np.isclose(np.exp(-0.5 * r * r), 1e-12)
    r = cutoff_radius("matern52", 1e-12)
    v = (1 + np.sqrt(5) * r + 5 / 3 * r * r) * np.exp(-np.sqrt(5) * r)
    assert np.isclose(v, 1e-12, rtol=1e-6)
