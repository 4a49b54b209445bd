"""The learned bending law's rest state is decided by the data (learning/laws.py, crgpr learn)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crgpr.commands.camera import camera_frame
from crgpr.commands.learn import learn, load_learned
from crgpr.config import ConfigError, load_config, rod_params, validate_schema
from crgpr.gp import load_model
from crgpr.io import read_parquet, write_parquet
from crgpr.learning.extrapolation import TangentContinuation
from crgpr.learning.gradient_models import subset_keeping_extremes
from crgpr.learning.law_tables import bending_tangent
from crgpr.learning.laws import rest_state
from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import simulate, trajectory_frame

SMOKE = "tests/smoke_config.yaml"
EI = 0.0024  # a bending stiffness of the order of the config's rod [N m^2]


def _record(c: float, n: int = 2000, seed: int = 0, noise: float = 1e-4):
    """Curvatures of a damped oscillation about 1/m (time-ordered, mostly one way) and a cubic
    law odd about c, with target noise."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, n)
    kappa = 1.0 + 3.0 * np.exp(-t) * np.cos(9.0 * t) + 0.05 * rng.standard_normal(n)
    d = kappa - c
    return kappa, EI * d * (1.0 + 0.05 * d**2) + noise * rng.standard_normal(n)


def test_rest_curvature_of_an_odd_law_is_recovered_within_its_band():
    kappa, m = _record(c=1.7)
    r = rest_state(kappa, m, degree=3, blocks=10)
    assert r.symmetric
    assert r.band_lo <= 1.7 <= r.band_hi and r.band_hi - r.band_lo < 0.2, r


def test_a_strongly_stiffening_law_raises_the_degree_and_finds_its_rest_curvature():
    """m = EI sinh(beta (kappa - c)) / beta, beta = 0.08 m, about c = -2 /m, from exact targets of
    a record that bends it far (|kappa - c| up to 60 /m): the cubic's misfit at large curvature
    moves its c off the truth by over 0.3 /m; the degree is raised while the held-out blocks
    support it and the c of the raised law is the truth to 0.01 /m."""
    t = np.linspace(0.0, 2.0, 4000)
    kappa = -2.0 + 60.0 * np.exp(-0.3 * t) * np.cos(7.0 * t)
    m = EI * np.sinh(0.08 * (kappa + 2.0)) / 0.08
    cubic = rest_state(kappa, m, 3, 10)
    raised = rest_state(kappa, m, 3, 10, max_degree=7)
    assert abs(cubic.kappa_rest + 2.0) > 0.3, cubic
    assert raised.degree > 3 and raised.degree_steps[0]["taken"], raised
    assert abs(raised.kappa_rest + 2.0) < 0.01 and raised.symmetric, raised


def test_a_cubic_law_keeps_the_cubic_degree():
    """The law is the cubic of ``_record`` with target noise: no higher degree predicts the
    held-out blocks better, D stays 3 and c is the one of the fixed-degree fit."""
    kappa, m = _record(c=1.7)
    fixed, sel = rest_state(kappa, m, 3, 10), rest_state(kappa, m, 3, 10, max_degree=7)
    assert sel.degree == 3 and not sel.degree_steps[-1]["taken"], sel
    assert sel.kappa_rest == fixed.kappa_rest


def test_a_law_that_is_not_odd_about_any_curvature_is_not_mirrored():
    kappa, _ = _record(c=0.0)
    m = EI * (kappa + 0.4 * kappa**2)  # stiffer one way than the other (an asymmetric section)
    r = rest_state(kappa, m, degree=3, blocks=10)
    assert not r.symmetric and r.heldout_mse_general < r.heldout_mse_odd, r


def test_a_saturating_law_seen_one_way_is_still_odd():
    """A softening law odd about 0 (m = m_s tanh(EI kappa / m_s)) that the record bends mostly one
    way: the odd law (D + 1 odd terms) and the general one (degree D) have as many coefficients, so
    the general law cannot win on flexibility alone (at equal degree it had twice the terms)."""
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 2.0, 3000)
    kappa = -40.0 * np.exp(-0.8 * t) * (1.0 + np.cos(9.0 * t)) / 2.0 + 2.0 * np.sin(5.0 * t)
    m_s = 0.05
    m = m_s * np.tanh(EI * kappa / m_s) + 1e-6 * rng.standard_normal(kappa.size)
    r = rest_state(kappa, m, degree=3, blocks=10)
    assert r.symmetric and r.band_lo <= 0.0 <= r.band_hi, r


def _segments_record(rest: np.ndarray, seed: int = 4):
    """Time-major samples of five segments, each with a stiffness of its own (graded along s)
    and a stiffening law odd about its own rest curvature ``rest`` (5,)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, 600)[:, None]
    j = np.arange(5)[None, :]
    kappa = (30.0 - 5.0 * j) * np.exp(-t) * np.cos(9.0 * t) + 0.3 * rng.standard_normal((600, 5))
    d = kappa - rest[None, :]
    m = EI * (1.5 - 0.2 * j) * np.sinh(0.05 * d) / 0.05 + 1e-6 * rng.standard_normal(kappa.shape)
    return kappa.ravel(), m.ravel(), np.tile(np.arange(5), 600)


def test_a_graded_law_odd_about_one_rest_curvature_is_mirrored_segment_by_segment():
    """With s as an input each segment has a law of its own about one shared rest curvature: the
    graded law is odd about 0."""
    kappa, m, groups = _segments_record(np.zeros(5))
    r = rest_state(kappa, m, 3, 10, groups)
    assert r.symmetric and r.band_lo <= 0.0 <= r.band_hi and r.band_hi - r.band_lo < 0.5, r


def test_a_rest_curvature_that_varies_along_the_rod_is_not_mirrored():
    kappa, m, groups = _segments_record(np.linspace(3.0, -3.0, 5))
    r = rest_state(kappa, m, 3, 10, groups)
    assert not r.symmetric, r


def test_a_shared_rest_curvature_is_found_where_the_tip_segments_bend_little():
    """A cantilever's segments bend less and less towards the tip (|kappa - c| from 60 /m at the
    clamp to 0.3 /m at the tip) about one rest curvature c = 1.5 /m, with a softening law of
    their own stiffness, from exact targets: the residual of the law about a wrong c is largest
    in the tip segments and its valley about the true c is narrower than a grid over the
    samples' range can resolve (a grid alone put it at 111 /m). With the degree raised as the
    held-out blocks support it, the estimate is the truth to 0.01 /m and the law odd about it."""
    n_seg, c, m_s = 20, 1.5, 0.1
    t = np.linspace(0.0, 2.0, 800)[:, None]
    amp = 60.0 * (1.0 - np.arange(n_seg) / n_seg) ** 2 + 0.3
    kappa = c + amp[None, :] * (np.exp(-0.5 * t) * np.cos(8.0 * t) - 0.3)
    ei = EI * np.linspace(1.0, 0.5, n_seg)[None, :]
    m = m_s * np.tanh(ei * (kappa - c) / m_s)
    groups = np.tile(np.arange(n_seg), t.size)
    r = rest_state(kappa.ravel(), m.ravel(), 3, 10, groups, kappa0=0.0, max_degree=7)
    assert r.degree > 3 and abs(r.kappa_rest - c) < 0.01, r
    assert r.symmetric and r.nominal_rejected, r


@pytest.mark.parametrize("rest", [0.0, 0.5])
def test_the_nominal_rest_curvature_is_kept_unless_the_estimate_predicts_better(rest):
    """The odd law about the nominal kappa0 = 0 against the odd law about the estimate, on the
    held-out blocks: a graded law odd about 0 keeps 0 (the blocks predict no better about c);
    a rod bent at rest by 0.5 /m rejects 0 and is mirrored about its estimate (a uniform law),
    or not at all (a law along s)."""
    kappa, m, groups = _segments_record(np.full(5, rest))
    r = rest_state(kappa, m, 3, 10, groups, kappa0=0.0)
    assert r.symmetric and r.kappa0_nominal == 0.0
    if rest == 0.0:
        assert not r.nominal_rejected and r.heldout_log_ratio_nominal <= 0.0, r
        assert r.mirror_about(0.0, estimate=False) == 0.0
    else:
        assert r.nominal_rejected and r.heldout_mse_nominal > r.heldout_mse_odd, r
        assert r.mirror_about(0.0, estimate=False) is None
        assert r.mirror_about(0.0) == pytest.approx(0.5, abs=0.05)


@pytest.mark.parametrize("log_ratio", [-0.3, 0.0, 0.3])
def test_a_narrow_band_that_misses_kappa0_does_not_alone_refuse_it(log_ratio):
    """From exact full-state moments the jackknife band of c can be narrower than the misfit of
    the polynomial law moves c (a graded rod odd about 0: band 0.0007-0.0119 /m): kappa0 is
    refused only where the held-out blocks also predict better about c (mean log ratio > 0)."""
    kappa, m, groups = _segments_record(np.zeros(5))
    r = replace(rest_state(kappa, m, 3, 10, groups, kappa0=0.0), kappa_rest=0.006, band_lo=0.001,
                band_hi=0.012, heldout_log_ratio_nominal=log_ratio, heldout_log_ratio_nominal_se=0.2,
                nominal_rejected=False)
    refused = log_ratio > 0
    assert r.mirror_about(0.0, estimate=False) == (None if refused else 0.0)
    assert r.mirror_about(0.0) == (0.006 if refused else 0.0)
    assert replace(r, kappa0_nominal=None).mirror_about(0.0) == 0.006  # not compared: the band decides


def test_a_rest_curvature_far_outside_the_band_needs_no_significant_held_out_gain():
    """A pre-curved rod's camera record (c = 1.97 /m, se 0.04 /m, nominal kappa0 = 0): a rest
    curvature shifts the moment by EI c only, small against the moment targets' noise, so the
    held-out blocks favoured c by +0.38 +- 0.19, short of 1.96 standard errors. Mirrored about
    the nominal 0 on that account, the rod's learned law was wrong by its whole rest curvature
    (0.23 rad at the test angles, worse than the nominal rod); the band decides, and the blocks
    only veto by their sign."""
    kappa, m, groups = _segments_record(np.full(5, 2.0))
    r = replace(rest_state(kappa, m, 3, 10, groups, kappa0=0.0), kappa_rest=1.97, band_lo=1.89, band_hi=2.05,
                heldout_log_ratio_nominal=0.38, heldout_log_ratio_nominal_se=0.19, nominal_rejected=False)
    assert r.mirror_about(0.0) == 1.97
    assert r.mirror_about(0.0, estimate=False) is None  # a law along s: not mirrored
    assert replace(r, heldout_log_ratio_nominal=-0.05).mirror_about(0.0) == 0.0


def test_a_law_mirrored_about_an_estimated_rest_curvature_is_offered_a_rest_shift_along_the_rod():
    """The profile along s the record fit offers a bending law learned from positions: a law along
    s gets the stiffness factor and the rest shift (``stiffness_terms``, ``rest_terms``); a
    uniform law mirrored about a rest curvature the data estimated gets the rest shift's variation
    along s alone (``estimated_rest_terms`` terms P_1.., the level fixed at the estimate): one c
    cannot hold a rest curvature that varies along the rod; a law mirrored about the nominal
    kappa0, and any law from the full state, get none."""
    from crgpr.commands.learn import _profile_terms

    cfg = load_config(SMOKE)
    cfg["camera"]["learn"]["record_fit"]["profile"] = {"stiffness_terms": 2, "rest_terms": 1,
                                                       "estimated_rest_terms": 3}
    assert _profile_terms(cfg, True, True, False) == (2, 1, True)
    assert _profile_terms(cfg, True, False, True) == (0, 4, False)
    assert _profile_terms(cfg, True, False, False)[:2] == (0, 0)
    assert _profile_terms(cfg, False, True, True)[:2] == (0, 0)


@settings(max_examples=25, deadline=None)
@given(n=st.integers(2, 60), seed=st.integers(0, 10_000))
def test_a_training_subset_keeps_the_least_and_largest_input(n, seed):
    x = np.random.default_rng(seed).standard_normal(61)
    idx = subset_keeping_extremes(x, n, np.random.default_rng(seed))
    assert idx.size == n and np.all(np.diff(idx) > 0)
    assert x[idx].min() == x.min() and x[idx].max() == x.max()


@settings(max_examples=15, deadline=None)
@given(shift=st.floats(-5.0, 5.0), c=st.floats(-1.0, 3.0))
def test_rest_curvature_moves_with_the_curvature_axis(shift, c):
    """Relabelling curvature by a constant moves the estimated rest curvature by the same constant."""
    kappa, m = _record(c=c, seed=1)
    a, b = rest_state(kappa, m, 3, 8), rest_state(kappa + shift, m, 3, 8)
    assert b.kappa_rest == pytest.approx(a.kappa_rest + shift, abs=1e-6)
    assert b.se == pytest.approx(a.se, rel=1e-3, abs=1e-8) and b.symmetric == a.symmetric


def test_rest_state_rejects_an_even_degree():
    kappa, m = _record(c=0.0)
    with pytest.raises(ValueError, match="degree"):
        rest_state(kappa, m, degree=2, blocks=10)


def test_schema_rejects_an_even_rest_degree():
    import copy

    cfg = copy.deepcopy(load_config(SMOKE))
    cfg["camera"]["learn"]["rest_degree"] = 2
    with pytest.raises(ConfigError, match="rest_degree"):
        validate_schema(cfg)


@pytest.fixture(scope="module")
def precurved_models(tmp_path_factory, smoke_training_run):
    """A pre-curved smoke rod (rest curvature 2 /m, the nominal rod's 0) learned from its full
    state and from 1 mm camera positions, the rest state estimated (the config's auto)."""
    cfg, tr = smoke_training_run
    truth = replace(tr.params, kappa0=2.0)
    rec = simulate(85.0, truth, SimSettings(dt=1e-4, t_end=0.4, record_every=40, scheme="variational"))
    d = tmp_path_factory.mktemp("precurved")
    write_parquet(trajectory_frame(rec), d / "full.parquet")
    learn(d / "full.parquet", d / "auto", cfg, "objective", "gp")
    write_parquet(camera_frame(rec.t, rec.q, 1e-3, np.random.default_rng(5)), d / "camera.parquet")
    learn(d / "camera.parquet", d / "camera", cfg, "objective", "gp")
    return cfg, d, truth


def test_precurved_rods_rest_curvature_is_recovered_within_its_band(precurved_models):
    cfg, d, truth = precurved_models
    model, man = load_learned(d / "auto")
    rest = man["rest_state"]
    assert man["rod"]["kappa0"] == 0.0  # the nominal rod knows nothing of the rest curvature
    assert rest["symmetric"] and rest["band_lo"] <= truth.kappa0 <= rest["band_hi"], rest
    assert man["bending_odd_about"] == rest["kappa_rest"]
    # the learned moment vanishes at the rest curvature and is odd about it
    c, k = rest["kappa_rest"], 1.5
    X = np.zeros((3, 5))
    X[:, 0] = [c - k, c, c + k]
    m = model.components["obj_m"](X)
    assert abs(m[1]) < 0.05 * abs(m[2]) and m[2] == pytest.approx(-m[0], rel=0.05), m
    assert m[2] == pytest.approx(k * truth.EI, rel=0.1)


def test_precurved_rods_rest_curvature_is_recovered_from_1mm_camera_positions(precurved_models):
    _, d, truth = precurved_models
    man = load_learned(d / "camera")[1]
    rest = man["rest_state"]
    assert man["input"] == "positions" and rest["symmetric"], rest
    assert rest["band_lo"] <= truth.kappa0 <= rest["band_hi"]
    assert man["bending_odd_about"] == rest["kappa_rest"]


def test_learned_law_is_written_as_a_table_and_figure_with_its_covered_range(precurved_models):
    cfg, d, truth = precurved_models
    man = load_learned(d / "auto")[1]
    assert man["law_table"] == "laws.parquet" and (d / "auto" / "laws.png").stat().st_size > 0
    tab = read_parquet(d / "auto" / man["law_table"])
    m = tab[(tab["law"] == "obj_m") & (tab["input"] == "kappa")]
    assert len(m) == cfg["camera"]["learn"]["law_table"]["n_grid"]
    lo, hi = man["law_inputs_covered"]["obj_m"]["kappa"]
    arrays, _ = load_model(d / "auto" / "obj_m")
    assert (lo, hi) == (arrays["X"].min(), arrays["X"].max())
    assert m["covered"].to_numpy().any() and (~m["covered"].to_numpy()).any()
    # every learned model's inputs have their covered range in the manifest
    assert set(man["law_inputs_covered"]) == set(man["models"])
    # the nominal law beside it is the nominal rod's m = EI (kappa - kappa0), kappa0 = 0
    assert np.allclose(m["nominal"], truth.EI * m["x"])
    # beyond the covered range: the GP's mean out to its reach, the tangent beyond it, in the
    # table and in the rod the rollouts integrate (learning.extrapolation)
    ex = man["bending_extrapolation"]
    assert ex["lo"] <= lo and ex["hi"] >= hi and (ex["covered_lo"], ex["covered_hi"]) == (lo, hi)
    assert np.array_equal(m["continued"].to_numpy(), ((m["x"] > ex["hi"]) | (m["x"] < ex["lo"])).to_numpy())
    assert isinstance(load_learned(d / "auto")[0].components["obj_m"], TangentContinuation)
    # the least tangent stiffness over the covered range: the law of a linear rod, positive
    tangent = man["bending_tangent"]
    assert tangent["kappa_range"] == [lo, hi] and 0.5 < tangent["min_over_EI"] < 1.5
    assert lo <= tangent["at_kappa"] <= hi


def test_the_least_tangent_stiffness_of_a_bending_law_is_found_where_a_warp_bends_it_down(tmp_path):
    """The nominal law EI kappa times the warp w = 1 - 0.9 u^4, u = kappa / 20 1/m: its tangent
    EI (1 - 4.5 u^4) is negative beyond |u| = 0.69 and least at the covered edges, -3.5 EI; the
    nominal law unwarped has EI everywhere."""
    P = replace(rod_params(load_config(SMOKE)), kappa0=0.0)
    warp = (0.0, 20.0, np.array([0.0, 0.0, -0.9]), np.zeros(0), np.zeros(0))
    t = bending_tangent(tmp_path, [], P, -20.0, 20.0, 401, warp)
    assert -3.5 < t["min_over_EI"] < -3.3 and abs(abs(t["at_kappa"]) - 20.0) < 0.2, t
    assert np.isclose(bending_tangent(tmp_path, [], P, -20.0, 20.0, 401)["min_over_EI"], 1.0)


def test_posterior_sd_of_a_learned_law_grows_beyond_its_covered_range(precurved_models):
    _, d, _ = precurved_models
    tab = read_parquet(d / "auto" / "laws.parquet")
    m = tab[(tab["law"] == "obj_m") & (tab["input"] == "kappa")].sort_values("x")
    inside, sd = m["covered"].to_numpy(), m["sd"].to_numpy()
    assert np.all(np.isfinite(sd)) and np.all(sd >= 0)
    # at both ends of the grid (half the covered width beyond it) the sd exceeds every sd inside
    assert sd[0] > sd[inside].max() and sd[-1] > sd[inside].max(), (sd[0], sd[inside].max(), sd[-1])
