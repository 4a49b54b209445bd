"""The data decide between a learned and the nominal law, and whether the bending law varies
along the rod (learning/law_choice.py, crgpr learn)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crgpr.commands.learn import learn, load_learned, read_manifest
from crgpr.config import ConfigError, load_config, rod_params, validate_schema
from crgpr.gp import load_model
from crgpr.io import read_parquet, write_parquet
from crgpr.learning.features import segment_arclength
from crgpr.learning.law_choice import (
    arclength_dependence,
    compare_heldout,
    learned_or_nominal,
    nominal_choice,
    poly_design,
    segment_weights,
    standin_departure,
)
from crgpr.learning.nominal import NOMINAL_LAWS, NominalLaw
from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import simulate, trajectory_frame

SMOKE = "tests/smoke_config.yaml"
EI = 1.5e-3  # a bending stiffness of the order of the config's rod [N m^2]
N, L0 = 10, 0.5


def _ar1(n: int, rho: float, sd: float, rng: np.random.Generator) -> np.ndarray:
    """Time-correlated errors (AR(1)), as a trajectory's systematic target errors are."""
    e = np.empty(n)
    e[0] = rng.standard_normal()
    for i in range(1, n):
        e[i] = rho * e[i - 1] + np.sqrt(1 - rho**2) * rng.standard_normal()
    return sd * e


def _bending_record(law, n_t: int = 300, seed: int = 0, noise: float = 2e-5):
    """A cantilever-like record on N segments (time-major rows): curvature amplitude largest at
    the clamp, a damped swing; moments m = law(kappa, s) plus time-correlated errors."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, n_t)[:, None]
    s = segment_arclength(N, L0 / N)[None, :]
    swing = 0.6 + 0.4 * np.exp(-t) * np.cos(8 * t)
    kappa = -60.0 * (1 - s / L0) ** 2 * swing + 0.5 * rng.standard_normal((n_t, N))
    S = np.broadcast_to(s, kappa.shape)
    m = law(kappa, S) + _ar1(kappa.size, 0.99, noise, rng).reshape(kappa.shape)
    return kappa.ravel(), S.ravel(), m.ravel()


def test_the_nominal_law_is_kept_where_the_learned_one_does_not_predict_heldout_blocks_better():
    # truth = the nominal law; the samples' errors are correlated in time (a record's systematic
    # errors): a polynomial fitted to them does not predict other time blocks
    kappa, _, m = _bending_record(lambda k, s: EI * k, noise=2e-4)
    c = learned_or_nominal(kappa[:, None], m, EI * kappa, 3, 10, pooled=True)
    assert not c.richer, c


def test_the_learned_law_is_chosen_where_the_truth_is_nonlinear():
    beta = 0.03  # exponential stiffening: m = EI sinh(beta kappa) / beta
    kappa, _, m = _bending_record(lambda k, s: EI * np.sinh(beta * k) / beta)
    c = learned_or_nominal(kappa[:, None], m, EI * kappa, 3, 10, pooled=True)
    assert c.richer and c.heldout_mse_richer < 0.1 * c.heldout_mse_simple, c



def test_a_law_that_departs_only_at_the_large_strains_of_a_decaying_release_is_learned():
    """A release's amplitude decays, so a stiffening law departs from the nominal one only in its
    first blocks: on the total held-out error it is learned, while per-block log ratios, which
    weigh the many small-amplitude blocks as much, do not show it consistently."""
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 2.0, 2000)
    kappa = 60.0 * np.exp(-t / 0.25) * np.sin(2 * np.pi * 3.0 * t)
    beta = 0.03
    m = EI * np.sinh(beta * kappa) / beta + _ar1(t.size, 0.99, 2e-4, rng)
    pooled = learned_or_nominal(kappa[:, None], m, EI * kappa, 3, 10, pooled=True)
    blocks = learned_or_nominal(kappa[:, None], m, EI * kappa, 3, 10, pooled=False)
    assert pooled.richer and not blocks.richer, (pooled, blocks)
    # and the nominal truth on the same record is kept either way
    m0 = EI * kappa + _ar1(t.size, 0.99, 2e-4, rng)
    assert not learned_or_nominal(kappa[:, None], m0, EI * kappa, 3, 10, pooled=True).richer

def test_a_departure_in_every_block_is_learned_though_one_block_dominates_the_total_error():
    """A rest curvature shifts the law by the same moment in every block; where the targets'
    errors are far larger in one block (a record from another discretisation: the coarse grid's
    moment balance is worst in the large motions), the total held-out error hides it, while the
    per-block log ratios show it, and either rule decides. The nominal truth under the same
    errors is kept."""
    rng = np.random.default_rng(11)
    t = np.linspace(0.0, 2.0, 2000)
    kappa = 30.0 * np.exp(-t / 0.8) * np.sin(2 * np.pi * 2.0 * t)
    k_rest = 2.0  # [1/m]
    sd = np.where(t < 0.2, 60.0, 1.0) * EI * k_rest * 0.05  # one block's errors 60x the others'
    noise = sd * _ar1(t.size, 0.99, 1.0, rng)
    m = EI * (kappa - k_rest) + noise
    A = poly_design(kappa, 3)
    total_only = compare_heldout(m, np.zeros((t.size, 0)), A, 10, 3, offset=EI * kappa, pooled=True)
    c = learned_or_nominal(kappa[:, None], m, EI * kappa, 3, 10, pooled=True)
    assert not total_only.richer and c.richer, (total_only, c)
    assert c.perblock_log_ratio > 1.96 * c.perblock_log_ratio_se
    m0 = EI * kappa + noise
    assert not learned_or_nominal(kappa[:, None], m0, EI * kappa, 3, 10, pooled=True).richer


def test_a_nominal_law_the_data_chose_has_the_band_of_the_departure_they_did_not_rule_out():
    """Kept nominal, the bending law's band is its richer stand-in's departure from it, fitted on
    every sample: a softening law whose departure the held-out blocks do not show consistently
    (its errors correlated over the record) lies inside that band over most of the record's
    curvatures, where a nominal law with no band holds it nowhere; the departure of a nominal
    truth is small next to the law; a law learned (richer chosen), or one left nominal by a
    fixed list, gets no such band."""
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 2.0, 2000)
    kappa = 60.0 * np.exp(-t / 0.8) * np.sin(2 * np.pi * 3.0 * t)

    def soft(k):
        return EI * 30.0 * np.tanh(k / 30.0)
    m = soft(kappa) + _ar1(t.size, 0.999, 0.04, rng)  # slowly wandering offsets, as large as the law
    c = learned_or_nominal(kappa[:, None], m, EI * kappa, 3, 10, pooled=True)
    assert not c.richer and c.standin is not None and len(c.standin) == 4, c
    grid = np.linspace(kappa.min(), kappa.max(), 201)
    band = 1.96 * standin_departure(grid, c.to_dict())
    inside = np.abs(EI * grid - soft(grid)) <= band
    assert inside.mean() > 0.8, inside.mean()
    truth = learned_or_nominal(kappa[:, None], EI * kappa + _ar1(t.size, 0.99, 2e-4, rng), EI * kappa, 3, 10,
                               pooled=True)
    assert np.max(standin_departure(grid, truth.to_dict())) < 0.05 * np.max(np.abs(EI * grid))
    learned = learned_or_nominal(kappa[:, None], soft(kappa), EI * kappa, 3, 10, pooled=True)
    assert learned.richer and not standin_departure(grid, learned.to_dict()).any()
    from crgpr.learning.law_tables import bending_law_at_segments
    P = rod_params(load_config("tests/smoke_config.yaml"))
    mean, sd = bending_law_at_segments(".", [], P, grid, 100, 0, 0, choice=c.to_dict())
    assert np.allclose(mean, (P.EI * (grid - P.kappa0))[:, None]) and sd.shape == (grid.size, P.N)
    assert np.array_equal(sd, np.repeat(standin_departure(grid, c.to_dict())[:, None], P.N, axis=1))
    man = {"nominal_laws": ["n1", "n2", "m"], "law_choice": {"m": c.to_dict()}}
    assert nominal_choice(man) == c.to_dict()
    assert nominal_choice({"nominal_laws": ["n1", "n2", "m"], "law_choice": None}) is None
    assert nominal_choice({**man, "nominal_laws": ["n1", "n2"]}) is None


@settings(max_examples=15, deadline=None)
@given(scale=st.floats(1e-3, 1e3))
def test_the_decision_does_not_depend_on_the_units_of_the_law(scale):
    kappa, _, m = _bending_record(lambda k, s: EI * np.tanh(k / 30.0) * 30.0)
    a = learned_or_nominal(kappa[:, None], m, EI * kappa, 3, 10, pooled=True)
    b = learned_or_nominal(kappa[:, None], scale * m, scale * EI * kappa, 3, 10, pooled=True)
    assert a.richer == b.richer and a.heldout_log_ratio == pytest.approx(b.heldout_log_ratio, abs=1e-6)


def test_a_uniform_nonlinear_law_does_not_take_arclength_as_an_input():
    # saturating law, uniform along the rod: the clamp's segments see the large curvatures, so a
    # rigid law in kappa would fit better per region; the spline in kappa leaves s nothing to add
    m_s = 0.06
    kappa, s, m = _bending_record(lambda k, s: m_s * np.tanh(EI * k / m_s))
    for s_degree, weights in ((1, "none"), (2, "segment")):
        c = arclength_dependence(kappa, s, m, 3, 8, s_degree, 10, weights)
        assert not c.richer, (s_degree, weights, c)


def test_a_graded_rod_takes_arclength_as_an_input():
    kappa, s, m = _bending_record(lambda k, s: EI * (1.5 - s / L0) * k)  # EI(s) from 1.5 EI to 0.5 EI
    for s_degree, weights in ((1, "none"), (2, "segment")):
        c = arclength_dependence(kappa, s, m, 3, 8, s_degree, 10, weights)
        assert c.richer and c.heldout_mse_richer < 0.5 * c.heldout_mse_simple, (s_degree, weights, c)


def test_a_rod_soft_near_its_free_tip_takes_arclength_only_where_every_segment_counts_alike():
    """EI uniform over the first half, then down to 0.4 EI at the tip, where the curvatures and
    moments are a small fraction of the clamp's: unweighted, the clamp's errors decide and the
    variation is not seen; with each segment's samples weighted by 1 / rms of its moments
    (``segment_weights``) it is."""
    def law(k, s):
        return EI * np.where(s < 0.5 * L0, 1.0, 1.0 - 1.2 * (s / L0 - 0.5)) * k
    kappa, s, m = _bending_record(law, noise=2e-4)
    assert not arclength_dependence(kappa, s, m, 3, 8, 2, 10, "none").richer
    c = arclength_dependence(kappa, s, m, 3, 8, 2, 10, "segment")
    assert c.richer, c
    w = segment_weights(s, m)
    for v in np.unique(s):
        assert np.sqrt(np.mean((w * m)[s == v] ** 2)) == pytest.approx(1.0)


def test_a_stiff_section_away_from_the_clamp_is_not_the_nominal_law():
    """EI 1.8 times the nominal over s/L0 0.55-0.75, where the curvatures are small: a stand-in
    uniform along the rod gains little on the nominal law; one in (kappa, s) predicts the
    held-out blocks consistently better (``grey_box`` then learns m, with s as an input). On the
    nominal rod's record neither does."""
    def law(k, s):
        return EI * k * (1.0 + 0.8 * ((s >= 0.55 * L0) & (s <= 0.75 * L0)))
    kappa, s, m = _bending_record(law)
    uniform = learned_or_nominal(kappa[:, None], m, EI * kappa, 3, 10, pooled=True)
    along = learned_or_nominal(np.c_[kappa, s], m, EI * kappa, 3, 10, pooled=True)
    assert along.richer and along.heldout_log_ratio > uniform.heldout_log_ratio + 0.5, (uniform, along)
    kappa, s, m = _bending_record(lambda k, s: EI * k, noise=2e-4)
    assert not learned_or_nominal(np.c_[kappa, s], m, EI * kappa, 3, 10, pooled=True).richer


def test_schema_rejects_an_unknown_arclength_setting():
    cfg = copy.deepcopy(load_config(SMOKE))
    cfg["camera"]["learn"]["bending_arclength"] = "sometimes"
    with pytest.raises(ConfigError, match="bending_arclength"):
        validate_schema(cfg)
    cfg = copy.deepcopy(load_config(SMOKE))
    cfg["camera"]["learn"]["choice_s_tests"]["positions"] = [[2, "clamp"]]
    with pytest.raises(ConfigError, match="choice_s_tests"):
        validate_schema(cfg)
    with pytest.raises(ValueError, match="arclength weights"):
        arclength_dependence(np.ones(40), np.arange(40.0), np.ones(40), 3, 0, 1, 2, "clamp")


PROFILE = [[0.0, 1.5], [1.0, 0.5]]  # EI(s) = EI (1.5 - s / L0)


@pytest.fixture(scope="module")
def graded_and_linear(tmp_path_factory, smoke_training_run):
    """Smoke rods learned from their noise-free full state: a graded one (EI from 1.5 EI at the
    clamp to 0.5 EI at the tip) and the nominal linear one."""
    cfg, tr = smoke_training_run
    tcfg = copy.deepcopy(cfg)
    tcfg["rod"]["material"]["stiffness_profile"] = PROFILE
    graded = rod_params(tcfg)
    rec = simulate(85.0, graded, SimSettings(dt=1e-4, t_end=0.4, record_every=40, scheme="variational"))
    d = tmp_path_factory.mktemp("law_choice")
    write_parquet(trajectory_frame(rec), d / "graded.parquet")
    learn(d / "graded.parquet", d / "graded", cfg, "objective", "gp")
    write_parquet(trajectory_frame(tr), d / "linear.parquet")
    learn(d / "linear.parquet", d / "linear", cfg, "objective", "gp")
    return cfg, d


def test_graded_rods_learned_law_uses_arclength_and_recovers_EI_of_s_within_its_band(graded_and_linear):
    cfg, d = graded_and_linear
    model, man = load_learned(d / "graded")
    assert man["bending_arclength"]["used"] and man["bending_arclength"]["choice"]["richer"]
    assert "obj_m" in man["models"] and "m" not in man["nominal_laws"]
    tab = read_parquet(d / "graded" / "laws.parquet")
    m = tab[(tab["law"] == "obj_m") & (tab["input"] == "kappa") & tab["covered"]]
    P = rod_params(cfg)
    at_s = sorted(m["at_s"].unique())
    assert len(at_s) == cfg["camera"]["learn"]["law_table"]["s_points"]
    Xt = load_model(d / "graded" / "obj_m")[0]["X"]  # training inputs [kappa, s]
    slopes = []
    for sv in at_s:
        # the curvatures the segments at (or beside) this s were trained on
        k_s = Xt[np.abs(Xt[:, 1] - sv) <= P.ds + 1e-12, 0]
        e = m[(m["at_s"] == sv) & (m["x"] >= k_s.min()) & (m["x"] <= k_s.max())]
        truth = P.EI * (1.5 - sv / P.L0) * (e["x"] - (man["bending_odd_about"] or 0.0))
        inside = np.abs(e["mean"] - truth) <= 1.96 * e["sd"] + 0.05 * np.abs(truth).max()
        assert inside.mean() > 0.9, (sv, float(inside.mean()))
        slopes.append(np.polyfit(e["x"], e["mean"], 1)[0])
    assert slopes[0] > slopes[-1]  # stiffer at the clamp than at the tip
    # the rollout feeds every segment its own s: the same curvature bends the rod's segments by
    # the law of their place
    X = np.zeros((N, 5))
    X[:, 0] = 10.0
    mm = model.components["obj_m"](X)
    assert mm[0] > mm[-1] > 0


def test_stretch_and_shear_laws_that_spoil_the_record_go_nominal_before_the_bending_law(graded_and_linear):
    """The graded rod's 0.4 s record: its shear law of nu2 beats the nominal one on the held-out
    blocks of its own samples (targets the prefilter smooths), but the rod with it follows the
    record worse than the nominal rod; taken nominal, the rod with the learned bending law
    follows it better, so only n1, n2 go nominal (not every law)."""
    _, d = graded_and_linear
    man = read_manifest(d / "graded")
    assert man["law_choice"]["n2"]["richer"]
    assert man["strain_laws_nominal_by_record_fit"] is True, man["record_fit"]
    assert {"n1", "n2"} <= set(man["nominal_laws"]) and "obj_n2" in man["models_refused"]
    assert not man["record_fit"]["nominal_fallback"] and "obj_m" in man["models"]
    assert man["record_fit"]["rmse_start_only"] < man["record_fit"]["rmse_nominal"]


def test_linear_rod_keeps_the_nominal_laws_and_no_arclength(graded_and_linear):
    _, d = graded_and_linear
    model, man = load_learned(d / "linear")
    assert not man["bending_arclength"]["used"]
    ch = man["law_choice"]
    assert set(ch) == {"n1", "n2", "m", "p_x", "p_y", "p_theta"}
    # the learned stretch law, bending law and momentum maps do not predict held-out blocks better
    # (the shear law of this 0.4 s record does: docs/learned-laws.md, "Not done")
    for k, comp in (("n1", "obj_n1"), ("m", "obj_m"), ("p_x", "dH_dp_x"), ("p_theta", "dH_dp_theta")):
        assert k in man["nominal_laws"] and not ch[k]["richer"], ch[k]
        assert isinstance(model.components[comp], NominalLaw)
    # a law is learned where it predicts its held-out blocks better and the rod with it follows
    # the record (the shear law of this record may not: its rod can leave the physical range)
    refused = set(man["models_refused"])
    for k, c in ch.items():
        assert (k not in man["nominal_laws"]) == (c["richer"] and NOMINAL_LAWS[k] not in refused), (k, c)
    if "n2" in man["nominal_laws"] and ch["n2"]["richer"]:
        fit = man["record_fit"]
        assert man["strain_laws_nominal_by_record_fit"] or fit["nominal_fallback"], fit
    # m kept nominal by the uniform stand-in is offered a stand-in varying along s too, kept too
    assert ch["m"]["decided_by"] == "uniform" and not ch["m"]["along_s"]["richer"]


def test_a_nominal_momentum_map_is_p_over_the_mass_per_length():
    P = rod_params(load_config(SMOKE))
    p = np.linspace(-0.3, 0.3, 7)
    assert np.allclose(NominalLaw("p_x", P)(p), p / P.rhoA)
    assert np.allclose(NominalLaw("p_theta", P)(p), p / P.rhoI)
    assert np.allclose(NominalLaw("p_y", P).slope(p), 1.0 / P.rhoA)
