"""Missing-physics selection mechanics on arrays (fast; no simulation of the workflow).

The end-to-end cases (tests/test_discovery.py) check the same mechanisms on camera records;
these tests pin each one down on data whose answer is known exactly.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from paper_rod import paper_rod

from crgpr.config import load_config
from crgpr.discovery.describe import ProfileFit, describe_region, knot_positions, profile_params
from crgpr.discovery.locate import local_stiffness_error, time_windows
from crgpr.discovery.regression import Fit
from crgpr.discovery.residual import Residual
from crgpr.discovery.settings import DiscoverySettings
from crgpr.discovery.stepwise import alternatives, eliminate, entry_threshold, swap, trajectory_delta_bic
from crgpr.discovery.trajectory import TrajectoryFit
from crgpr.physics.rod import segment_EI

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def st() -> DiscoverySettings:
    return DiscoverySettings.from_config(load_config(ROOT / "config.yaml")["discovery"], seed=1)


# --------------------------------------------------------------------------------------------
# localisation of a stiffness defect along s (instrumental-variable regression per segment)
# --------------------------------------------------------------------------------------------
def _bending_record(defect: dict[int, float], seed: int = 0, n_t: int = 400):
    """Residual of a rod whose segment j is softer by the fraction defect[j] than nominal.

    The model's curvature is a decaying first-mode swing (zero at the free tip); the measured
    curvature adds camera noise (errors in variables) and the dynamic moment acceleration noise
    that grows towards the base, as on camera data."""
    p = paper_rod()
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n_t)
    s = p.s
    shape = s / p.L0 - 0.5 * (s / p.L0) ** 2
    theta = 1.2 * (np.cos(2 * np.pi * 2.0 * t) * np.exp(-t))[:, None] * shape
    q = np.zeros((n_t, p.N + 1, 3))
    q[..., 2] = theta[:, :] + 1.4
    EI = segment_EI(p)
    kappa = np.diff(q[..., 2], axis=-1) / p.ds
    M = EI * kappa
    X = M + 0.05 * np.abs(M).max() * rng.standard_normal(M.shape)  # EI x measured curvature
    d = np.zeros(p.N)
    for j, v in defect.items():
        d[j] = v
    grow = np.linspace(1.0, 0.2, p.N)  # acceleration noise of the dynamic moment, largest at the base
    mb_dyn = (1.0 - d) * M + 0.03 * np.abs(M).max() * grow * rng.standard_normal(M.shape)
    rho = X - mb_dyn
    res = Residual(rho=rho, sig={"stiffness_scale": X}, base_y=np.zeros(n_t), base_sig=np.zeros(n_t),
                   mb_const=X, mb_dyn=mb_dyn)
    return p, res, q, d


def test_local_stiffness_error_finds_a_defect_and_its_depth():
    p, res, q, d = _bending_record({6: 0.4, 7: 0.6, 8: 0.4})
    out = local_stiffness_error(res, q, p, slice(5, -5))
    assert out["peak_s_m"] == pytest.approx(7.5 * p.ds)
    assert out["peak_relative_error"] == pytest.approx(0.6, abs=0.1)
    assert 5.5 * p.ds <= out["extent_s_m"][0] and out["extent_s_m"][1] <= 9.5 * p.ds
    z = np.delete(np.array(out["z"]), [0, 6, 7, 8])
    assert np.all(np.abs(z) < 4.5)  # nothing significant elsewhere, the free tip included


def test_local_stiffness_error_is_unbiased_at_the_free_tip():
    """Ordinary least squares on the noisy measured curvature gives d -> 1 where the true
    curvature vanishes (the free tip); the model-curvature instrument does not."""
    p, res, q, _ = _bending_record({})
    rows = slice(5, -5)
    X, y = res.sig["stiffness_scale"][rows], res.rho[rows]
    ols = (X * y).sum(0) / (X * X).sum(0)
    out = local_stiffness_error(res, q, p, rows)
    assert ols[-1] > 0.5  # the errors-in-variables artefact the instrument removes
    assert abs(out["relative_error"][-1]) < 0.3
    assert max(abs(v) for v in out["z"]) < 4.5  # nothing localised on effect-free data


# --------------------------------------------------------------------------------------------
# backward elimination (nested-model test on the joint fit)
# --------------------------------------------------------------------------------------------
class _StubFitter:
    """Trajectory fits whose residual sum of squares depends on the named effects only: the
    data hold tip_mass and viscous_drag; rest_curvature is a proxy that helps only while one
    of them is missing."""

    n = 2000

    def _rss(self, names: list[str]) -> float:
        rss = 1.0
        rss += 0.0 if "tip_mass" in names else (0.5 if "rest_curvature" in names else 1.0)
        rss += 0.0 if "viscous_drag" in names else 0.8
        return rss

    def fit(self, names, x0, x_std, max_nfev):
        return TrajectoryFit(list(names), np.ones(len(names)), np.full(len(names), 0.1), np.zeros(8),
                             np.zeros((1, 1, 3)), np.zeros((1, 3)), np.zeros((1, 3)), self._rss(names),
                             self.n, 1.0, 1)

    def effect_size(self, fit, k):
        others = [n for n in fit.names if n != k]
        return float(np.sqrt(max(self._rss(others) - fit.rss, 0.0) / self.n))


def test_backward_elimination_drops_a_proxy_once_the_true_effects_are_named(st):
    f = _StubFitter()
    cur = f.fit(["rest_curvature", "viscous_drag", "tip_mass"], None, None, 0)
    out, records = eliminate(f, cur, "tip_mass", gap_before=0.05, st=st)
    assert out.names == ["viscous_drag", "tip_mass"]
    dropped = [r["effect"] for r in records if r["dropped"]]
    assert dropped == ["rest_curvature"]
    kept = [r for r in records if r["effect"] == "viscous_drag"]
    assert kept and all(r["trajectory_delta_bic"] >= st.bic_min_improvement for r in kept)


def test_backward_elimination_keeps_every_needed_effect(st):
    f = _StubFitter()
    cur = f.fit(["viscous_drag", "tip_mass"], None, None, 0)
    out, records = eliminate(f, cur, "tip_mass", gap_before=0.05, st=st)
    assert out.names == ["viscous_drag", "tip_mass"] and not any(r["dropped"] for r in records)


def test_trajectory_delta_bic_is_a_nested_model_test():
    f = _StubFitter()
    small, big = f.fit(["tip_mass"], None, None, 0), f.fit(["tip_mass", "viscous_drag"], None, None, 0)
    same = f.fit(["tip_mass", "rest_curvature"], None, None, 0)
    assert trajectory_delta_bic(small, big) > 10.0
    assert trajectory_delta_bic(small, same) < 0.0  # an extra parameter that changes nothing costs log n


@pytest.mark.parametrize("T, w", [(1.0, 0.1), (0.8, 0.1), (2.0, 0.1), (0.95, 0.1), (0.3, 0.1)])
def test_time_windows_cover_the_record_without_a_one_sample_window(T, w):
    t = np.arange(0.0, T + 1e-9, 0.004)
    wins = time_windows(t, w)
    masks = np.array([m for _, _, m in wins])
    assert np.all(masks.sum(axis=0) == 1)  # every sample in exactly one window
    assert min(m.sum() for m in masks) >= 0.5 * w / 0.004  # none degenerate (the last included)
    assert wins[0][0] == 0.0 and wins[-1][1] == pytest.approx(t[-1])


# --------------------------------------------------------------------------------------------
# replacement step (a named effect swapped for a correlated one of the same place)
# --------------------------------------------------------------------------------------------
class _StubRegression:
    """Joint cut-moment regression whose coefficients are all positive (signs agree)."""

    def fit(self, names):
        return Fit(list(names), np.full(len(names), 0.5), np.full(len(names), 0.1), 0.0, 0.0)


class _DragFitter(_StubFitter):
    """The data hold tip_mass and viscous_drag; air_drag stands in for the viscous drag with
    a worse fit, internal_damping (also dissipative) helps less than either."""

    def _rss(self, names: list[str]) -> float:
        rss = 1.0 + (0.0 if "tip_mass" in names else 1.0)
        drag = {"viscous_drag": 0.0, "air_drag": 0.1, "internal_damping": 0.5}
        rss += min([drag[k] for k in names if k in drag], default=0.8)
        return rss


def test_swap_replaces_a_drag_that_entered_in_place_of_the_true_one(st):
    f = _DragFitter()
    cur = f.fit(["tip_mass", "air_drag"], None, None, 0)
    out, records = swap(f, cur, _StubRegression(), set(), size_min=0.005, st=st)
    assert out.names == ["tip_mass", "viscous_drag"]
    tried = {(r["out"], r["in"]) for r in records}
    # only effects of the same place are offered: the drag among the R terms, the tip mass
    # (H, G u) has no partner; the replaced air_drag is not offered back
    assert ("air_drag", "viscous_drag") in tried and ("air_drag", "internal_damping") in tried
    assert not any(r["out"] == "tip_mass" for r in records)
    assert not any(r["in"] == "air_drag" for r in records)
    assert [r["in"] for r in records if r["swapped"]] == ["viscous_drag"]


def test_swap_keeps_the_right_model(st):
    f = _DragFitter()
    cur = f.fit(["tip_mass", "viscous_drag"], None, None, 0)
    out, records = swap(f, cur, _StubRegression(), set(), size_min=0.005, st=st)
    assert out is cur and not any(r["swapped"] for r in records)
    assert all(r["trajectory_delta_bic"] < 0 for r in records)


def test_entry_threshold_when_the_initial_state_hides_the_gap(st):
    """A model within min_gap_rad of its floor (the fitted initial state absorbed what the
    effect did) admits only effects that alone would have put it over that threshold; a clear
    gap admits effects of min_effect_fraction of it."""
    hidden, size = entry_threshold(0.018, 0.012, 0.018, st)
    assert hidden and size == pytest.approx(math.hypot(0.012, st.min_gap_rad))
    hidden, size = entry_threshold(0.20, 0.012, 0.25, st)
    assert not hidden and size == pytest.approx(st.min_effect_fraction * 0.25)


def test_alternatives_are_swaps_the_data_do_not_tell_apart(st):
    """A replacement within bic_min_improvement of the named model that passes the entry tests
    is reported; a clearly worse one, a failed sign test or one tried in another model is not."""
    rec = {"out": "air_drag", "in": "viscous_drag", "model": ["tip_mass", "air_drag"], "rmse": 0.0134,
           "trajectory_delta_bic": -9.6, "effect_size_rad": 0.15, "signs_agree": True, "swapped": False}
    worse = {**rec, "in": "internal_damping", "trajectory_delta_bic": -55.0}
    sign = {**rec, "signs_agree": False}
    other = {**rec, "model": ["air_drag"]}
    out = alternatives([rec, worse, sign, other], ["tip_mass", "air_drag"], 0.01, st)
    assert [(a["named"], a["alternative"]) for a in out] == [("air_drag", "viscous_drag")]
    assert alternatives([rec], [], 0.01, st) == []  # nothing named: no alternatives


def test_trajectory_fit_jacobian_is_the_derivative_of_its_residual():
    """The fitter's Jacobian: initial-state columns from the tangent-linear run (exact),
    coefficient columns by least_squares' own forward differences; both match central
    differences of the theta residual at the markers, and its residual is the fit's own."""
    from crgpr.discovery.trajectory import TrajectoryFitter, rod_state, run_model
    from crgpr.measured.kinematics import Kinematics

    pr = paper_rod(N=10)
    n, period = 41, 0.005
    th = np.radians(85.0) - 0.3 * (pr.s / pr.L0) ** 2
    om = 2.0 * pr.s / pr.L0
    q0, v0 = rod_state(th, om, np.zeros(2), pr)
    q = run_model(pr.replace(tip_mass=0.005), q0, v0, period, n, 1e-4)
    t = np.arange(n) * period
    vq = np.gradient(q, t, axis=0)
    kin = Kinematics(t, q, vq, np.gradient(vq, t, axis=0), 1e-3, q[:, 0, 2].copy(),
                     np.array([0.1, 0.2, 0.3, 0.4, 0.5]) * pr.L0)
    fitter = TrajectoryFitter(pr, kin, 1e-4, n_modes=2, window_s=0.05)
    names = ["tip_mass", "viscous_drag"]
    x = np.array([0.003, 0.02, 0.01, -0.02, 0.05, 0.03])
    lo, hi = np.zeros(2), np.full(2, np.inf)
    assert fitter._init_jacobian(names, x[:2], x[2:], n) is not None  # the tangent path, not the fallback
    J = fitter._jacobian(names, x, 2, (lo, hi), n, 1e-4)
    r0 = fitter._resid(names, x[:2], x[2:], n)
    assert J.shape == (r0.size, 6)
    for i in range(6):
        h = 1e-6 * max(abs(x[i]), 1e-2)
        e = np.zeros(6)
        e[i] = h
        fd = (fitter._resid(names, (x + e)[:2], (x + e)[2:], n)
              - fitter._resid(names, (x - e)[:2], (x - e)[2:], n)) / (2 * h)
        tol = 1e-3 if i < 2 else 1e-6  # forward differences (rel. step 1e-4) vs exact
        assert np.abs(J[:, i] - fd).max() <= tol * np.abs(fd).max(), i


def test_summary_reports_indistinguishable_alternatives_apart_from_correct(tmp_path):
    """discovery.csv: a name the data cannot tell apart from the true one (an
    ``indistinguishable_alternatives`` entry) is not counted correct, but is reported, and the
    case counts as correct up to that alternative only if the alternative is the hidden effect."""
    import json

    from crgpr.report.discovery import summary

    where = {"residual_moment_peak_s_m": 0.1, "time_window_s": [0.0, 0.1]}
    inp = {"n_markers": 26, "t0_s": 0.0, "missing_fraction": [0.0], "outliers_total": 0}
    base = {"verdict": "effect_found", "input": inp, "gap_before": 0.1, "gap_floor": 0.02, "gap_after": 0.02,
            "tip_gap_before": 0.1, "tip_gap_after": 0.01, "explained_fraction": 0.8, "where": where,
            "timing_s": {"total": 1.0}}
    eff = [{"name": "tip_mass", "coefficient": 0.01, "coefficient_std": 0.001},
           {"name": "air_drag", "coefficient": 0.03, "coefficient_std": 0.01}]
    truth = {"effects": {"tip_mass": 0.01, "viscous_drag": 0.04}, "effect_size_rmse_theta_rad": 0.3}
    cases = {"alt_true": [{"named": "air_drag", "alternative": "viscous_drag", "trajectory_delta_bic": -9.6,
                           "rmse": 0.02}],
             "alt_other": [{"named": "air_drag", "alternative": "internal_damping",
                            "trajectory_delta_bic": -3.0, "rmse": 0.02}],
             "no_alt": []}
    tps, rps = [], []
    for name, alts in cases.items():
        tp, rp = tmp_path / f"{name}_t.json", tmp_path / f"{name}_r.json"
        tp.write_text(json.dumps(truth))
        rp.write_text(json.dumps({**base, "effects": eff, "indistinguishable_alternatives": alts}))
        tps.append(tp)
        rps.append(rp)
    df = summary(list(cases), tps, rps, 0.02, tmp_path / "d.csv", tmp_path / "d.png").set_index("case")
    assert not df["correct"].any()
    assert df.loc["alt_true", "indistinguishable"] == "air_drag~viscous_drag"
    assert df["correct_up_to_indistinguishable"].tolist() == [True, False, False]


def test_discretisation_floor_is_the_fitted_gap_and_ignores_spurious_initial_rates():
    """The floor's discretisation part (``discretisation_error``: the model fitted to the data
    on its grid N and step dt and on 2N, dt/2, each with its own initial state, 4/3 of the
    difference) is the gap the nominal model actually shows on effect-free, noise-free data
    from a simulator 4x finer in space and time (within 30 %), at most the difference of the
    two discretisations from the exact release (the fit
    absorbs part of it), and is not inflated by a spurious initial rate mode in the measured
    state or in the fitted corrections it starts from: one fitted state run on both grids
    (a one-grid estimator) inflates it several times."""
    from crgpr.discovery.floor import discretisation_error
    from crgpr.discovery.trajectory import TrajectoryFitter, rod_state, run_model
    from crgpr.measured.kinematics import Kinematics, marker_matrix
    from crgpr.physics.rod import straight_rod

    pr = paper_rod(N=10)
    n, period, dt = 121, 0.005, 1e-4

    def release(p, step=dt):
        q0 = straight_rod(math.radians(85.0), p)
        return run_model(p, q0, np.zeros_like(q0), period, n, step)

    q = release(pr.replace(N=4 * pr.N), dt / 4)[:, ::4]  # finer simulator, seen at the model's nodes
    t = np.arange(n) * period
    v = np.gradient(q, t, axis=0)
    s_m = pr.s[1:]
    spurious = (pr.s / pr.L0) ** 3  # cubic rate mode, 1 rad/s at the tip

    def fitter(domega):
        vm = v.copy()
        vm[0, :, 2] += domega
        kin = Kinematics(t, q, vm, np.gradient(v, t, axis=0), 1e-3, q[:, 0, 2].copy(), s_m)
        return TrajectoryFitter(pr, kin, dt, n_modes=4, window_s=0.2)

    fine = pr.replace(N=2 * pr.N)
    release_ref = 4.0 / 3.0 * math.sqrt(np.mean((release(pr)[..., 2] @ marker_matrix(s_m, pr).T
                                                 - release(fine, dt / 2)[..., 2] @ marker_matrix(s_m, fine).T)
                                                ** 2))
    f = fitter(0.0)
    nominal = f.fit([], np.zeros(0), np.zeros(0), 20)
    est = discretisation_error(f, dt, c0=nominal.init)
    # the gap of the fitted nominal model is e_N - e_4N = (15/16) e_N for a second-order scheme
    assert est == pytest.approx(nominal.rmse * 16.0 / 15.0, rel=0.3)
    assert 0.0 < est <= release_ref
    # a spurious rate mode: in the measured initial state, or in the corrections it starts from
    f_sp = fitter(spurious)
    c_sp = np.zeros(8)
    c_sp[4:] = np.linalg.lstsq(f.P, spurious / f.w_scale, rcond=None)[0]
    for e in (discretisation_error(f_sp, dt, c0=np.zeros(8)), discretisation_error(f, dt, c0=c_sp)):
        assert e == pytest.approx(est, rel=0.1)
    runs = []
    for g, step in ((pr, dt), (fine, dt / 2)):  # one state (the spurious one) on both grids
        q0, v0 = rod_state(np.interp(g.s, pr.s, f_sp.theta), np.interp(g.s, pr.s, f_sp.omega), np.zeros(2), g)
        runs.append(run_model(g, q0, v0, period, n, step)[..., 2] @ marker_matrix(s_m, g).T)
    assert 4.0 / 3.0 * math.sqrt(np.mean((runs[0] - runs[1]) ** 2)) > 3.0 * est


# --------------------------------------------------------------------------------------------
# the learned bending-stiffness law (verdict "described")
# --------------------------------------------------------------------------------------------
def _profile_fit(logf: np.ndarray, sd: float) -> ProfileFit:
    n = len(logf)
    return ProfileFit(knot_positions(n), np.asarray(logf, float), sd**2 * np.eye(n), np.zeros(8),
                      np.zeros((1, 2, 3)), 0.0, 1, 0)


def test_described_region_is_the_place_direction_and_factor_of_a_soft_spot():
    """A factor 0.5 at the knot s / L0 = 0.25 (band 0.05 in log f) is described as softer there,
    within the neighbouring knots, with the factor and its band at the extreme, and an extra
    compliance int (1/f - 1) ds inside its own band and below (1/0.5 - 1) x the two knot
    intervals the soft spot spans."""
    logf = np.zeros(9)
    logf[2] = math.log(0.5)
    reg = describe_region(_profile_fit(logf, 0.05), 0.5, 1.96)
    assert reg["direction"] == "softer"
    assert reg["s_extreme_m"] == pytest.approx(0.125)
    assert 0.0625 <= reg["s_from_m"] < 0.125 < reg["s_to_m"] <= 0.1875
    assert reg["factor"] == pytest.approx(0.5)
    assert reg["band"][0] < 0.5 < reg["band"][1]
    lo, hi = reg["extra_compliance_band_m"]
    assert lo <= reg["extra_compliance_m"] <= hi
    assert 0.0 < reg["extra_compliance_m"] < (1 / 0.5 - 1) * 0.125  # at most the knot interval


def test_described_region_is_none_when_the_band_holds_the_nominal_law():
    logf = np.full(9, 0.05)
    assert describe_region(_profile_fit(logf, 0.1), 0.5, 1.96) is None
    reg = describe_region(_profile_fit(logf, 0.01), 0.5, 1.96)  # a tight band: 5 % stiffer everywhere
    assert reg["direction"] == "stiffer" and reg["s_from_m"] == 0.0 and reg["s_to_m"] == 0.5


def test_profile_params_with_a_zero_log_factor_is_the_nominal_rod():
    p = paper_rod()
    q = profile_params(p, np.zeros(9))
    s_rel = (np.arange(p.N) + 0.5) / p.N
    assert np.allclose(q.material.ei_factor(s_rel), 1.0)
    half = profile_params(p, np.full(5, math.log(0.5)))
    assert np.allclose(half.material.ei_factor(s_rel), 0.5)


# --------------------------------------------------------------------------------------------
# held-out time blocks: no effect that the others make redundant out of sample
# --------------------------------------------------------------------------------------------
def _one_rod_record(truth: dict[str, float], noise_rad: float, seed: int = 3, material: dict | None = None):
    """A 1 s swing of a 10-segment rod with effects ``truth`` (and ``rod.material`` changes
    ``material``), theta seen at 5 markers with white noise ``noise_rad``; the fitter of the
    nominal rod on it."""
    import dataclasses

    from crgpr.discovery.effects import effect_params
    from crgpr.discovery.trajectory import TrajectoryFitter, rod_state, run_model
    from crgpr.measured.kinematics import Kinematics

    pr = paper_rod(N=10)
    n, period = 201, 0.005
    th = np.full(pr.N + 1, np.radians(85.0))
    q0, v0 = rod_state(th, np.zeros(pr.N + 1), np.zeros(2), pr)
    p_truth = effect_params(pr, truth)
    if material:
        p_truth = p_truth.replace(material=dataclasses.replace(p_truth.material, **material))
    q = run_model(p_truth, q0, v0, period, n, 1e-4)
    q[..., 2] += noise_rad * np.random.default_rng(seed).standard_normal(q[..., 2].shape)
    t = np.arange(n) * period
    vq = np.gradient(q, t, axis=0)
    kin = Kinematics(t, q, vq, np.gradient(vq, t, axis=0), 1e-3, q[:, 0, 2].copy(),
                     np.array([0.2, 0.4, 0.6, 0.8, 1.0]) * pr.L0)
    return TrajectoryFitter(pr, kin, 1e-4, n_modes=2, window_s=0.05)


@pytest.mark.parametrize("a", [0.1, 0.3])
def test_holdout_drops_a_proxy_beside_the_one_hidden_effect(st, a):
    """A uniform stiffness error of 10 % and 30 %: the model with a cubic stiffening beside it
    fits in-sample at least as well, but on held-out time blocks the stiffening adds nothing,
    and it leaves; the stiffness error stays, with its coefficient."""
    from crgpr.discovery.holdout import holdout_check

    fitter = _one_rod_record({"stiffness_scale": a}, 2e-3)
    two = fitter.fit(["stiffness_scale", "nonlinear_stiffness"], np.array([a, 1e-3]), np.array([0.05, 1e-3]),
                     st.refine_max_nfev)
    out, rec = holdout_check(fitter, two, st)
    assert out.names == ["stiffness_scale"]
    assert out.coef[0] == pytest.approx(a, rel=0.1)
    assert [r["effect"] for r in rec if r["dropped"]] == ["nonlinear_stiffness"]


def test_holdout_keeps_two_hidden_effects(st):
    """Both effects of a record with a stiffness error and a tip mass predict held-out blocks."""
    from crgpr.discovery.holdout import holdout_check

    fitter = _one_rod_record({"stiffness_scale": 0.3, "tip_mass": 0.005}, 2e-3)
    two = fitter.fit(["stiffness_scale", "tip_mass"], np.array([0.3, 0.005]), np.array([0.05, 1e-3]),
                     st.refine_max_nfev)
    out, rec = holdout_check(fitter, two, st)
    assert out.names == ["stiffness_scale", "tip_mass"]
    assert all(r["held_out_evidence"] >= st.holdout_min_evidence for r in rec)


def test_block_mask_alternates_equal_blocks_from_the_first():
    from crgpr.discovery.holdout import block_mask

    m = block_mask(12, 6)
    assert m.tolist() == [1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0]


def test_model_form_floor_is_zero_for_the_point_clamp_and_grows_with_the_clamp_stiffness():
    """The clamp's model-form part of the floor: none with ``clamp_factor`` 1 (the model's own
    point clamp), positive and larger for a stiffer clamp of the same length."""
    from crgpr.discovery.floor import model_form_error

    fitter = _one_rod_record({}, 0.0)
    assert model_form_error(fitter, 1e-4, 0.05, 1.0) == 0.0
    e3, e10 = (model_form_error(fitter, 1e-4, 0.05, f) for f in (3.0, 10.0))
    assert 0.0 < e3 < e10


def test_summary_counts_a_described_defect_by_its_place_and_direction(tmp_path):
    """A stiffness defect is expected `described`; it is correct only if the described region
    holds the defect's centre and is softer."""
    import json

    from crgpr.report.discovery import summary

    where = {"residual_moment_peak_s_m": 0.1, "time_window_s": [0.0, 0.1]}
    inp = {"n_markers": 26, "t0_s": 0.0, "missing_fraction": [0.0], "outliers_total": 0}
    base = {"verdict": "described", "input": inp, "gap_before": 0.03, "gap_floor": 0.015, "gap_after": 0.012,
            "tip_gap_before": 0.1, "tip_gap_after": 0.01, "explained_fraction": 0.6, "where": where,
            "timing_s": {"total": 1.0}, "effects": [], "indistinguishable_alternatives": []}
    truth = {"effects": {}, "disturbance": {"stiffness_defect": {"s_m": 0.15, "width_m": 0.06, "depth": 0.6}},
             "effect_size_rmse_theta_rad": 0.08}
    region = {"direction": "softer", "s_from_m": 0.09, "s_to_m": 0.21, "factor": 0.59, "band": [0.48, 0.72]}
    cases = {"right": region, "wrong_place": {**region, "s_from_m": 0.3, "s_to_m": 0.4},
             "wrong_direction": {**region, "direction": "stiffer"}}
    tps, rps = [], []
    for name, reg in cases.items():
        tp, rp = tmp_path / f"{name}_t.json", tmp_path / f"{name}_r.json"
        tp.write_text(json.dumps(truth))
        rp.write_text(json.dumps({**base, "described": {"region": reg}}))
        tps.append(tp)
        rps.append(rp)
    df = summary(list(cases), tps, rps, 0.02, tmp_path / "d.csv", tmp_path / "d.png").set_index("case")
    assert df["expected_verdict"].eq("described").all()
    assert df["correct"].tolist() == [True, False, False]
    assert df.loc["right", "described"].startswith("EI x0.59")


@pytest.mark.parametrize("truth, material, accepted", [
    ({"tip_mass": 0.003}, None, False),
    ({}, {"defect_start": 0.3, "defect_end": 0.5, "defect_factor": 0.4, "defect_edge": 0.02}, True),
])
def test_learned_law_does_not_stand_in_for_a_library_effect(st, truth, material, accepted):
    """A tip mass hidden: the learned EI(s) (nine knots) may close the gap, but the library's
    one-parameter tip-mass fit does about as well, so the law is not accepted, and the tip mass
    is reported as the closest library model. A soft spot (EI x 0.4 over 0.3-0.5 L0): the law
    beats the same rival and is accepted, softer where the spot is."""
    from crgpr.discovery.describe import describe

    fitter = _one_rod_record(truth, 2e-3, material=material)
    nominal = fitter.fit([], np.zeros(0), np.zeros(0), st.refine_max_nfev)
    tm = fitter.fit(["tip_mass"], np.array([0.002]), np.array([1e-3]), st.refine_max_nfev)
    floor = 2e-3
    excess = math.sqrt(max(nominal.rmse**2 - floor**2, 0.0))
    out = describe(fitter, nominal, floor, nominal.tau, nominal.rmse, excess, st, ((["tip_mass"], tm.rmse),))
    assert out["closest_library_model"]["effects"] == ["tip_mass"]
    assert out["closes_the_gap"]  # on its own the law would describe both records
    assert out["accepted"] is accepted
    if accepted:
        reg = out["region"]
        assert reg["direction"] == "softer"
        assert reg["s_from_m"] <= 0.4 * fitter.params.L0 <= reg["s_to_m"]


# --------------------------------------------------------------------------------------------
# the smallest model that reaches its own floor
# --------------------------------------------------------------------------------------------
def _prune(st, truth: dict[str, float], names: list[str], x0: list[float], noise_rad: float = 2e-3):
    """The model ``names`` fitted to a one-rod record with ``truth`` hidden, then pruned; a
    model's floor is the white theta noise and its own discretisation error (the model fitted on
    its grid and on one twice as fine, ``floor.discretisation_error``)."""
    from crgpr.discovery.floor import discretisation_error
    from crgpr.discovery.prune import residual_gain, smallest_model

    fitter = _one_rod_record(truth, noise_rad)
    cur = fitter.fit(names, np.array(x0), np.full(len(names), 0.05), st.refine_max_nfev)
    nominal = fitter.fit([], np.zeros(0), np.zeros(0), st.refine_max_nfev)
    gap = nominal.rmse
    excess = math.sqrt(max(gap**2 - noise_rad**2, 0.0))
    rows = slice(4, fitter.n - 4)
    out, rec = smallest_model(fitter, cur, lambda f: math.hypot(noise_rad, discretisation_error(
                                  fitter, 1e-4, tuple(f.names), f.coef, f.init)),
                              lambda f, k: residual_gain(fitter.kin, fitter.params, rows, f, k),
                              gap, excess, False, st)
    return fitter, cur, out, rec


@pytest.mark.parametrize("truth, extra", [({"stiffness_scale": 0.1}, "nonlinear_stiffness"),
                                          ({"stiffness_scale": 0.3}, "nonlinear_stiffness"),
                                          ({"rest_curvature": 0.5}, "stiffness_scale"),
                                          ({"rest_curvature": 1.0}, "stiffness_scale")])
def test_pruning_drops_an_unneeded_effect_beside_the_hidden_one(st, truth, extra):
    """The hidden effect fitted together with an unneeded one (a cubic stiffening beside a
    stiffness error of 10 % and 30 %; a stiffness error beside a rest curvature of 0.5 and
    1 /m): the model without the extra effect is at its floor and the residual does not ask for
    it back, so it leaves; the hidden effect stays with its coefficient, refitted."""
    (k, c), = truth.items()
    _, cur, out, rec = _prune(st, truth, [k, extra], [c, 1e-3])
    assert out.names == [k]
    assert out.coef[0] == pytest.approx(c, rel=0.1)
    assert [r["effect"] for r in rec if r["dropped"]] == [extra]


def test_pruning_keeps_two_hidden_effects_each_larger_than_the_none_threshold(st):
    """A stiffness error and a tip mass both hidden, each moving theta by more than
    ``min_gap_rad`` on its own: neither model without one reaches its floor, and both stay."""
    fitter, cur, out, rec = _prune(st, {"stiffness_scale": 0.3, "tip_mass": 0.01},
                                   ["stiffness_scale", "tip_mass"], [0.3, 0.01])
    for k in cur.names:
        assert fitter.effect_size(cur, k) > st.min_gap_rad
    assert out.names == ["stiffness_scale", "tip_mass"]
    assert rec and not any(r["dropped"] or r["at_floor_without"] for r in rec)


def test_closes_gap_is_the_verdicts_rule_against_a_models_own_floor(st):
    """Half the gap closed and an excess over the model's own floor within the allowance; on a
    nominal gap within ``min_gap_rad`` of its floor, half of the excess instead."""
    from crgpr.discovery.prune import closes_gap

    assert closes_gap(0.03, 0.03, 0.1, 0.095, False, st.min_gap_rad, st)
    assert not closes_gap(0.045, 0.03, 0.1, 0.095, False, st.min_gap_rad, st)  # 55 %, 0.034 over its floor
    assert not closes_gap(0.055, 0.055, 0.1, 0.085, False, st.min_gap_rad, st)  # at its floor, 45 % closed
    assert closes_gap(0.031, 0.03, 0.035, 0.02, True, st.min_gap_rad, st)  # hidden: 61 % of the excess
