"""A learned bending law beyond its covered curvatures: the GP's mean while its band is narrow,
its tangent beyond (learning.extrapolation)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crgpr.gp import fit_gp
from crgpr.learning.extrapolation import (
    Reach,
    TangentContinuation,
    continue_table,
    continued,
    law_reach,
    manifest_reach,
    side_reach,
)


def _table(x: np.ndarray, mean: np.ndarray, sd: np.ndarray, lo: float, hi: float, at_s: float = np.nan
           ) -> pd.DataFrame:
    return pd.DataFrame({"law": "obj_m", "input": "kappa", "x": x, "mean": mean, "sd": sd,
                         "covered": (x >= lo) & (x <= hi), "covered_lo": lo, "covered_hi": hi, "at_s": at_s})


def test_reach_is_the_last_point_of_the_narrow_band_run_from_each_edge():
    x = np.linspace(-2.0, 2.0, 41)
    mean = x.copy()
    # 1.96 sd = 0.2 |m| exactly at |x| = 1.5 on the right; the left fails at its first point
    sd = np.where(x > 0, 0.2 / 1.959963984540054 * np.maximum(x - 1.0, 0.0) * 3.0, 10.0)
    sd[np.abs(x) <= 1.0] = 0.0
    lo, hi = side_reach(x, mean, sd, -1.0, 1.0, band=0.2)
    assert lo == -1.0  # the first point beyond the left edge fails: the edge itself
    assert hi == pytest.approx(1.5, abs=1e-12)
    # a band that fails once stops the run even if it narrows again further out
    sd2 = sd.copy()
    sd2[x > 1.7] = 0.0
    assert side_reach(x, mean, sd2, -1.0, 1.0, band=0.2)[1] == pytest.approx(1.5, abs=1e-12)


def test_a_law_of_s_takes_the_nearest_reach_over_its_slices():
    x = np.linspace(-2.0, 2.0, 41)
    narrow, wide = np.zeros_like(x), np.where(np.abs(x) > 1.0, 10.0, 0.0)
    tab = pd.concat([_table(x, x, narrow, -1.0, 1.0, 0.1), _table(x, x, wide, -1.0, 1.0, 0.4)])
    r = law_reach(tab, band=0.2, tangent_span=0.1)
    assert (r.lo, r.hi) == (-1.0, 1.0) and r.span == pytest.approx(0.2)
    assert law_reach(tab[tab["at_s"] == 0.1], 0.2, 0.1).hi == pytest.approx(2.0)
    assert law_reach(tab.iloc[:0], 0.2, 0.1) is None
    with pytest.raises(ValueError, match="tangent_span"):
        law_reach(tab, 0.2, 0.0)


REACH = Reach(lo=-1.0, hi=2.0, span=0.5, covered_lo=-1.0, covered_hi=1.0, band=0.2)


@settings(max_examples=60, deadline=None)
@given(st.floats(-20.0, 20.0), st.floats(0.1, 5.0), st.floats(-2.0, 2.0))
def test_continuation_is_the_law_inside_its_reach_and_its_tangent_beyond(k, a, b):
    def law(v):
        return a * np.tanh(v) + b * v ** 3
    y = continued(np.array([k]), law, REACH)[0]
    if REACH.lo <= k <= REACH.hi:
        assert y == law(np.array([k]))[0]
    else:
        r = REACH.hi if k > REACH.hi else REACH.lo
        inner = r - REACH.span if k > REACH.hi else r + REACH.span
        slope = max((law(np.array([r]))[0] - law(np.array([inner]))[0]) / (r - inner), 0.0)
        assert y == pytest.approx(law(np.array([r]))[0] + slope * (k - r), rel=1e-12, abs=1e-12)
    # continuous at the reach, and never a negative stiffness beyond it
    eps = 1e-9
    for r, sgn in ((REACH.hi, 1.0), (REACH.lo, -1.0)):
        y0, y1 = continued(np.array([r, r + sgn * eps]), law, REACH)
        assert abs(y1 - y0) < 1e-6
        far = continued(np.array([r + sgn * 1.0, r + sgn * 2.0]), law, REACH)
        assert sgn * (far[1] - far[0]) >= 0.0


@settings(max_examples=40, deadline=None)
@given(st.floats(-3.0, 3.0), st.floats(0.2, 3.0), st.floats(-30.0, 30.0))
def test_an_odd_law_is_continued_by_its_mirror_image_as_far_as_the_other_side_reaches(c, a, k):
    """The reach [c - 2, c + 6] of a law odd about c: beyond c - 2 the continuation is the law
    itself (its mirror image is) down to c - 6, where the other side's reach ends; beyond c - 6
    and beyond c + 6, the tangent of the law at c + 6 (mirrored on the short side)."""
    def law(v):
        return a * np.sinh((v - c) / 2.0)
    r = Reach(lo=c - 2.0, hi=c + 6.0, span=0.5, covered_lo=c - 2.0, covered_hi=c + 6.0, band=0.2, center=c)
    y = continued(np.array([k]), law, r)[0]
    if abs(k - c) <= 6.0:
        assert y == pytest.approx(law(np.array([k]))[0], rel=1e-9, abs=1e-12)
    else:
        end = c + 6.0 if k > c else c - 6.0
        slope = (law(np.array([c + 6.0]))[0] - law(np.array([c + 5.5]))[0]) / 0.5
        assert y == pytest.approx(law(np.array([end]))[0] + slope * (k - end), rel=1e-9, abs=1e-12)


def test_wrapper_continues_each_row_from_its_own_inputs_and_rewraps():
    def law_of_s(X):  # m(kappa, s) = (1 + s) kappa, s in column 1
        return (1.0 + X[..., 1]) * X[..., 0]
    X = np.zeros((4, 3, 2))
    X[..., 0] = np.array([0.5, 3.0, -4.0])[None, :]
    X[..., 1] = np.arange(4)[:, None]
    wrapped = TangentContinuation(law_of_s, REACH)
    assert np.allclose(wrapped(X), law_of_s(X))  # a linear law is its own tangent
    saturating = TangentContinuation(lambda Z: np.tanh(Z[..., 0]) * (1.0 + Z[..., 1]), REACH)
    out = saturating(X)
    assert out.shape == (4, 3)
    for i in range(4):
        for j in range(3):
            def law(v, s=X[i, j, 1]):
                return np.tanh(v) * (1 + s)
            assert out[i, j] == pytest.approx(continued(np.array([X[i, j, 0]]), law, REACH)[0])
    assert wrapped.rewrap(law_of_s).reach is REACH
    assert manifest_reach({"bending_extrapolation": REACH.to_dict()}) == REACH
    assert manifest_reach({"bending_extrapolation": None}) is None and manifest_reach({}) is None


def test_a_tail_factor_scales_the_tangent_beyond_the_end_and_each_row_takes_its_own():
    """g x the tangent's slope beyond the reach (the law inside it, and so the join, unchanged);
    a batched wrapper continues member b with its own g_b; a manifest written before the factor
    existed reads as g = 1."""
    def law(v):
        return np.tanh(v)
    k = np.array([-6.0, -1.0, 0.5, 2.0, 3.0, 7.0])
    base = continued(k, law, REACH)
    half = Reach(**{**REACH.to_dict(), "slope_factor": 0.5})
    y = continued(k, law, half)
    inside = (k >= REACH.lo) & (k <= REACH.hi)
    assert np.array_equal(y[inside], base[inside])
    for r in (REACH.lo, REACH.hi):
        assert continued(np.array([r]), law, half)[0] == pytest.approx(law(np.array([r]))[0])
    out = ~inside
    edge = np.where(k > REACH.hi, law(np.array([REACH.hi]))[0], law(np.array([REACH.lo]))[0])
    assert np.allclose(y[out] - edge[out], 0.5 * (base[out] - edge[out]), rtol=1e-12, atol=1e-15)
    X = np.repeat(k[None, :, None], 3, axis=0)
    g = np.array([1.0, 0.5, 2.0])
    rows = TangentContinuation(lambda Z: np.tanh(Z[..., 0]), REACH, g)(X)
    for b in range(3):
        want = continued(k, law, Reach(**{**REACH.to_dict(), "slope_factor": float(g[b])}))
        assert np.allclose(rows[b], want, rtol=1e-12, atol=1e-15)
    old = {key: v for key, v in REACH.to_dict().items() if key != "slope_factor"}
    assert manifest_reach({"bending_extrapolation": old}).slope_factor == 1.0


def _frictionless_energy(g: float, dt: float) -> tuple[float, float, float]:
    """A learned rod (the paper's, N = 8, zeta = 0) whose bending law stiffens inside a reach of
    +-6 1/m and is continued beyond it with tail factor g, released from 120 deg for 0.5 s: the
    largest |kappa| [1/m], the stored energy's range and the total energy's largest change [J];
    the stored energy sums ds (int_0^kappa m + EA (nu1 - nu1_0)^2 / 2 + GA (nu2 - nu2_0)^2 / 2)
    over the segments, the bending part by quadrature of the continued law."""
    from dataclasses import replace

    from paper_rod import paper_rod

    from crgpr.learning.learned import LearnedRod, kinetic_energy, rollout
    from crgpr.learning.nominal import NOMINAL_LAWS, NominalLaw
    from crgpr.learning.warp import BendingWarp
    from crgpr.physics.params import SimSettings
    from crgpr.physics.rod import strains

    P = replace(paper_rod(N=8), zeta=0.0)
    reach = Reach(lo=-6.0, hi=6.0, span=1.2, covered_lo=-6.0, covered_hi=6.0, band=0.2)
    stiffening = BendingWarp(NominalLaw("m", P), 0.0, 6.0, np.array([0.0, 0.8]))
    m = TangentContinuation(stiffening, reach, np.array([g]))
    model = LearnedRod({**{c: NominalLaw(k, P) for k, c in NOMINAL_LAWS.items()}, "obj_m": m}, "objective", P)
    tr = rollout(model, 120.0, SimSettings(dt=dt, t_end=0.5, record_every=int(round(1e-3 / dt)),
                                           scheme="variational"))
    st = strains(tr.q, P)
    k = st["kappa"]
    grid = np.linspace(-3 * np.abs(k).max(), 3 * np.abs(k).max(), 40001)
    X = np.zeros((grid.size, 5))
    X[:, 0] = grid
    mg = m(X)
    W = np.concatenate([[0.0], np.cumsum(0.5 * (mg[1:] + mg[:-1]) * np.diff(grid))])
    W -= np.interp(0.0, grid, W)
    stored = P.ds * (np.interp(k, grid, W) + 0.5 * P.EA * (st["nu1"] - P.nu1_0) ** 2
                     + 0.5 * P.GA * (st["nu2"] - P.nu2_0) ** 2).sum(-1)
    total = stored + P.rhoA * P.g * (model.wds * tr.q[..., 1]).sum(-1) + kinetic_energy(model, tr.p)
    return float(np.abs(k).max()), float(np.ptp(stored)), float(np.abs(total - total[0]).max())


def test_a_continued_law_keeps_a_potential_whatever_its_tail_factor():
    """Eq. (10): the moment stays a function of kappa beyond the reach, so a frictionless rollout
    conserves the learned H (stored + gravity + kinetic) though the rod bends to 4-6 x the reach:
    to 1e-6 of the energy it exchanges, second order in the step."""
    for g in (1.0, 0.3):
        reach_out, exchange, drift = _frictionless_energy(g, 1e-4)
        assert reach_out > 4 * 6.0 and drift < 1e-6 * exchange, (g, reach_out, exchange, drift)
    assert _frictionless_energy(0.3, 5e-5)[2] < drift / 3.0


def test_a_law_seen_on_one_side_follows_its_edge_not_the_far_sides_trend():
    """A saturating law odd about 0, its noisy samples from one side (as a record that bends the
    rod one way gives them, unmirrored): on the unseen side the band is as wide as the moment
    almost at once, so the reach stops at the edge. Beyond it the tangent there follows the law
    better than the GP's linear-basis trend, fitted where the law saturates, and with the rest
    curvature known the mirror image of the seen side follows it far better (ten noise draws)."""
    ms, ei = 0.06, 1.5e-3

    def truth(k):
        return ms * np.tanh(ei * k / ms)
    ratios = []
    for seed in range(10):
        rng = np.random.default_rng(seed)
        k = rng.uniform(-70.0, 3.0, 300)
        gp = fit_gp(k[:, None], truth(k) + 3e-3 * rng.standard_normal(k.size), basis="linear", n_restarts=2,
                    seed=0)
        x = np.linspace(k.min() - 36.5, k.max() + 36.5, 201)
        mean, var = gp.predict(x[:, None], return_var=True)
        mean, sd = np.ravel(mean), np.sqrt(np.ravel(var))
        tab = _table(x, mean, sd, float(k.min()), float(k.max()))
        for center in (None, 0.0):
            r = law_reach(tab, band=0.2, tangent_span=0.1, center=center)
            assert r.hi == k.max() and r.lo < k.min()  # the seen side keeps its GP beyond the edge
            cont = continue_table(tab, r)
            far = (x > 15.0) & (x < 40.0)
            flagged = cont["continued"].to_numpy()
            assert flagged[far].all() and not flagged[tab["covered"].to_numpy()].any()
            assert np.all(np.diff(cont["mean"].to_numpy()[x > r.hi]) >= 0.0)
            ratios.append(np.abs(cont["mean"].to_numpy()[far] - truth(x[far])).max()
                          / np.abs(mean[far] - truth(x[far])).max())
    tangent, mirrored = np.array(ratios[0::2]), np.array(ratios[1::2])
    assert np.median(tangent) < 0.75 and mirrored.max() < 0.25, ratios
