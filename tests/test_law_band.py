"""The learned law's 95 % band (laws.parquet ``sd``): the latent posterior widened by the
delete-a-block jackknife where the targets' errors run along the trajectory (by its median scale
over the record, and pointwise where the mean moves more than that), never narrowed, and never
below the floor sigma_n / sqrt(blocks) of a record that holds about that many independent
samples of its errors."""

from __future__ import annotations

import numpy as np
import pytest
from paper_rod import PAPER_ROD

from crgpr.gp import fit_gp
from crgpr.learning.law_tables import law_table

EI = 0.02


def _saved_law(tmp_path, err: np.ndarray, kappa: np.ndarray, name: str = "obj_m") -> str:
    """A bending law m(kappa) = EI kappa + err fitted with a tiny noise and saved as a model."""
    gp = fit_gp(kappa[:, None], EI * kappa + err, kernel="se", basis="linear", sigma_n_min=1e-7,
                standardise_y=True, seed=0)
    stem = tmp_path / name
    gp.save(stem, extra={"features": ["kappa"]})
    return str(stem)


def _kappa(n_t: int = 400) -> np.ndarray:
    """A decaying oscillation of one segment's curvature, time-major (as the training rows)."""
    t = np.linspace(0.0, 2.0, n_t)
    return 20.0 * np.exp(-0.5 * t) * np.cos(2.0 * np.pi * 2.0 * t)


def _band(tmp_path, err: np.ndarray, blocks: int, floor: bool = False):
    kappa = _kappa(err.size)
    stem = _saved_law(tmp_path, err, kappa)
    tab = law_table(stem, "obj_m", ["kappa"], PAPER_ROD, n_grid=61, pad=0.0, max_points=400, seed=0,
                    s_points=3, band_blocks=blocks, floor=floor)
    return tab, kappa


def test_a_systematic_error_along_the_trajectory_widens_the_band_to_hold_the_true_law(tmp_path):
    """Targets off by a slowly drifting 2 % of the law (a finite-difference bias that changes
    along the record): the latent band, sigma_n ~ 1e-7, misses the true law; the jackknife
    band (sd_scale > 1) holds it over most of the covered range."""
    t = np.linspace(0.0, 2.0, 400)
    err = 0.02 * EI * 20.0 * np.sin(2.0 * np.pi * t / 1.3)
    latent, _ = _band(tmp_path, err, 0)
    wide, _ = _band(tmp_path, err, 10)
    truth = EI * latent["x"].to_numpy()
    inside = lambda tab: np.mean(np.abs(tab["mean"] - truth) <= 1.96 * tab["sd"])  # noqa: E731
    assert (latent["sd_scale"] == 1.0).all() and (wide["sd_scale"] > 1.0).all()
    np.testing.assert_allclose(wide["sd"] / latent["sd"], wide["sd_scale"], rtol=1e-6)
    np.testing.assert_allclose(wide["mean"], latent["mean"], rtol=0, atol=1e-12)
    assert inside(latent) < 0.9 <= inside(wide)


def test_a_bias_common_to_every_block_is_held_by_the_floor_not_the_jackknife(tmp_path):
    """Targets 0.1 % too soft in every block (a discretisation error of the moment balance is the
    same wherever the record goes; at most half the targets' scatter here) plus independent
    noise: no block moves the mean more than the latent band allows (sd_scale about 1, the
    pointwise jackknife within 5 % of the floor's band), and that band misses the true law; the
    floor sigma_n / sqrt(blocks), uniform over the inputs, holds it. (A bias well above
    sigma_n / sqrt(blocks) stays outside: no band the record can size holds an error it shows in
    no statistic.)"""
    kappa = _kappa(400)
    err = -0.001 * EI * kappa + np.random.default_rng(3).normal(0.0, 2e-3 * EI * 20.0, kappa.size)
    stem = _saved_law(tmp_path, err, kappa)
    sigma_n = float(__import__("json").loads((tmp_path / "obj_m.json").read_text())["sigma_n"])
    kw = dict(n_grid=61, pad=0.0, max_points=400, seed=0, s_points=3, band_blocks=10)
    bare = law_table(stem, "obj_m", ["kappa"], PAPER_ROD, floor=False, **kw)
    held = law_table(stem, "obj_m", ["kappa"], PAPER_ROD, floor=True, **kw)
    truth = EI * bare["x"].to_numpy()
    inside = lambda tab: np.mean(np.abs(tab["mean"] - truth) <= 1.96 * tab["sd"])  # noqa: E731
    assert (bare["sd_scale"] < 1.1).all() and (bare["sd_floor"] == 0.0).all()
    np.testing.assert_allclose(held["sd_floor"], sigma_n / np.sqrt(10), rtol=1e-12)
    floor_only = np.sqrt(bare["sd"] ** 2 + held["sd_floor"] ** 2)
    assert (held["sd"] >= floor_only * (1.0 - 1e-9)).all() and (held["sd"] <= 1.05 * floor_only).all()
    assert inside(bare) < 0.5 and inside(held) >= 0.9


def _bare_and_held(tmp_path, err: np.ndarray, kappa: np.ndarray):
    """The law's band without (``floor`` False) and with the record's systematic terms, and the
    bare band with the floor alone added in quadrature."""
    stem = _saved_law(tmp_path, err, kappa)
    kw = dict(n_grid=61, pad=0.0, max_points=400, seed=0, s_points=3, band_blocks=10)
    bare = law_table(stem, "obj_m", ["kappa"], PAPER_ROD, floor=False, **kw)
    held = law_table(stem, "obj_m", ["kappa"], PAPER_ROD, floor=True, **kw)
    return bare, held, np.sqrt(bare["sd"] ** 2 + held["sd_floor"] ** 2)


def test_errors_running_along_the_trajectory_in_part_of_the_range_widen_the_band_there_only(tmp_path):
    """Targets off by a drifting 2 % of the law where |kappa| > 8 only (a finite-difference bias
    of the fast, large-amplitude swings): the jackknife's median scale over the record stays 1,
    so that scale and the floor leave the band where it is; the pointwise jackknife widens it
    over the large curvatures, holds the true law over more of the range, and leaves the small
    curvatures' band as it was."""
    t = np.linspace(0.0, 2.0, 400)
    kappa = _kappa(400)
    err = 0.02 * EI * 20.0 * np.sin(2.0 * np.pi * t / 0.7) * np.clip((np.abs(kappa) - 8.0) / 4.0, 0.0, 1.0)
    bare, held, floor_only = _bare_and_held(tmp_path, err, kappa)
    x = bare["x"].to_numpy()
    truth = EI * x
    inside = lambda sd: np.mean(np.abs(held["mean"] - truth) <= 1.96 * sd)  # noqa: E731
    widening = held["sd"].to_numpy() / floor_only.to_numpy()
    assert (held["sd_scale"] == 1.0).all()
    assert (widening >= 1.0 - 1e-9).all()  # never narrowed
    assert np.median(widening[np.abs(x) < 5.0]) < 1.01
    assert np.median(widening[np.abs(x) > 10.0]) > 1.5
    assert inside(held["sd"]) >= inside(floor_only) + 0.1


@pytest.mark.parametrize("seed", [1, 2])
def test_independent_noise_is_not_widened_by_the_pointwise_jackknife(tmp_path, seed):
    """Noise independent from sample to sample: a leave-one-block-out mean moves as the latent
    posterior says, so the band with the record's systematic terms is the floor's alone."""
    kappa = _kappa(400)
    err = np.random.default_rng(seed).normal(0.0, 1e-3 * EI * 20.0, 400)
    _, held, floor_only = _bare_and_held(tmp_path, err, kappa)
    np.testing.assert_array_less(held["sd"].to_numpy(), 1.05 * floor_only.to_numpy())


def test_without_blocks_the_band_has_no_floor(tmp_path):
    err = np.random.default_rng(4).normal(0.0, 1e-3 * EI * 20.0, 400)
    tab, _ = _band(tmp_path, err, 0, floor=True)
    assert (tab["sd_floor"] == 0.0).all()


@pytest.mark.parametrize("seed", [1, 2])
def test_independent_noise_leaves_the_latent_band(tmp_path, seed):
    """Noise independent from sample to sample: the jackknife moves the mean no more than the
    latent posterior says, so the scale is 1 (never below: the band is not narrowed)."""
    err = np.random.default_rng(seed).normal(0.0, 1e-3 * EI * 20.0, 400)
    tab, _ = _band(tmp_path, err, 10)
    assert (tab["sd_scale"] == 1.0).all()


def test_a_matern_law_gets_its_own_kernels_band(tmp_path):
    """A law fitted with a Matern-5/2 kernel: the table's mean and latent sd are that GP's own
    posterior (the band's exact posterior uses the model's kernel, not SE)."""
    kappa = _kappa(200)
    gp = fit_gp(kappa[:, None], EI * kappa + 1e-4 * np.sin(kappa), kernel="matern52", basis="linear",
                standardise_y=True, seed=0)
    gp.save(tmp_path / "obj_m", extra={"features": ["kappa"]})
    tab = law_table(tmp_path / "obj_m", "obj_m", ["kappa"], PAPER_ROD, n_grid=31, pad=0.2, max_points=400,
                    seed=0, s_points=3, band_blocks=4, floor=False)
    mean, var = gp.predict(tab["x"].to_numpy()[:, None], return_var=True)
    np.testing.assert_allclose(tab["mean"], np.ravel(mean), rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(tab["sd"] / tab["sd_scale"], np.sqrt(np.ravel(var)), rtol=1e-5)
