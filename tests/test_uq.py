"""Trajectory UQ (crgpr.uq): the calibrated-coverage reference, coverage of a GP-posterior truth
by the sampler's bands (a statistical test), the sampled LearnedRod through the mean models'
rollout (zero posterior variance reproduces the mean rollout; batching changes nothing),
divergence handling, the sampling stage, tables and figures."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from paper_rod import paper_rod

from crgpr.gp import KernelMean, Table1D, fit_gp, load_evaluator
from crgpr.gp.sampling import (
    CompressedSamples,
    exact_posterior,
    heldout_block_scale,
    sparse_posterior,
    spec_from_gp,
)
from crgpr.learning.gradient_models import FEATURE_NAMES, MOMENTUM_MODELS, fit_model
from crgpr.learning.learned import LearnedRod, rollout
from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import simulate
from crgpr.uq.calibration import model_features, true_targets
from crgpr.uq.coverage import COVERAGE_COLUMNS, coverage_rows, expected_coverage, summary_rows
from crgpr.uq.rollout import rollout_samples, rollout_samples_angles
from crgpr.uq.samples import TabulatedSamples, centre_on_rollout, load_gp_spec, load_samples, sample_model
from crgpr.uq.settings import UQSettings

LEVELS = (50.0, 80.0, 90.0, 95.0)
SETTINGS = UQSettings(methods=("cr_gpr",), sampler="sparse_pathwise", n_samples=8, paper_n_samples=4,
                      n_features=64, inducing=60, levels=LEVELS, angles_deg=(125,), figure_angle_deg=125,
                      figure_level=95.0, figure_time_fractions=(0.5, 1.0), exact_check_max_n=500,
                      check_points=100, posterior_scale="none", heldout_blocks=5,
                      kernel_tol=0.0, update_rank_tol=1.0e-14, update_rank_max_error=1.0e-4,
                      tabulated_exact_max_n=4000)


# ---------------------------------------------------------------------------------------------
# the calibrated reference e(S, L)


def test_expected_coverage_of_a_calibrated_band() -> None:
    """S = 10, 95 %: about 0.79 (the 2.5 / 97.5 % percentiles of 10 draws lie inside their range,
    which holds an 11th draw with probability 9 / 11); e(S, L) grows with S, stays below L, and
    for large S approaches the uniform-draw value (S - 1) / (S + 1) L (-> L)."""
    assert expected_coverage(10, 95.0) == pytest.approx(0.79, abs=0.01)
    for level in LEVELS:  # 20000 replications: standard error <= 0.0036 (e(1 - e) <= 1/4)
        e = [expected_coverage(S, level, n_mc=20_000) for S in (5, 20, 200)]
        assert e[0] < e[1] < e[2] < level / 100 + 0.005
        assert e[2] == pytest.approx(199 / 201 * level / 100, abs=0.011)  # 3 se


# ---------------------------------------------------------------------------------------------
# statistical test: a truth drawn from the GP posterior is covered at the calibrated rate


def test_posterior_draw_truth_is_covered_at_the_calibrated_rate() -> None:
    """Truth: a draw from the EXACT GP posterior (R&W eq. 2.42 covariance) at m test inputs,
    near and away from the data. Bands: S samples of the rollout's sampler (sparse pathwise on
    the training inputs, evaluated by the compiled CompressedSamples). Over R independent
    replications (fresh truth and fresh samples) the mean coverage must equal e(S, L) within
    Monte Carlo error: z = (mean - e) / se, se from the spread of the R replications, two-sided
    |z| < 3.29 (false-alarm rate 0.1 % per level, <= 0.4 % for the four levels)."""
    rng = np.random.default_rng(7)
    X = rng.uniform(-1.0, 1.0, (120, 2))
    y = np.sin(2.5 * X[:, 0]) + 0.5 * X[:, 1] ** 2 + 0.05 * rng.standard_normal(120)
    gp = fit_gp(X, y, kernel="ard_se", basis="constant", n_restarts=0, seed=0)
    spec = spec_from_gp(gp)
    post = exact_posterior(spec)
    sparse = sparse_posterior(spec, spec.Xs)  # Z = X: the DTC posterior is the exact one
    xt = np.vstack([rng.uniform(-1.0, 1.0, (30, 2)), rng.uniform(1.0, 1.6, (10, 2))])
    mean, _ = post.mean_var(xt)
    L = np.linalg.cholesky(post.cov(xt) + 1e-12 * np.eye(len(xt)))
    S, R = 20, 60
    cov = {lv: [] for lv in LEVELS}
    narrow = {lv: [] for lv in LEVELS}  # negative control: the same samples, spread halved
    for _ in range(R):
        truth = mean + L @ rng.standard_normal(len(xt))
        comp = sparse.sample(S, 128, rng)
        f = comp(np.broadcast_to(xt, (S, *xt.shape)))  # (S, m)
        f_half = f.mean(0) + 0.5 * (f - f.mean(0))
        for lv in LEVELS:
            for g, out in ((f, cov), (f_half, narrow)):
                lo, hi = np.percentile(g, [50 - lv / 2, 50 + lv / 2], axis=0)
                out[lv].append(np.mean((truth >= lo) & (truth <= hi)))

    def z_score(c: list[float], lv: float) -> float:
        c = np.asarray(c)
        return (c.mean() - expected_coverage(S, lv)) / (c.std(ddof=1) / np.sqrt(R))

    for lv in LEVELS:
        z = z_score(cov[lv], lv)
        assert abs(z) < 3.29, (lv, np.mean(cov[lv]), expected_coverage(S, lv), z)
        # the test has power: a band half as wide as the posterior's is flagged at every level
        assert z_score(narrow[lv], lv) < -3.29, (lv, np.mean(narrow[lv]))


def test_coverage_rows_of_exchangeable_and_biased_ensembles() -> None:
    """Truth exchangeable with the samples (an extra member): theta coverage equals e(S, L)
    within the Monte Carlo bound; a biased narrow ensemble covers nothing; the first S samples
    give the paper's row."""
    rng = np.random.default_rng(3)
    n_t, n_nodes, S = 200, 6, 40
    t = np.linspace(0, 1, n_t)[:, None, None]
    s = np.linspace(0, 1, n_nodes)[None, :, None]
    cov = {lv: [] for lv in LEVELS}
    frac = []
    for _ in range(30):
        amp = rng.standard_normal((S + 1, 1, 1, 3))
        ph = rng.uniform(0, 2 * np.pi, (S + 1, 1, 1, 3))
        fam = amp * np.sin(4 * t + ph) * s  # (S+1, n_t, n_nodes, 3), zero at t = 0? no: at s = 0
        rows = coverage_rows(fam[:S], fam[S], LEVELS, [S])
        for r in rows:
            cov[r["level"]].append(r["theta_coverage"])
            assert r["loo"].shape == (S,)
            # leave-one-out: each sample covered by the other S - 1, on average e(S - 1, L)
            e1 = expected_coverage(S - 1, r["level"])
            assert abs(r["loo"].mean() - e1) < 4 * r["calibrated_coverage_sd"] / np.sqrt(S) + 0.02
            frac.append(r["calibrated_fraction_at_least"])
    for lv in LEVELS:
        e = expected_coverage(S, lv)
        assert abs(np.mean(cov[lv]) - e) < 3 * np.sqrt(e * (1 - e) / (S + 2)) / np.sqrt(30) + 0.02
    # the truth is exchangeable with the samples: its rank among the leave-one-out coverages is
    # uniform, the fraction at least as large ~0.5 (sd of the mean of 120 correlated values
    # <= 0.29 / sqrt(30) = 0.053: bounds > 3.5 sd)
    assert 0.3 < np.mean(frac) < 0.75, np.mean(frac)
    fam = 1e-3 * rng.standard_normal((S, n_t, n_nodes, 3))
    rows = coverage_rows(fam, np.full((n_t, n_nodes, 3), 0.2), LEVELS, [10, S], fam.mean(0))
    assert len(rows) == 2 * len(LEVELS) and {r["n_samples"] for r in rows} == {10, S}
    assert all(r["theta_coverage"] == 0.0 and r["tip_coverage"] == 0.0 for r in rows)
    assert all(r["calibrated_fraction_at_least"] == 1.0 for r in rows)  # too narrow: flagged
    assert rows[0]["theta_rmse_mean_model"] == pytest.approx(0.2, rel=0.05)
    df = pd.DataFrame([{"method": "m", "theta0_deg": a, "n_diverged": 0, **r} for a in (60.0, 125.0)
                       for r in rows])[list(COVERAGE_COLUMNS)]
    mean = summary_rows(df)
    assert len(mean) == len(rows) and mean["theta0_deg"].isna().all()


# ---------------------------------------------------------------------------------------------
# the sampled LearnedRod through the mean models' rollout


PARAMS = paper_rod(N=6)
SHORT = SimSettings(dt=1e-4, t_end=0.03, record_every=10, scheme="variational")


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory) -> Path:
    """The nine gradient models (gradient_models.fit_model: the real fit and rollout
    approximation) trained on the analytic targets of a short 85 deg run of a 6-segment rod
    (0.2 s, 51 records, 150 training points per model: cheap, the tests only need models that
    roll out 0.03 s)."""
    out = tmp_path_factory.mktemp("models")
    traj = simulate(85.0, PARAMS, SimSettings(dt=1e-4, t_end=0.2, record_every=40, scheme="variational"))
    center = 0.5 * float(traj.q[:, 1:, 2].min() + traj.q[:, 1:, 2].max())
    feats = model_features(traj.q, traj.p, PARAMS, center)
    truth = true_targets(traj.q, traj.p, PARAMS)
    # rollout_mean dtc: the mean model here is the DTC mean the samples are centred on
    gm = {"n_restarts": 0, "n_hyper": 80, "inducing": 30, "check_points": 50, "rollout_mean": "dtc",
          "dtc_max_error": 1e-6, "dtc_rank_tol": 1e-14, "exact_tol": 1e-12, "check_every": 1,
          "hyper_bounds": {"ell_min_over_spread": 0.01, "ell_max_over_spread": 100.0,
                           "sigma_f_min_std": 0.01, "sigma_f_max_std": 10.0}}
    rng = np.random.default_rng(5)
    for i, name in enumerate(FEATURE_NAMES):
        X = feats[name].reshape(-1, feats[name].shape[-1])
        sd = float(np.std(truth[name]))
        yv = truth[name].reshape(-1) + 0.01 * sd * rng.standard_normal(X.shape[0])  # measured targets
        spec = {"kernel": "se", "ard": X.shape[1] > 1, "n_train": 150, "sigma_n_min": 0.005 * sd,
                "basis": "none" if name in MOMENTUM_MODELS else "constant"}
        gp, arrays, report = fit_model(name, X, yv, spec, gm, seed=i)
        gp.save(out / name, extra={"name": name, "features": list(FEATURE_NAMES[name]),
                                   "theta_center": center, **report}, extra_arrays=arrays)
    return out


class _Batched:
    """A mean model's component evaluated for a batch of S identical rods (x (S, ..., d))."""

    def __init__(self, comp: KernelMean | Table1D):
        self.comp = comp
        if comp.kind == "table":  # the same table for every rod: the rod's compiled momentum maps see it
            self.tx, self.ty, self.dim = comp.tx, comp.ty, 1

    def __call__(self, X: np.ndarray) -> np.ndarray:
        if self.comp.kind == "table":
            return self.comp(X)
        return self.comp(X.reshape(-1, X.shape[-1])).reshape(X.shape[:-1])

    def slope(self, x: np.ndarray) -> np.ndarray:
        return self.comp.slope(x)


def _zero_variance_samples(stem: Path, S: int) -> CompressedSamples | TabulatedSamples:
    """S 'posterior samples' of a model whose posterior variance is zero: every sample is the
    rollout's mean model (DTC coefficients, no prior part; the tabulated mean)."""
    spec, Z, grid = load_gp_spec(stem, stem.name)
    ra = spec.rollout_arrays
    if grid is not None:
        with np.load(stem.with_suffix(".npz")) as a:
            return TabulatedSamples(grid, np.repeat(a["table_y"][None], S, axis=0))
    D, d = 4, spec.dim
    return CompressedSamples(np.ones((S, D, d)), np.zeros((S, D)), np.zeros((S, D)), Z,
                             np.repeat(np.ravel(ra["dtc_w"])[None], S, axis=0),
                             np.repeat(np.ravel(ra["dtc_beta"])[None], S, axis=0), spec.sigma_f,
                             spec.lengthscales, spec.x_mean, spec.x_std, spec.basis, spec.y_mean,
                             spec.y_scale)


@pytest.mark.parametrize("features", ["paper", "objective"])
def test_zero_posterior_variance_reproduces_the_mean_rollout(model_dir: Path, features: str) -> None:
    """(1) The mean model's own components on a batch of 3 rods: every member equals the
    unbatched mean rollout bit for bit (batching through LearnedRod and run_hamiltonian changes
    nothing). (2) Sample sets with zero posterior variance (the sampler's representation,
    compiled sums with polynomial exp / cos) reproduce the mean rollout to round-off of those
    polynomials (relative 1e-10 per evaluation)."""
    mean = LearnedRod.from_dir(model_dir, features, PARAMS)
    ref = rollout(mean, 125.0, SHORT)
    batched = LearnedRod({m: _Batched(c) for m, c in mean.components.items()}, features, PARAMS, mean.center)
    tb = rollout(batched, 125.0, SHORT, n_batch=3)
    assert tb.q.shape == (ref.q.shape[0], 3, *ref.q.shape[1:])
    for s in range(3):
        assert np.array_equal(tb.q[:, s], ref.q) and np.array_equal(tb.p[:, s], ref.p)
    np.testing.assert_allclose(tb.dissipated[:, 1], ref.dissipated, rtol=1e-12, atol=0)
    assert np.abs(ref.q[-1] - ref.q[0]).max() > 1e-3  # the rod moved
    S = 4
    smp = {m: _zero_variance_samples(model_dir / m, S) for m in mean.components}
    t, q, p, keep, div = rollout_samples(smp, features, PARAMS, mean.center, 125.0, SHORT)
    assert div == [] and list(keep) == list(range(S))
    np.testing.assert_array_equal(t, ref.t)
    for s in range(S):
        np.testing.assert_allclose(q[s], ref.q, rtol=0, atol=1e-9)
        np.testing.assert_allclose(p[s], ref.p, rtol=1e-7, atol=1e-9 * np.abs(ref.p).max())


class _ZeroDraws:
    """A random generator whose every normal and uniform draw is 0: the sampler's deviations
    from its mean are linear in its draws, so these samples have zero posterior variance."""

    def standard_normal(self, size: tuple[int, ...]) -> np.ndarray:
        return np.zeros(size)

    def uniform(self, low: float, high: float, size: tuple[int, ...]) -> np.ndarray:
        return np.zeros(size)


def test_jackknife_covariance_sampler_with_zero_variance_reproduces_the_mean_rollout(model_dir: Path) -> None:
    """uq.posterior_scale = jackknife_covariance: the objective GPs' samples from their
    jackknife covariance (``SparsePosterior.sample(jackknife=...)``, 4 leave-one-block-out
    posteriors), with every draw zero, centred on the rollout mean by the sampler's own
    ``centre_on_rollout``: the sampled rollout equals the mean rollout to the round-off of the
    compiled polynomial sums (as the zero-variance test above); with real draws the samples
    scatter."""
    mean = LearnedRod.from_dir(model_dir, "objective", PARAMS)
    ref = rollout(mean, 125.0, SHORT)
    S = 3
    smp, real = {}, {}
    for m in mean.components:
        if m in MOMENTUM_MODELS:
            smp[m] = real[m] = _zero_variance_samples(model_dir / m, S)
            continue
        spec, Z, _ = load_gp_spec(model_dir / m, m)
        post = sparse_posterior(spec, Z)
        coeffs: list[np.ndarray] = []
        heldout_block_scale(spec, 4, Z, "jackknife", 50, post, coeffs)
        for rng, out in ((_ZeroDraws(), smp), (np.random.default_rng(2), real)):
            comp = post.sample(S, 16, rng, np.asarray(coeffs))
            centre_on_rollout(comp, post, spec.rollout_arrays, 1.0)
            out[m] = comp
    t, q, p, keep, div = rollout_samples(smp, "objective", PARAMS, mean.center, 125.0, SHORT)
    assert div == [] and list(keep) == list(range(S))
    for s in range(S):
        np.testing.assert_allclose(q[s], ref.q, rtol=0, atol=1e-9)
        np.testing.assert_allclose(p[s], ref.p, rtol=1e-7, atol=1e-9 * np.abs(ref.p).max())
    _, q2, _, _, _ = rollout_samples(real, "objective", PARAMS, mean.center, 125.0, SHORT)
    assert np.std(q2[:, -1, -1, 2]) > 0


def test_sampled_rollout_scatters_and_drops_diverged_samples(model_dir: Path, tmp_path: Path) -> None:
    """Real posterior samples (the uq_samples stage) through the batched rollout: the samples
    differ; a sample made to run away is named by the integrator, recorded and dropped, the rest
    are integrated again and equal their first run."""
    names = ("q_x", "q_y", "dH_dtheta", *MOMENTUM_MODELS)
    for m in names:
        sample_model(model_dir / m, m, SETTINGS, 11, tmp_path / f"{m}.npz", tmp_path / f"{m}.json")
        info = json.loads((tmp_path / f"{m}.json").read_text())["model"]
        assert info["n_samples"] == SETTINGS.n_samples
    smp = load_samples({m: tmp_path / f"{m}.npz" for m in names})
    center = json.loads((model_dir / "q_x.json").read_text())["theta_center"]
    t, q, p, keep, div = rollout_samples(smp, "paper", PARAMS, center, 125.0, SHORT)
    assert div == [] and q.shape[0] == SETTINGS.n_samples
    assert np.std(q[:, -1, -1, 2]) > 0
    bad = smp["dH_dp_theta"]
    bad.values[2] *= 1e9  # sample 2: a runaway angular velocity
    t2, q2, p2, keep2, div2 = rollout_samples(smp, "paper", PARAMS, center, 125.0, SHORT)
    assert [d["sample"] for d in div2] == [2] and 2 not in keep2
    np.testing.assert_allclose(q2, q[keep2], rtol=0, atol=1e-12)


def test_samples_are_centred_on_the_rollout_mean(model_dir: Path, tmp_path: Path) -> None:
    """The sampled functions of a model scatter around exactly the rollout's DTC mean, with the
    sampler's predictive sd, and the diagnostics compare the sampler to the exact posterior."""
    import dataclasses

    st = dataclasses.replace(SETTINGS, n_samples=300)
    comp = sample_model(model_dir / "obj_n1", "obj_n1", st, 3, tmp_path / "s.npz", tmp_path / "s.json")
    diag = json.loads((tmp_path / "s.json").read_text())["model"]
    assert diag["centred_on"].startswith("the rollout's DTC mean")
    assert diag["sd_ratio_median"] == pytest.approx(1.0, abs=0.2)
    mean = load_evaluator(model_dir / "obj_n1")
    spec, Z, _ = load_gp_spec(model_dir / "obj_n1", "obj_n1")
    xt = spec.Xs[:6] * spec.x_std + spec.x_mean
    f = comp(np.broadcast_to(xt, (300, *xt.shape)))
    _, var = sparse_posterior(spec, Z).mean_var(xt)
    assert np.all(np.abs(f.mean(0) - mean(xt)) < 5.0 * np.sqrt(var / 300))
    np.testing.assert_allclose(f.std(0), np.sqrt(var), rtol=0.3)


def test_true_targets_match_the_rod_forces() -> None:
    """The analytic targets reproduce the rod's nodal forces through the learned model's own
    assembly (features.forces_from_q, theta_forces_objective)."""
    from crgpr.learning import features as ft
    from crgpr.physics.rod import internal_forces, node_weights

    params = paper_rod(N=8)
    traj = simulate(125.0, params, SimSettings(dt=1e-4, t_end=0.05, record_every=100, scheme="variational"))
    tt = true_targets(traj.q, traj.p, params)
    wds = node_weights(params.N) * params.ds
    F = internal_forces(traj.q[-1], params, float(traj.q[0, 0, 2]))[0] / wds[:, None]
    tol = 1e-9 * np.abs(F).max()
    np.testing.assert_allclose(ft.forces_from_q(tt["q_x"][-1], params)[1:], F[1:, 0], atol=tol)
    np.testing.assert_allclose(ft.forces_from_q(tt["q_y"][-1], params)[1:], F[1:, 1], atol=tol)
    sg = ft.segments(*np.moveaxis(traj.q[-1], -1, 0), params.ds)
    th = ft.theta_forces_objective(tt["obj_n1"][-1], tt["obj_n2"][-1], tt["obj_m"][-1], sg["nu1"], sg["nu2"],
                                   params)
    np.testing.assert_allclose(th[1:], F[1:, 2], atol=tol)
    np.testing.assert_allclose(tt["dH_dp_x"], traj.p[:, 1:, 0] / params.rhoA)


def test_reliability_diagram_and_band_figure(tmp_path: Path) -> None:
    from crgpr.report.uq import band_figure, reliability_diagram

    rng = np.random.default_rng(0)
    n_t, n_nodes, S = 50, 7, 12
    s = np.linspace(0, 0.5, n_nodes)
    base = np.stack([np.broadcast_to(s, (n_t, n_nodes)), np.zeros((n_t, n_nodes)),
                     np.zeros((n_t, n_nodes))], axis=-1)
    arr = base + 0.01 * rng.standard_normal((S, 1, 1, 3)) * s[None, None, :, None]
    rows = [{"method": m, "theta0_deg": a, "n_diverged": 0, **r} for m in ("a", "b") for a in (60.0, 125.0)
            for r in coverage_rows(arr, base, LEVELS, [4, S])]
    df = pd.DataFrame(rows)[list(COVERAGE_COLUMNS)]
    reliability_diagram(pd.concat([df, summary_rows(df)], ignore_index=True), tmp_path / "rel.png")
    band_figure(arr[..., :2], np.linspace(0, 1, n_t), base[..., :2], 95.0, (0.5, 1.0), tmp_path / "band.png",
                "a", 125.0, base[..., :2])
    for f in ("rel.png", "band.png"):
        png = (tmp_path / f).read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_uq_settings_cross_checks() -> None:
    from crgpr.config import ConfigError, load_config

    u = dict(load_config("tests/smoke_config.yaml")["uq"])
    assert UQSettings.from_section(u).levels == LEVELS
    with pytest.raises(ConfigError, match="uq.paper_n_samples"):
        UQSettings.from_section({**u, "paper_n_samples": u["n_samples"] + 1})
    with pytest.raises(ConfigError, match="uq.figure_level"):
        UQSettings.from_section({**u, "figure_level": 99})
    with pytest.raises(ConfigError, match="jackknife_covariance needs uq.sampler sparse_pathwise"):
        UQSettings.from_section({**u, "posterior_scale": "jackknife_covariance", "sampler": "exact_pathwise"})


def test_angles_batched_equal_each_angle_alone_and_resume_exactly(model_dir: Path, tmp_path: Path) -> None:
    """All angles in one batch of S x A rods give, per angle, the numbers of that angle alone; a
    member made to run away is dropped and the others resume from the last good record bit for
    bit (no restart from t = 0)."""
    names = ("q_x", "q_y", "dH_dtheta", *MOMENTUM_MODELS)
    for m in names:
        sample_model(model_dir / m, m, SETTINGS, 13, tmp_path / f"{m}.npz", tmp_path / f"{m}.json")
    smp = load_samples({m: tmp_path / f"{m}.npz" for m in names})
    center = json.loads((model_dir / "q_x.json").read_text())["theta_center"]
    both = rollout_samples_angles(smp, "paper", PARAMS, center, [125.0, 60.0], SHORT)
    for a in (125.0, 60.0):
        t, q, p, keep, div = rollout_samples(smp, "paper", PARAMS, center, a, SHORT)
        tb, qb, pb, keepb, divb = both[a]
        assert div == divb == [] and np.array_equal(keep, keepb)
        assert np.array_equal(t, tb) and np.array_equal(q, qb) and np.array_equal(p, pb)
    smp["dH_dp_theta"].values[3] *= 1e9  # sample 3: a runaway angular velocity
    after = rollout_samples_angles(smp, "paper", PARAMS, center, [125.0, 60.0], SHORT)
    for a in (125.0, 60.0):
        t2, q2, p2, keep2, div2 = after[a]
        t, q, p, keep, _ = both[a]
        assert [d["sample"] for d in div2] == [3] and 3 not in keep2
        assert np.array_equal(t2, t)
        rows = np.searchsorted(keep, keep2)
        assert np.array_equal(q2, q[rows]) and np.array_equal(p2, p[rows])


def test_a_run_resumed_from_a_record_equals_the_uninterrupted_run(model_dir: Path) -> None:
    """The resume of ``rollout_samples_angles``: the scheme's state at a record, (q, p), fixes the
    rest of the run, so integrating in two pieces gives the one-piece numbers bit for bit."""
    from crgpr.physics.integrator import rod_length, run_hamiltonian
    from crgpr.physics.rod import free_mask, straight_rod

    rod = LearnedRod.from_dir(model_dir, "paper", PARAMS)
    q0 = straight_rod(np.radians(125.0), PARAMS)
    args = (rod.force, rod.velocity, free_mask(PARAMS), PARAMS.zeta, SHORT.dt)
    kw = {"velocity_slope": rod.velocity_slope, "length": rod_length(q0)}
    n, every = SHORT.n_steps, SHORT.record_every
    whole = run_hamiltonian(q0, np.zeros_like(q0), *args, n, every, rod.wds, **kw)
    r = (n // every) // 2
    first = run_hamiltonian(q0, np.zeros_like(q0), *args, r * every, every, rod.wds, **kw)
    rest = run_hamiltonian(first.q[-1], first.v[-1], *args, n - r * every, every, rod.wds, **kw)
    assert np.array_equal(np.concatenate([first.q[:-1], rest.q]), whole.q)
    assert np.array_equal(np.concatenate([first.v[:-1], rest.v]), whole.v)
