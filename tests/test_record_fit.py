"""The record fit (learning/record_fit.py, learning/warp.py): the learned rod fitted to its own
training record by output error, its start and a warp of its bending law, kept only where the
warp forecasts held-out blocks of the record better."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crgpr.config import load_config, rod_params
from crgpr.learning.learned import LearnedRod, rollout
from crgpr.learning.lm import levenberg_marquardt, levenberg_marquardt_batch
from crgpr.learning.nominal import NOMINAL_LAWS, NominalLaw
from crgpr.learning.record_fit import fit_record, start_state, tail_factor
from crgpr.learning.warp import (
    BendingWarp,
    admissible,
    law_factor,
    manifest_warp,
    profile_factor,
    rest_shift,
    segment_positions,
    warp_factor,
    warp_sd,
)
from crgpr.physics.params import SimSettings

finite = st.floats(-0.5, 0.5, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(center=st.floats(-5, 5), scale=st.floats(1, 80), a=st.lists(finite, min_size=1, max_size=4),
       d=st.floats(0, 200))
def test_warp_is_even_about_its_centre_and_constant_beyond_the_covered_range(center, scale, a, d):
    w_plus = warp_factor(np.array([center + d]), center, scale, np.array(a))
    w_minus = warp_factor(np.array([center - d]), center, scale, np.array(a))
    assert np.allclose(w_plus, w_minus, rtol=1e-12, atol=1e-12)
    assert warp_factor(np.array([center + d]), center, scale, np.zeros(len(a)))[0] == 1.0
    if d >= scale:  # beyond the training range: the edge value 1 + sum a_k, not the polynomial
        assert math.isclose(w_plus[0], 1.0 + sum(a), rel_tol=1e-12, abs_tol=1e-12)


@settings(max_examples=60, deadline=None)
@given(a=st.lists(st.lists(finite, min_size=5, max_size=5), min_size=1, max_size=3),
       terms=st.integers(1, 5), seed=st.integers(0, 2**16))
def test_the_compiled_warp_is_its_formula_term_by_term(a, terms, seed):
    """warp_factor (a compiled loop on the rollouts' path) equals 1 + sum_k a_k u^(2k) written
    with arrays, for one warp and for one warp per batch member: bit for bit up to u^4, within
    4 ulp of the terms' size from u^6 on (the compiled pow and numpy's may round their last bit apart)."""
    A = np.array(a)[:, :terms]
    kappa = np.random.default_rng(seed).normal(0.0, 40.0, (A.shape[0], 3, 7))
    u2 = np.minimum(((kappa - 1.5) / 30.0) ** 2, 1.0)
    batched, single = np.ones_like(u2), np.ones_like(u2)
    for k in range(terms):  # 1, then each term added in turn
        batched = batched + A[:, k].reshape(-1, 1, 1) * u2**k
        single = single + A[0, k] * u2**k
    if terms <= 3:
        assert np.array_equal(warp_factor(kappa, 1.5, 30.0, A), batched)
        assert np.array_equal(warp_factor(kappa, 1.5, 30.0, A[0]), single)
    else:  # 4 ulp of the terms' own size (a sum near 0 has no ulp scale of its own)
        size = 1.0 + np.abs(A).sum(1).reshape(-1, 1, 1)
        eps = np.finfo(float).eps
        assert np.all(np.abs(warp_factor(kappa, 1.5, 30.0, A) - batched) <= 4 * eps * size)
        assert np.all(np.abs(warp_factor(kappa, 1.5, 30.0, A[0]) - single) <= 4 * eps * size[0])


def test_a_states_only_rollout_has_the_same_states():
    """The record fit's rollouts book no energies (book_energy=False); the states are the
    rollout's own, bit for bit."""
    P = rod_params(load_config("tests/smoke_config.yaml"))
    comps = {name: NominalLaw(law, P) for law, name in NOMINAL_LAWS.items()}
    comps["obj_m"] = BendingWarp(comps["obj_m"], 0.0, 30.0, np.array([0.1, -0.2, 0.05]))
    model = LearnedRod(comps, "objective", P, None, 1e-5)  # with a bending damping
    st_ = SimSettings(dt=1e-4, t_end=0.05, record_every=10, scheme="variational")
    full = rollout(model, 85.0, st_)
    states = rollout(model, 85.0, st_, book_energy=False)
    assert np.array_equal(full.q, states.q) and np.array_equal(full.p, states.p)
    assert full.force_work is not None and states.force_work is None
    assert np.all(full.dissipated[1:] > 0) and np.all(states.dissipated == 0)


def test_warp_keeps_the_laws_zero_and_warps_each_batch_member_by_its_own_row():
    P = rod_params(load_config("tests/smoke_config.yaml"))
    law = NominalLaw("m", P)
    X = np.zeros((3, P.N, 5))
    X[..., 0] = np.linspace(-30, 30, P.N)
    A = np.array([[0.0, 0.0], [0.1, 0.0], [0.0, 0.2]])
    batched = BendingWarp(law, 0.0, 30.0, A)(X)
    for b in range(3):
        single = BendingWarp(law, 0.0, 30.0, A[b])(X[b])
        assert np.array_equal(batched[b], single)
    assert np.array_equal(batched[0], law(X[0]))
    at_rest = np.zeros((1, 5))
    assert BendingWarp(law, 0.0, 30.0, np.array([0.3, -0.2]))(at_rest)[0] == 0.0
    assert manifest_warp({"kept": False, "center": 0, "kappa_scale": 1, "coefficients": [0.1]}) is None


@settings(max_examples=40, deadline=None)
@given(b=st.lists(finite, min_size=1, max_size=4), a=st.lists(finite, min_size=1, max_size=3))
def test_a_profile_along_s_is_positive_and_scales_each_segment_by_its_own_factor(b, a):
    """v(s) = exp(sum_j b_j P_j(2 s/L - 1)) > 0 for any coefficients, 1 without them; the wrapped
    law is m w(kappa) v(s_j) at segment j, batched by rows; the table's factor (``law_factor`` at
    the segments' mid-points) is the rollout's; and the delta-method sd of w v matches the
    spread of w v over coefficients drawn from their covariance."""
    P = rod_params(load_config("tests/smoke_config.yaml"))
    law = NominalLaw("m", P)
    b, a = np.array(b), np.array(a)
    s_rel = segment_positions(P.N)
    v = profile_factor(s_rel, b)
    assert np.all(v > 0) and np.array_equal(profile_factor(s_rel, np.zeros_like(b)), np.ones(P.N))
    X = np.zeros((2, P.N, 5))
    X[..., 0] = np.linspace(-20, 20, P.N)
    B = np.stack([b, np.zeros_like(b)])
    out = BendingWarp(law, 0.0, 30.0, np.stack([a, a]), B)(X)
    w = warp_factor(X[0, :, 0], 0.0, 30.0, a)
    assert np.allclose(out[0], law(X[0]) * w * v, rtol=1e-12, atol=1e-15)
    assert np.allclose(out[1], law(X[1]) * w, rtol=1e-12, atol=1e-15)
    warp = (0.0, 30.0, a, b, np.zeros(0))
    assert np.allclose(law_factor(X[0, :, 0], s_rel, warp), w * v, rtol=1e-12)
    C = np.diag(np.full(a.size + b.size, 1e-6))
    draws = np.random.default_rng(0).multivariate_normal(np.r_[a, b], C, size=4000)
    spread = np.std([law_factor(X[0, :, 0], s_rel, (0.0, 30.0, d[:a.size], d[a.size:], np.zeros(0)))
                     for d in draws], axis=0)
    assert np.allclose(warp_sd(X[0, :, 0], s_rel, warp, C), spread, rtol=0.1)


def test_a_kept_fit_without_warp_or_profile_terms_has_no_factor_band_but_its_truncation():
    """A record fit that keeps only its start (or a damping) has no warp or profile coefficient:
    the factor is 1 and its sd 0, whatever covariance of other parameters it records; a
    truncation estimate still adds its own part."""
    kappa = np.linspace(-20.0, 20.0, 7)
    s_rel = segment_positions(7)
    warp = (0.0, 30.0, np.zeros(0), np.zeros(0), np.zeros(0))
    cov = np.diag([1e-4, 1e-4])  # e.g. the start's modes: not the factor's
    assert np.array_equal(law_factor(kappa, s_rel, warp), np.ones(7))
    assert np.array_equal(warp_sd(kappa, s_rel, warp, cov), np.zeros(7))
    assert np.array_equal(warp_sd(kappa, None, warp, cov), np.zeros(7))
    d = np.array([0.01, 0.002])
    assert np.allclose(warp_sd(kappa, s_rel, warp, cov, d), np.abs(warp_factor(kappa, 0.0, 30.0, d) - 1.0))


def test_an_admissible_warp_keeps_the_laws_sign_over_the_covered_range():
    assert admissible(np.array([[0.1, 0.2], [-0.5, 0.3], [0.0, 0.0]])).all()
    assert not admissible(np.array([[-0.012, -84.4, -1.7e5]]))[0]  # reverses the law near |u| = 1
    assert list(admissible(np.array([[0.0, -1.5], [0.0, -0.5]]))) == [False, True]


def test_start_state_of_a_rigidly_rotating_rod_is_that_rod():
    """Zero corrections: positions rebuilt at the rest strains from the clamped base, linear
    momenta rho A omega s (-sin, cos) of a rigid rotation, angles and rates as derived; the
    corrections leave the clamped node alone."""
    P = rod_params(load_config("tests/smoke_config.yaml"))
    th0, om = 1.1, 0.7
    s = np.linspace(0, P.L0, P.N + 1)
    arr = {"x": (s * math.cos(th0))[None], "y": (s * math.sin(th0))[None],
           "theta": np.full((1, P.N + 1), th0), "p_theta": np.r_[0.0, np.full(P.N, P.rhoI * om)][None]}
    q, p = start_state(arr, P, np.zeros((1, 4)), 2)
    assert np.allclose(q[0, :, 0], s * math.cos(th0), atol=1e-15)
    assert np.allclose(q[0, :, 1], s * math.sin(th0), atol=1e-15)
    # the base node's rate is clamped to 0: the first segment turns at omega / 2 (mid-segment mean)
    omega_bar = np.r_[0.5 * om, np.full(P.N - 1, om)]
    v_expected = np.r_[0.0, np.cumsum(P.ds * omega_bar)]
    assert np.allclose(p[0, :, 0], -P.rhoA * math.sin(th0) * v_expected, atol=1e-15)
    assert np.allclose(p[0, :, 1], P.rhoA * math.cos(th0) * v_expected, atol=1e-15)
    qb, pb = start_state(arr, P, np.array([[0.1, -0.2, 0.5, 0.3]]), 2)
    assert np.array_equal(qb[0, 0], q[0, 0]) and np.array_equal(pb[0, 0], p[0, 0])
    assert not np.allclose(qb[0, -1], q[0, -1])


def _nominal_rod(P, warp: np.ndarray | None, scale: float, damping: float = 0.0,
                 profile: np.ndarray | None = None, rest: np.ndarray | None = None) -> LearnedRod:
    comps = {c: NominalLaw(law, P) for law, c in NOMINAL_LAWS.items()}
    if warp is not None:
        comps["obj_m"] = BendingWarp(comps["obj_m"], 0.0, scale, warp, profile, rest)
    return LearnedRod(comps, "objective", P, None, damping)


def _exact_record(P, true_warp: np.ndarray, scale: float, damping: float = 0.0,
                  profile: np.ndarray | None = None, rest: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """A 0.4 s release from 80 deg of the rod whose bending law is the nominal one times
    ``true_warp`` (and its ``profile`` and ``rest`` shift along s; with a bending damping c), its
    full state as recorded."""
    sim = SimSettings(dt=1e-4, t_end=0.4, record_every=40, scheme="variational")
    tr = rollout(_nominal_rod(P, true_warp, scale, damping, profile, rest), 80.0, sim)
    return {"t": tr.t, "x": tr.q[..., 0], "y": tr.q[..., 1], "theta": tr.q[..., 2].copy(),
            "p_x": tr.p[..., 0], "p_y": tr.p[..., 1], "p_theta": tr.p[..., 2].copy()}


def _record(P, true_warp: np.ndarray, scale: float, noise: float, seed: int,
            rest: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """``_exact_record``, its first frame's derived angles and rates off by a smooth error (what
    the derived start of a camera record has), its angles with iid noise."""
    arr = _exact_record(P, true_warp, scale, rest=rest)
    s = np.linspace(0, 1, P.N + 1)
    arr["theta"] += np.random.default_rng(seed).normal(0, noise, arr["theta"].shape) * (s > 0)
    arr["theta"][0] += 0.02 * s**2
    arr["p_theta"][0] += P.rhoI * 0.5 * s
    return arr


@pytest.fixture(scope="module")
def smoke():
    cfg = load_config("tests/smoke_config.yaml")
    rf = copy.deepcopy(cfg["camera"]["learn"]["record_fit"])
    rf.update(start_modes=2, warp_terms=[1])
    return rod_params(cfg), SimSettings(dt=1e-4, t_end=0.4, record_every=40, scheme="variational"), rf


def test_a_stiffer_law_is_recovered_from_its_record_and_kept(smoke):
    """The law 8 % stiffer than the learned one: the fit finds the factor (to 1 %), fits the
    start's error away and keeps the warp (it forecasts the held-out blocks better)."""
    P, sim, rf = smoke
    arr = _record(P, np.array([0.08]), 20.0, 1e-4, seed=1)
    fit = fit_record(lambda W, c: _nominal_rod(P, W, 20.0, c), arr, P, sim, 0.0, 20.0, rf)
    assert fit.kept, fit
    assert abs(fit.coefficients[0] - 0.08) < 0.01, fit
    assert fit.rmse_fitted < 0.2 * fit.rmse_learned and fit.heldout_log_ratio > 0


def test_a_damped_stiffer_rod_from_its_full_state_gets_both_its_damping_and_its_law(smoke):
    """The full state of a rod 8 % stiffer, with a bending damping c: the fit starts from the
    recorded state (no start modes), from c 40 % low, and recovers c (to 2 %) and the factor
    (to 0.5 %); the damping's size is fitted with the start alone too, so the warp is kept only
    for what c cannot explain."""
    P, sim, rf = smoke
    c_true = 4e-5
    arr = _exact_record(P, np.array([0.08]), 20.0, c_true)
    fit = fit_record(lambda W, c: _nominal_rod(P, W, 20.0, c), arr, P, sim, 0.0, 20.0, rf,
                     damping=0.6 * c_true, exact_start=True)
    assert fit.kept and fit.exact_start and fit.start_coefficients == [], fit
    assert abs(fit.damping / c_true - 1.0) < 0.02 and fit.damping_before == 0.6 * c_true, fit
    assert abs(fit.coefficients[0] - 0.08) < 0.005, fit
    assert fit.rmse_fitted < 0.05 * fit.rmse_learned


def test_an_undamped_fit_leaves_the_damping_at_zero(smoke):
    P, sim, rf = smoke
    arr = _exact_record(P, np.array([0.05]), 20.0)
    fit = fit_record(lambda W, c: _nominal_rod(P, W, 20.0, c), arr, P, sim, 0.0, 20.0, rf, exact_start=True)
    assert fit.damping == 0.0 and fit.kept and abs(fit.coefficients[0] - 0.05) < 0.005, fit


def test_no_warp_is_kept_where_the_learned_law_is_the_true_one(smoke):
    P, sim, rf = smoke
    arr = _record(P, np.array([0.0]), 20.0, 1e-3, seed=2)
    fit = fit_record(lambda W, c: _nominal_rod(P, W, 20.0, c), arr, P, sim, 0.0, 20.0, rf)
    assert not fit.kept and fit.coefficients == [] and fit.warp_terms == 0, fit
    assert manifest_warp(fit.to_dict()) is None
    assert fit.rmse_start_only < fit.rmse_learned  # the start is still fitted


def test_a_record_too_short_to_hold_out_keeps_the_law_as_learned(smoke):
    P, sim, rf = smoke
    arr = {k: v[:12] for k, v in _record(P, np.array([0.05]), 20.0, 0.0, seed=3).items()}
    fit = fit_record(lambda W, c: _nominal_rod(P, W, 20.0, c), arr, P, sim, 0.0, 20.0, rf)
    assert not fit.kept and "too short" in fit.note and fit.coefficients == []


def test_more_warp_terms_are_taken_only_where_they_forecast_better_than_fewer(smoke):
    """Candidates of one and two terms (forward selection on the held-out blocks): a law
    stiffer by a constant factor keeps one term; one whose stiffening grows with the curvature
    (w = 1 + 0.02 + 0.4 u^2, u over the record's largest curvature) needs the second, which is
    chosen over the first and found (to 0.03).
    Every comparison is recorded."""
    P, sim, rf = smoke
    rf = {**rf, "warp_terms": [1, 2]}
    stiffer = _record(P, np.array([0.08]), 20.0, 1e-4, seed=1)
    one = fit_record(lambda W, c: _nominal_rod(P, W, 20.0, c), stiffer, P, sim, 0.0, 20.0, rf)
    assert one.kept and one.warp_terms == 1 and len(one.coefficients) == 1, one
    assert [c["terms"] for c in one.candidates] == [1, 2] and one.candidates[0]["chosen"]
    assert not one.candidates[1]["chosen"] and one.candidates[1]["against_terms"] == 1
    true, scale = np.array([0.02, 0.4]), 9.0  # the 80 deg release bends the smoke rod to |kappa| < 9 1/m
    two = fit_record(lambda W, c: _nominal_rod(P, W, scale, c), _record(P, true, scale, 1e-4, seed=4),
                     P, sim, 0.0, scale, rf)
    assert two.kept and two.warp_terms == 2 and two.candidates[1]["chosen"], two
    assert np.allclose(two.coefficients, true, atol=0.03), two
    assert np.asarray(two.coefficient_cov).shape == (2, 2)
    # the truncation estimate: against the next larger candidate where there is one, else the
    # next smaller (here: the u^2 term the one-term warp lacks, as fitted on the record's first part)
    assert one.truncation_terms == 2 and len(one.truncation_coefficients) == 2, one
    assert two.truncation_terms == 1 and -0.5 < two.truncation_coefficients[1] < -0.25, two


def test_a_larger_warp_is_offered_only_while_the_held_out_blocks_take_more_terms(smoke):
    """Candidates of one, two and three terms: the third is fitted only where the second was
    chosen. A law stiffer by a constant factor stops at the second candidate; one whose
    stiffening grows with the curvature (two terms) is offered the third, does not take it, and
    keeps the two-term warp it gets without the third on offer, bit for bit (every candidate is
    fitted from the start-alone fit), with the third as its truncation estimate."""
    P, sim, rf = smoke
    rf = {**rf, "warp_terms": [3, 1, 2]}  # any order: the candidates are taken fewest terms first
    stiffer = _record(P, np.array([0.08]), 20.0, 1e-4, seed=1)
    one = fit_record(lambda W, c: _nominal_rod(P, W, 20.0, c), stiffer, P, sim, 0.0, 20.0, rf)
    assert [c["terms"] for c in one.candidates] == [1, 2] and one.warp_terms == 1, one
    true, scale = np.array([0.02, 0.4]), 9.0
    record = _record(P, true, scale, 1e-4, seed=4)
    two = fit_record(lambda W, c: _nominal_rod(P, W, scale, c), record, P, sim, 0.0, scale, rf)
    assert [c["terms"] for c in two.candidates] == [1, 2, 3] and two.candidates[2]["against_terms"] == 2, two
    assert two.warp_terms == 2 and two.candidates[1]["chosen"] and not two.candidates[2]["chosen"], two
    assert np.allclose(two.coefficients, true, atol=0.03), two
    without = fit_record(lambda W, c: _nominal_rod(P, W, scale, c), record, P, sim, 0.0, scale,
                         {**rf, "warp_terms": [1, 2]})
    assert two.coefficients == without.coefficients and two.candidates[:2] == without.candidates, without
    assert two.truncation_terms == 3 and without.truncation_terms == 1, (two, without)


def test_a_stiffness_profile_along_s_is_found_where_the_law_takes_s_and_not_where_it_is_uniform(smoke):
    """A rod whose stiffness varies along s (v(s) with b = (0.15, -0.08): 24 % softer at the clamp
    than at the tip, graded like a tapered rod) and a learned law that is uniform: offered a
    two-term profile, the fit keeps it (it forecasts the held-out blocks better) and finds b to
    0.02; on a uniform rod (a camera-like start and 1 mrad noise) the profile the same offer
    finds is flat to 1 % (what it absorbs of the derived start's errors, kept or not)."""
    P, sim, rf = smoke
    true_b = np.array([0.15, -0.08])
    arr = _exact_record(P, np.array([0.0]), 20.0, profile=true_b)

    def rod(W, c):
        return _nominal_rod(P, W[:, :1], 20.0, c, W[:, 1:])
    fit = fit_record(rod, arr, P, sim, 0.0, 20.0, rf, exact_start=True, profile_terms=(2, 0))
    assert fit.kept and fit.profile_terms == 2 and fit.profile_log_ratio > 0, fit
    assert np.allclose(fit.profile_coefficients, true_b, atol=0.02), fit
    assert np.asarray(fit.coefficient_cov).shape == (fit.warp_terms + 2,) * 2
    assert np.allclose(manifest_warp(fit.to_dict())[3], fit.profile_coefficients)
    uniform = fit_record(rod, _record(P, np.array([0.0]), 20.0, 1e-3, seed=2), P, sim, 0.0, 20.0, rf,
                         profile_terms=(2, 0))
    b = np.asarray(uniform.profile_coefficients or [0.0])
    assert uniform.coefficients == [] and np.all(np.abs(b) < 0.01), uniform


def test_a_rest_curvature_along_s_shifts_the_laws_input_and_is_found_from_the_record(smoke):
    """The rest shift d(s) moves the law's curvature inputs: the warped law at kappa is the law at
    kappa - d(s_j) (its zero at d(s_j)). A rod whose rest curvature is d(s) = 0.4 + 0.3 P_1 1/m
    (a learned law whose rest curvature is off, more so towards the tip): offered the profile's
    two rest terms alone, the fit keeps them and finds c to 0.03 1/m."""
    P, sim, rf = smoke
    law = NominalLaw("m", P)
    c_true = np.array([0.4, 0.3])
    X = np.zeros((P.N, 5))
    X[:, 0] = np.linspace(-10, 10, P.N)
    d = rest_shift(segment_positions(P.N), c_true)
    shifted = BendingWarp(law, 0.0, 20.0, np.zeros(1), None, c_true)
    assert np.allclose(shifted(X), P.EI * (X[:, 0] - d - P.kappa0), rtol=1e-12, atol=1e-15)
    arr = _exact_record(P, np.array([0.0]), 20.0, rest=c_true)

    def rod(W, c):
        return _nominal_rod(P, W[:, :1], 20.0, c, None, W[:, 1:])
    fit = fit_record(rod, arr, P, sim, 0.0, 20.0, rf, exact_start=True, profile_terms=(0, 2))
    assert fit.kept and fit.rest_terms == 2 and fit.profile_coefficients == [], fit
    assert np.allclose(fit.rest_coefficients, c_true, atol=0.03), fit
    assert np.allclose(manifest_warp(fit.to_dict())[4], fit.rest_coefficients)


def test_a_rest_shift_the_fit_resolves_is_taken_unless_the_held_out_blocks_forecast_worse(smoke):
    """The rest shift's rule: a rest curvature shifts the moment by EI d(s) only, so the held-out
    blocks' test has little power for it; the shift is taken where the fit on the record's first
    part resolves it (Wald statistic above the chi-square 95 % quantile, from the covariance the
    kept warps report) and the blocks do not forecast worse. A rod whose rest curvature grows
    along s (d = 0.3 P_1 1/m; camera-like start, 0.03 rad noise) gains too little on the blocks
    for their test alone, and is taken: d to 0.1 1/m. A uniform
    rod whose noisy record pulls the fit to a spurious shift the covariance calls resolved: the
    held-out blocks forecast worse with it, so it is not taken."""
    from scipy.stats import chi2

    P, sim, rf = smoke

    def rod(W, c):
        return _nominal_rod(P, W[:, :1], 20.0, c, None, W[:, 1:])
    quantile = chi2.ppf(0.95, 2)
    c_true = np.array([0.0, 0.3])
    graded = fit_record(rod, _record(P, np.zeros(1), 20.0, 0.03, 3, c_true), P, sim, 0.0, 20.0, rf,
                        profile_terms=(0, 2))
    assert graded.rest_wald > quantile, graded
    assert 0 < graded.rest_log_ratio < 1.96 * graded.rest_log_ratio_se, graded
    assert graded.kept and np.allclose(graded.rest_coefficients, c_true, atol=0.1), graded
    assert "resolved by the fit" in graded.note, graded.note
    spurious = fit_record(rod, _record(P, np.zeros(1), 20.0, 0.01, 2), P, sim, 0.0, 20.0, rf,
                          profile_terms=(0, 2))
    assert spurious.rest_wald > quantile and spurious.rest_log_ratio < 0, spurious
    assert spurious.rest_coefficients == [] and len(spurious.rest_fitted) == 2, spurious


def test_a_rest_shift_without_its_level_keeps_the_laws_mean_rest_curvature(smoke):
    """``rest_level`` False (a law mirrored about a rest curvature the regression estimated):
    the shift's level c_0 stays exactly 0 and only its variation along s is fitted: a rod whose
    rest curvature grows along s by 0.3 P_1 1/m gets c_1 to 0.03 1/m, one free term."""
    P, sim, rf = smoke

    def rod(W, c):
        return _nominal_rod(P, W[:, :1], 20.0, c, None, W[:, 1:])
    arr = _exact_record(P, np.zeros(1), 20.0, rest=np.array([0.0, 0.3]))
    fit = fit_record(rod, arr, P, sim, 0.0, 20.0, rf, exact_start=True, profile_terms=(0, 2),
                     rest_level=False)
    assert fit.kept and fit.rest_coefficients[0] == 0.0 and abs(fit.rest_coefficients[1] - 0.3) < 0.03, fit
    assert len(fit.rest_fitted) == 1 and len(fit.rest_fitted_sd) == 1, fit


def test_a_rest_shift_on_a_law_without_s_is_shown_and_scored_segment_by_segment(tmp_path):
    """A uniform law (no s input) whose record-fit warp shifts its rest curvature along the rod
    (d(s) = 0.4 + 0.3 P_1 1/m) is one law per segment: ``laws.parquet``'s rows are repeated at
    ``s_points`` values of s from the first segment's mid-point to the last's, each crossing
    zero at d(s); the per-segment law (the study's law scores, the tangent check) is EI (kappa -
    d(s_j)) at every segment j. Without the shift the table keeps one slice (at_s NaN)."""
    from paper_rod import PAPER_ROD

    from crgpr.gp import fit_gp
    from crgpr.learning.law_tables import bending_law_at_segments, law_table

    P = PAPER_ROD
    kappa = np.linspace(-20.0, 20.0, 300)
    fit_gp(kappa[:, None], P.EI * kappa, kernel="se", basis="linear", sigma_n_min=1e-9, standardise_y=True,
           seed=0).save(tmp_path / "obj_m", extra={"features": ["kappa"]})
    c = np.array([0.4, 0.3])
    warp = (0.0, 20.0, np.zeros(1), np.zeros(0), c)
    tab = law_table(tmp_path / "obj_m", "obj_m", ["kappa"], P, n_grid=401, pad=0.0, max_points=300, seed=0,
                    s_points=3, band_blocks=0, floor=False, warp=warp)
    s_at = np.sort(tab["at_s"].unique())
    L = P.N * P.ds
    np.testing.assert_allclose(s_at / L, [0.5 / P.N, 0.5, 1.0 - 0.5 / P.N], rtol=1e-12)
    for sv, g in tab.groupby("at_s"):
        zero = np.interp(0.0, g["mean"].to_numpy(), g["x"].to_numpy())
        assert abs(zero - rest_shift(np.array([sv / L]), c)[0]) < 1e-3, (sv, zero)
    x = np.linspace(-10.0, 10.0, 21)
    mean, _ = bending_law_at_segments(tmp_path, ["obj_m"], P, x, 300, 0, 0, warp, with_sd=False)
    d = rest_shift(segment_positions(P.N), c)
    np.testing.assert_allclose(mean, P.EI * (x[:, None] - d[None, :]), atol=1e-6 * P.EI * 20.0)
    flat = (0.0, 20.0, np.zeros(1), np.zeros(0), np.zeros(0))
    plain = law_table(tmp_path / "obj_m", "obj_m", ["kappa"], P, n_grid=41, pad=0.0, max_points=300, seed=0,
                      s_points=3, band_blocks=0, floor=False, warp=flat)
    assert plain["at_s"].isna().all() and len(plain) == 41


def test_a_tail_softer_than_the_tangent_is_sized_from_the_record(smoke):
    """The law beyond its reach (``learning.extrapolation``): a rod whose law beyond |kappa| = 2
    1/m (the smoke rod's 80 deg release bends it to 3.4 1/m in the fit's first part) stiffens at
    0.4 x its tangent's slope; the learned law is that law with the tangent as it is (g = 1).
    Offered the tail factor with the warp, the fit keeps it and finds g to 0.05, the warp next to
    none; the covariance keeps the warp's terms alone."""

    from crgpr.learning.extrapolation import Reach, TangentContinuation

    P, sim, rf = smoke
    law = NominalLaw("m", P)
    reach = Reach(lo=-2.0, hi=2.0, span=0.5, covered_lo=-2.0, covered_hi=2.0, band=0.2)
    true = LearnedRod({**{c: NominalLaw(k, P) for k, c in NOMINAL_LAWS.items()},
                       "obj_m": TangentContinuation(law, Reach(**{**reach.to_dict(), "slope_factor": 0.4}))},
                      "objective", P, None, 0.0)
    tr = rollout(true, 80.0, sim)
    arr = {"t": tr.t, "x": tr.q[..., 0], "y": tr.q[..., 1], "theta": tr.q[..., 2].copy(),
           "p_x": tr.p[..., 0], "p_y": tr.p[..., 1], "p_theta": tr.p[..., 2].copy()}

    def rod(W, c):
        m = TangentContinuation(BendingWarp(law, 0.0, 2.0, W[:, :1]), reach, tail_factor(W[:, 1]))
        return LearnedRod({**{cc: NominalLaw(k, P) for k, cc in NOMINAL_LAWS.items()}, "obj_m": m},
                          "objective", P, None, c)
    fit = fit_record(rod, arr, P, sim, 0.0, 2.0, rf, exact_start=True, tail=True)
    assert fit.kept and abs(math.exp(fit.tail_log_factor) - 0.4) < 0.05, fit
    assert abs(fit.coefficients[0]) < 0.02 and np.asarray(fit.coefficient_cov).shape == (1, 1), fit
    assert tail_factor(-1e4) == pytest.approx(0.01) and tail_factor(0.0) == 1.0  # held to [1/100, 100]


def test_a_warped_posterior_sample_set_is_still_a_sample_set_for_the_uq_rollout():
    """The UQ rollout sees a kept warp around the bending law's samples (``learned_components``
    wraps whatever ``load`` gives): the wrapped set is recognised, subset and sized like the bare one."""
    from crgpr.learning.nominal import SelectedInputs
    from crgpr.uq.rollout import n_samples_of
    from crgpr.uq.samples import TabulatedSamples, is_sample_set, select_samples

    grid = np.linspace(-40.0, 40.0, 81)
    values = np.stack([0.0015 * (1 + 0.01 * s) * grid for s in range(5)])
    smp = BendingWarp(SelectedInputs(TabulatedSamples(grid, values), [0]), 0.0, 40.0, np.array([0.1]))
    assert is_sample_set(smp) and n_samples_of({"obj_m": smp}) == 5
    sub = select_samples(smp, np.array([1, 3]))
    assert isinstance(sub, BendingWarp) and n_samples_of({"obj_m": sub}) == 2
    X = np.zeros((2, 4, 5))
    X[..., 0] = np.array([-30.0, -10.0, 10.0, 30.0])
    assert np.allclose(sub(X), 1.1 * values[[1, 3]][:, [10, 30, 50, 70]], rtol=1e-12)


def test_a_learned_law_that_forecasts_its_record_worse_than_the_nominal_rod_falls_back(smoke):
    """The rod is the nominal one; the learned law is wrong in shape (w = 1 + 0.8 u^4), which a
    one-term warp cannot mend: the nominal rod, its start fitted on the same first part,
    forecasts the held-out blocks consistently better and follows the whole record better, so the
    fit says fall back. With the roles
    swapped (the learned law is the rod's own, the comparison rod the misshapen one) it does not."""
    P, sim, rf = smoke
    scale, wrong = 9.0, np.array([0.0, 0.0, 0.8])
    arr = _record(P, np.array([0.0]), scale, 1e-4, seed=5)
    nominal, misshapen = _nominal_rod(P, None, scale), _nominal_rod(P, wrong, scale)

    def wrong_rod(W, c):
        return LearnedRod({**misshapen.components, "obj_m": BendingWarp(misshapen.components["obj_m"], 0.0,
                                                                          scale, W)}, "objective", P, None, c)
    fit = fit_record(wrong_rod, arr, P, sim, 0.0, scale, rf, nominal_rod=nominal)
    assert fit.nominal_fallback and not fit.kept and fit.coefficients == [], fit
    assert fit.nominal_log_ratio > 1.96 * fit.nominal_log_ratio_se and fit.rmse_nominal < fit.rmse_compared
    right = fit_record(lambda W, c: _nominal_rod(P, W, scale, c), arr, P, sim, 0.0, scale, rf,
                       nominal_rod=misshapen)
    assert not right.nominal_fallback and right.nominal_log_ratio < 0
    assert right.rmse_compared < right.rmse_nominal
    unchecked = fit_record(lambda W, c: _nominal_rod(P, W, scale, c), arr, P, sim, 0.0, scale, rf)
    assert not unchecked.nominal_fallback and math.isnan(unchecked.nominal_log_ratio)  # no nominal rod given


def test_a_warp_whose_refit_reverses_the_law_is_kept_as_chosen_or_the_law_as_learned_is_checked_again(
        smoke, monkeypatch):
    """The rod is 8 % stiffer than the nominal one, the learned law 20 % softer than the rod: the
    warp (about +25 %) forecasts the held-out blocks better and beats the nominal rod. Where its
    refit on the whole record reverses the law (``warp.admissible`` false for it, made so here),
    the warp as the held-out blocks chose it, fitted on the record's first part, is kept; where
    that too reverses it, no warp is kept and the law as learned, which follows the record worse
    than the nominal rod, is compared with the nominal rod again: every law nominal."""
    import crgpr.learning.record_fit as record_fit

    P, sim, rf = smoke
    arr = _record(P, np.array([0.08]), 20.0, 1e-4, seed=1)
    soft = _nominal_rod(P, np.array([1.08 * 0.8 - 1.0]), 20.0)

    def soft_rod(W, c):
        return LearnedRod({**soft.components, "obj_m": BendingWarp(soft.components["obj_m"], 0.0, 20.0, W)},
                          "objective", P, None, c)
    calls = []

    def refit_reverses(c):  # the first check (the whole-record refit) fails, later ones pass
        calls.append(1)
        return np.full(np.atleast_2d(c).shape[0], len(calls) > 1)
    monkeypatch.setattr(record_fit, "admissible", refit_reverses)
    fit = fit_record(soft_rod, arr, P, sim, 0.0, 20.0, rf, nominal_rod=_nominal_rod(P, None, 20.0))
    assert fit.kept and not fit.nominal_fallback and "first part" in fit.note, fit
    assert abs(fit.coefficients[0] - 0.25) < 0.03 and np.isfinite(fit.coefficient_cov).all(), fit
    monkeypatch.setattr(record_fit, "admissible", lambda c: np.zeros(np.atleast_2d(c).shape[0], dtype=bool))
    fit = fit_record(soft_rod, arr, P, sim, 0.0, 20.0, rf, nominal_rod=_nominal_rod(P, None, 20.0))
    assert not fit.kept and fit.nominal_fallback and "every law nominal" in fit.note, fit
    assert fit.rmse_nominal < fit.rmse_compared == fit.rmse_start_only


def test_a_damped_rod_with_a_misshapen_learned_law_takes_its_nominal_bending_law_warped(smoke):
    """A damped rod whose law is the nominal one 8 % stiffer; the learned law is wrong in shape
    (w = 1 + 0.8 u^4, as a law regressed on moment targets that still hold part of the damping can
    be), which a one-term warp cannot mend. The nominal bending law, its warp and the damping's size
    fitted as the learned law's are, follows the record better: it is taken, with the factor (to
    0.5 %) and c (to 2 %). Where the learned law is the rod's own and the nominal one cannot be
    warped into it, it is not."""
    P, sim, rf = smoke
    c_true, scale, wrong = 4e-5, 20.0, np.array([0.0, 0.0, 0.8])

    def warped(base):
        def rod(W, c):
            m = BendingWarp(base.components["obj_m"], 0.0, scale, W)
            return LearnedRod({**base.components, "obj_m": m}, "objective", P, None, c)
        return rod
    nominal_bending = (lambda W, c: _nominal_rod(P, W, scale, c), 0.0, scale)
    arr = _exact_record(P, np.array([0.08]), scale, c_true)
    fit = fit_record(warped(_nominal_rod(P, wrong, scale)), arr, P, sim, 0.0, scale, rf,
                     damping=0.6 * c_true, exact_start=True, nominal_bending=nominal_bending)
    assert fit.bending_nominal and fit.kept, fit
    assert abs(fit.coefficients[0] - 0.08) < 0.005 and abs(fit.damping / c_true - 1.0) < 0.02, fit
    assert fit.rmse_bending_nominal < fit.rmse_bending_learned
    arr = _exact_record(P, wrong, scale, c_true)
    own = fit_record(warped(_nominal_rod(P, wrong, scale)), arr, P, sim, 0.0, scale, rf,
                     damping=0.6 * c_true, exact_start=True, nominal_bending=nominal_bending)
    assert not own.bending_nominal and own.rmse_bending_learned < own.rmse_bending_nominal, own
    assert own.bending_log_ratio < 0


def test_problems_fitted_side_by_side_take_the_steps_they_take_alone():
    """``levenberg_marquardt_batch``: each problem (one with a trial that leaves the admissible
    range, one with nothing free) ends where ``levenberg_marquardt`` alone ends, bit for bit,
    in fewer calls of the residual function than the problems take one by one."""
    t = np.linspace(0.0, 1.0, 50)
    calls = {"n": 0}

    def residuals(A):
        calls["n"] += 1
        if np.any(np.abs(A[:, 0]) > 3.0):  # a "diverged" rod: the whole batch gives None
            return None
        return np.stack([a[0] * np.exp(-a[1] * t) + a[2] * t**2 - (2.0 * np.exp(-1.3 * t) + 0.4 * t**2)
                         for a in A])
    starts = [np.zeros(3), np.array([2.9, 0.5, 0.0]), np.array([1.0, 1.0, 1.0])]
    frees = [np.ones(3, bool), np.array([True, True, False]), np.zeros(3, bool)]
    alone = [levenberg_marquardt(residuals, a, f, 6, 1e-4) for a, f in zip(starts, frees, strict=True)]
    n_alone, calls["n"] = calls["n"], 0
    together = levenberg_marquardt_batch(residuals, starts, frees, 6, 1e-4)
    for (a1, r1), (a2, r2) in zip(alone, together, strict=True):
        assert np.array_equal(a1, a2) and r1 == r2
    assert alone[0][1] < 1e-5 and calls["n"] < n_alone


def _accepted_costs(costs: list[float]) -> np.ndarray:
    """The costs of a fit's accepted points, from the cost of every point it evaluated (in order):
    the start and each trial that lowered the best cost so far."""
    accepted = [costs[0]]
    for c in costs[1:]:
        if c < accepted[-1]:
            accepted.append(c)
    return np.array(accepted)


def test_a_fit_stops_where_the_gauss_newton_step_predicts_less_than_the_tolerance():
    """``levenberg_marquardt`` stops at convergence: where the Gauss-Newton step at its point
    predicts a gain below ``tolerance`` of the cost; ``iterations`` caps the accepted steps of a
    fit that has more to gain."""
    t = np.linspace(0.0, 2.0, 80)
    noise = 0.05 * np.random.default_rng(3).standard_normal(t.size)  # the optimum's cost is > 0
    target = 2.0 * np.exp(-1.3 * t) * np.cos(3.0 * t) + noise

    def residuals(A):
        return np.stack([a[0] * np.exp(-a[1] * t) * np.cos(a[2] * t) - target for a in A])

    def fit(iterations, tolerance):
        costs = []  # the cost of each evaluated point (row 0 of every call)

        def counted(A):
            R = residuals(A)
            costs.append(float(np.mean(R[0] ** 2)))
            return R
        a, rms = levenberg_marquardt(counted, np.array([1.0, 0.5, 2.5]), np.ones(3, bool), iterations,
                                     tolerance)
        return a, rms, _accepted_costs(costs).size - 1

    def predicted_gain(a):  # the Gauss-Newton step's predicted gain at a, over the cost
        r = residuals(a[None])[0]
        J = np.stack([(residuals((a + 1e-6 * e)[None])[0] - r) / 1e-6 for e in np.eye(3)], axis=1)
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        return (np.sum(r**2) - np.sum((r + J @ step) ** 2)) / np.sum(r**2)

    a, rms, steps = fit(100, 1e-2)
    assert predicted_gain(a) < 1e-2 < predicted_gain(np.array([1.0, 0.5, 2.5]))
    a_tight, rms_tight, steps_tight = fit(100, 1e-12)
    assert np.allclose(a_tight, [2.0, 1.3, 3.0], atol=0.1) and rms_tight <= rms
    assert predicted_gain(a_tight) < 1e-8 and steps < steps_tight < 100
    a_capped, rms_capped, steps_capped = fit(2, 1e-12)
    assert steps_capped == 2 and rms_capped > rms_tight and predicted_gain(a_capped) > 1e-2


def test_a_short_step_far_from_the_optimum_does_not_end_the_fit():
    """In a curved valley (Rosenbrock's residuals) the damped steps gain little, some below
    ``tolerance`` of the cost, while the Gauss-Newton step still predicts the whole cost: the fit
    goes on to the optimum."""
    costs = []

    def residuals(A):
        R = np.stack([[10.0 * (a[1] - a[0] ** 2), 1.0 - a[0]] for a in A])
        costs.append(float(np.mean(R[0] ** 2)))
        return R
    a, rms = levenberg_marquardt(residuals, np.array([-1.2, 1.0]), np.ones(2, bool), 100, 0.1)
    accepted = _accepted_costs(costs)
    gains = -np.diff(accepted) / accepted[:-1]  # each step's gain over the cost it starts from
    assert np.any(gains < 0.1) and np.allclose(a, [1.0, 1.0], atol=1e-6) and rms < 1e-6


def test_a_learned_rod_that_leaves_the_physical_range_on_its_own_record_falls_back_to_the_nominal_one(smoke):
    """A learned shear law of the wrong sign (n2 = -GA nu2) tears the rod apart within its
    record: no warp of the bending law can mend it, and the nominal rod, which stays in range,
    follows the record better, so every law goes nominal. Without a nominal rod to compare with,
    the learned law is kept unwarped."""
    P, sim, rf = smoke
    arr = _record(P, np.array([0.0]), 20.0, 1e-4, seed=6)
    torn = NominalLaw("n2", P)
    torn.stiffness = -torn.stiffness

    def torn_rod(W, c):
        rod = _nominal_rod(P, W, 20.0, c)
        return LearnedRod({**rod.components, "obj_n2": torn}, "objective", P, None, c)
    fit = fit_record(torn_rod, arr, P, sim, 0.0, 20.0, rf, nominal_rod=_nominal_rod(P, None, 20.0))
    assert "left the physical range" in fit.note and fit.nominal_fallback and not fit.kept, fit
    assert fit.rmse_nominal < 0.1 and fit.rmse_compared == pytest.approx(math.pi)
    alone = fit_record(torn_rod, arr, P, sim, 0.0, 20.0, rf)
    assert "left the physical range" in alone.note and not alone.nominal_fallback and not alone.kept
