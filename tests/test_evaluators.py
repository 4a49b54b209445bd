"""crgpr.gp evaluators: exact, DTC and tabulated means agree with the exact posterior mean."""

from __future__ import annotations

import numpy as np
import pytest

from crgpr.gp import GP, KernelMean, Table1D, dtc_fit, fit_gp, load_evaluator, select_inducing
from crgpr.gp.evaluators import TABLE_POINTS, kernel_sum, kernel_sum_fast, law_grid
from crgpr.learning.nominal import SelectedInputs


def _gp(kernel: str, basis: str, n: int = 150, d: int = 3, seed: int = 0) -> tuple[GP, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1.0, 1.0, (n, d)) * np.arange(1, d + 1)
    y = np.sin(2.0 * X[:, 0]) + 0.3 * X[:, -1] ** 2 + 0.01 * rng.standard_normal(n)
    gp = fit_gp(X, y, kernel=kernel, basis=basis, ard=True,
                fixed={"sigma_f": 1.2, "lengthscales": np.linspace(0.5, 1.0, d), "sigma_n": 0.05})
    return gp, X


@pytest.mark.parametrize("kernel", ["se", "matern52"])
@pytest.mark.parametrize("basis", ["none", "constant", "linear", "pure_quadratic"])
def test_exact_evaluator_is_the_exact_posterior_mean(kernel, basis):
    gp, X = _gp(kernel, basis)
    Xs = np.random.default_rng(1).uniform(-2.0, 2.0, (64, 3)) * np.arange(1, 4)
    ev = KernelMean.exact(gp)
    scale = np.abs(gp.predict(Xs)).max()
    np.testing.assert_allclose(ev(Xs), gp.predict(Xs), rtol=0, atol=1e-11 * scale)
    # leading batch axes are kept
    assert ev(Xs.reshape(4, 16, 3)).shape == (4, 16)


@pytest.mark.parametrize("kernel", ["se", "matern52"])
def test_dtc_on_all_inputs_is_the_exact_mean_and_converges_with_m(kernel):
    """The DTC mean with every training input as inducing input is the exact posterior mean
    (up to its jitter); with fewer inputs it is an approximation whose error the full set removes."""
    gp, X = _gp(kernel, "pure_quadratic", n=120)
    V = gp._V()
    Xs = np.random.default_rng(2).uniform(-1.0, 1.0, (80, 3)) * np.arange(1, 4)
    exact = gp.predict(Xs)
    errs = []
    for M in (15, 40, 120):
        a = dtc_fit(gp, X, V, M, seed=0)
        errs.append(np.abs(KernelMean.dtc(gp, a["dtc_Z"], a["dtc_w"], a["dtc_beta"])(Xs) - exact).max())
    assert errs[-1] < 1e-4 * np.abs(exact).max()
    assert errs[-1] < 1e-3 * min(errs[:2])


def test_table_agrees_with_exact_mean_and_its_slope_with_the_derivative():
    rng = np.random.default_rng(3)
    x = rng.uniform(-2.0, 2.0, 200)
    gp = fit_gp(x, 0.7 * x + 0.1 * np.sin(3 * x), kernel="se", basis="none",
                fixed={"sigma_f": 2.0, "lengthscales": 1.0, "sigma_n": 1e-3})
    grid = np.linspace(-2.0, 2.0, 4001)
    tab = Table1D.from_gp(gp, grid)
    xs = rng.uniform(-1.9, 1.9, 300)
    m, d1, _ = gp.predict_derivatives(xs)
    np.testing.assert_allclose(tab(xs), m, atol=1e-6)
    np.testing.assert_allclose(tab.slope(xs), d1, atol=2e-3)
    assert tab(np.array([-3.0, 3.0])).tolist() == [0.0, 0.0]  # prior mean outside
    assert tab.slope(np.array([-3.0, 3.0])).tolist() == [0.0, 0.0]


def test_saved_models_load_as_the_same_evaluators(tmp_path):
    gp, X = _gp("se", "linear")
    a = dtc_fit(gp, X, gp._V(), 30, seed=0)
    gp.save(tmp_path / "dtc", extra={"name": "dtc"}, extra_arrays=a)
    gp.save(tmp_path / "exact", extra={"name": "exact"})
    Xs = X[:25] + 0.1
    dtc = KernelMean.dtc(gp, a["dtc_Z"], a["dtc_w"], a["dtc_beta"])
    assert np.array_equal(load_evaluator(tmp_path / "dtc")(Xs), dtc(Xs))
    loaded = load_evaluator(tmp_path / "exact")
    assert loaded.kind == "exact" and loaded.meta["name"] == "exact"
    np.testing.assert_allclose(loaded(Xs), gp.predict(Xs), rtol=0, atol=1e-11)


def test_fast_kernel_sum_agrees_with_the_ieee_one():
    rng = np.random.default_rng(4)
    xl = rng.standard_normal((3, 20, 4))
    ZlT = np.ascontiguousarray(rng.standard_normal((4, 50)))
    a = rng.standard_normal((3, 50))
    out, fast = np.zeros((3, 20)), np.zeros((3, 20))
    kernel_sum(xl, ZlT, a, 1.7, 0, out)
    kernel_sum_fast(xl, ZlT, a, 1.7, 2, fast)
    np.testing.assert_allclose(fast, out, rtol=1e-9, atol=1e-12)


def test_inducing_selection_is_seeded_and_spread():
    U = np.random.default_rng(5).uniform(0.0, 1.0, (500, 2))
    idx = select_inducing(U, 25, seed=3)
    assert np.array_equal(idx, select_inducing(U, 25, seed=3)) and len(set(idx)) == 25
    Z = U[idx]
    gaps = np.sqrt(((U[:, None] - Z[None]) ** 2).sum(-1)).min(1)
    assert gaps.max() < 0.2  # every point is near an inducing input


def test_a_law_of_kappa_and_s_is_tabulated_per_segment_as_its_mean():
    """A bending law of (kappa, s) seen through ``SelectedInputs`` at the segments' fixed s is
    one table per segment: within 1e-6 of the law's spread on the grid, the mean itself off it."""
    rng = np.random.default_rng(4)
    X = np.column_stack([rng.uniform(-20.0, 20.0, 300), rng.uniform(0.0, 0.5, 300)])
    y = 0.01 * X[:, 0] * (1.0 + X[:, 1]) + 1e-4 * X[:, 0] ** 3 / 20.0
    gp = fit_gp(X, y, kernel="se", basis="linear", ard=True,
                fixed={"sigma_f": 1.0, "lengthscales": [1.0, 1.0], "sigma_n": 0.01})
    mean = KernelMean.exact(gp)
    s = np.linspace(0.01, 0.49, 25)
    law = SelectedInputs(mean, [0], s)
    assert law._tables is not None and law._tables.grid.size == TABLE_POINTS
    rows = np.zeros((6, 25, 5))
    rows[..., 0] = rng.uniform(-30.0, 30.0, (6, 25))
    rows[0, :3, 0] = [law._tables.grid[0] - 1.0, law._tables.grid[-1] + 1.0, 0.0]  # off the grid
    exact = mean(np.stack([rows[..., 0], np.broadcast_to(s, (6, 25))], -1))
    np.testing.assert_allclose(law(rows), exact, rtol=0, atol=1e-6 * np.ptp(exact))
    np.testing.assert_array_equal(law(rows)[0, :2], exact[0, :2])


def test_a_law_that_varies_on_a_short_scale_is_tabulated_finely_enough():
    """The tabulation grid keeps its step within a twentieth of the lengthscale (more than the
    default points where the law varies on a short scale): a law of unit amplitude on a 0.4
    lengthscale over a range of 200 is tabulated within 1e-3, where the default number of
    points is not; a smooth law keeps the default grid."""
    rng = np.random.default_rng(5)
    x = np.sort(rng.uniform(-100.0, 100.0, 400))
    gp = fit_gp(x, np.sin(x / 0.4), kernel="se", basis="none",
                fixed={"sigma_f": 1.0, "lengthscales": 0.4 / np.std(x), "sigma_n": 1e-3})  # standardised
    ell = float(np.ravel(gp.lengthscales)[0] * gp.x_scale[0])
    assert ell == pytest.approx(0.4, rel=0.01)
    grid = law_grid(x, ell)
    assert grid.size > TABLE_POINTS and np.diff(grid).max() <= 0.05 * ell * (1 + 1e-9)
    xs = rng.uniform(-100.0, 100.0, 500)
    err = np.abs(Table1D.from_gp(gp, grid)(xs) - gp.predict(xs)).max()
    coarse = np.linspace(grid[0], grid[-1], TABLE_POINTS)  # the default number of points
    err_coarse = np.abs(Table1D.from_gp(gp, coarse)(xs) - gp.predict(xs)).max()
    assert err < 1e-3 < err_coarse
    assert law_grid(x, 50.0).size == TABLE_POINTS
