"""The materials study (docs/materials.md, "The materials study"): the true law of each segment,
the law metrics on cases with a known answer, the config checks, and the study's rules end to end
on the smoke config."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from paper_rod import paper_rod

from crgpr.commands.materials import COLUMNS, INPUTS, LEARN_DEFAULTS, learn_config
from crgpr.config import ConfigError, load_config, material_case_rod, rod_params
from crgpr.physics.material import Material
from crgpr.physics.params import RodParams
from crgpr.physics.rod import segment_moment_law, straight_rod, strains
from crgpr.report.metrics import law_accuracy

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "tests" / "smoke_config.yaml"


def _rod(**material) -> RodParams:
    return paper_rod(N=8, material=Material(**material))


def _bent(params: RodParams, seed: int) -> np.ndarray:
    """A straight rod with random nodal angles (curvatures of order 10 1/m)."""
    q = straight_rod(0.3, params)
    rng = np.random.default_rng(seed)
    q[1:, 2] += np.cumsum(rng.normal(0.0, 10.0 * params.ds, params.N))
    q[1:, :2] = q[0, :2] + np.cumsum(params.ds * np.stack([np.cos(q[:-1, 2]), np.sin(q[:-1, 2])], -1), 0)
    return q


@pytest.mark.parametrize("material", [
    {},
    {"bending_law": "exponential", "bending_beta": 0.05, "stiffness_profile": [[0.0, 1.5], [1.0, 0.6]]},
    {"bending_law": "saturating", "saturation_moment": 0.02,
     "rest_curvature_profile": [[0.0, 2.5], [1.0, 1.5]]},
    {"defect_start": 0.4, "defect_end": 0.6, "defect_factor": 0.3, "defect_edge": 0.02},
])
def test_the_true_law_of_each_segment_is_the_simulators_moment(material):
    """m(kappa_j, s_j) of segment j equals the moment the simulator's strains give that segment."""
    p = _rod(**material)
    s = strains(_bent(p, 3), p)
    law = segment_moment_law(p, s["kappa"])  # (N, N): every curvature at every segment's s
    np.testing.assert_allclose(np.diag(law), s["m"], rtol=1e-12, atol=1e-15)


def test_the_true_law_follows_the_closed_forms_along_s():
    p = _rod(bending_law="exponential", bending_beta=0.05, stiffness_profile=[[0.0, 1.5], [1.0, 0.6]],
             rest_curvature_profile=[[0.0, 2.0], [1.0, 0.0]])
    kappa = np.linspace(-30.0, 30.0, 7)
    s_rel = (np.arange(p.N) + 0.5) / p.N
    ei = p.EI * (1.5 - 0.9 * s_rel)
    dk = kappa[:, None] - 2.0 * (1.0 - s_rel)[None, :]
    np.testing.assert_allclose(segment_moment_law(p, kappa), ei * np.sinh(0.05 * dk) / 0.05, rtol=1e-12)


def test_a_learned_law_equal_to_the_truth_scores_zero_error_and_full_coverage():
    x = np.linspace(-20.0, 20.0, 41)
    truth = np.sinh(0.05 * x)[:, None]
    out = law_accuracy(truth[:, 0], np.full(x.size, 1e-3), truth, np.ones_like(truth, bool))
    assert out == {"law_rmse": 0.0, "law_band_coverage": 1.0}


@settings(max_examples=40, deadline=None)
@given(shift=st.floats(0.01, 5.0), slope=st.floats(0.1, 10.0), sd=st.floats(0.001, 3.0))
def test_a_shifted_law_scores_its_shift_over_the_spread(shift, slope, sd):
    """Truth m = slope x on x in [-1, 1] (spread 2 slope), learned = truth + shift: the error is
    shift / (2 slope), and the band covers the truth everywhere or nowhere (shift vs 1.96 sd)."""
    x = np.linspace(-1.0, 1.0, 51)
    truth = (slope * x)[:, None]
    out = law_accuracy(slope * x + shift, np.full(x.size, sd), truth, np.ones_like(truth, bool))
    assert out["law_rmse"] == pytest.approx(shift / (2.0 * slope), rel=1e-9)
    if abs(shift - 1.959963984540054 * sd) > 1e-9 * shift:
        assert out["law_band_coverage"] == (1.0 if shift < 1.959963984540054 * sd else 0.0)


def test_coverage_counts_the_points_inside_the_band_per_segment():
    """Two segments, the learned law on the first: the band holds the first everywhere and the
    second (shifted by 1) only where the band is wider than 1; only the compared points count."""
    x = np.linspace(0.0, 1.0, 11)
    truth = np.stack([x, x + 1.0], -1)
    sd = np.where(x < 0.45, 1.0, 0.1)  # 1.96 sd > 1 on x < 0.45 (5 points)
    where = np.ones_like(truth, bool)
    where[0] = False  # the first grid point is not compared (2 of 22 points)
    out = law_accuracy(x, sd, truth, where)
    assert out["law_band_coverage"] == pytest.approx((10 + 4) / 20)
    assert out["law_rmse"] == pytest.approx(math.sqrt(10 / 20) / 1.9)
    assert math.isnan(law_accuracy(x, sd, truth, np.zeros_like(where))["law_rmse"])


def test_a_case_overlay_with_a_bad_law_is_one_config_error_naming_the_case():
    cfg = load_config(SMOKE)
    assert material_case_rod(cfg, "graded").material.bending_law == "exponential"
    assert material_case_rod(cfg, "linear") == RodParams.from_dict(cfg["rod"])
    with pytest.raises(ConfigError, match=r"materials_study\.cases\.bad: rod\.material\.bending_beta"):
        load_config(SMOKE, {"materials_study": {"cases": {"bad": {"bending_law": "exponential"}}}})
    with pytest.raises(ConfigError, match=r"materials_study\.cases\.bad\.stiffness"):
        load_config(SMOKE, {"materials_study": {"cases": {"bad": {"stiffness": 2.0}}}})
    with pytest.raises(ConfigError, match=r"materials_study\.camera_rate_hz"):
        load_config(SMOKE, {"materials_study": {"camera_rate_hz": 300.0}})


def test_each_input_learns_under_its_own_caps_the_defaults_source_under_none_and_a_scalar_cap_is_an_error():
    """In ``all`` both inputs learn under the study's run-time caps (config.yaml); the source
    ``camera_defaults`` (target ``sweeps``) learns the camera record as ``crgpr learn`` does with
    the config as it is: its own n_train, n_hyper and frames."""
    cfg = load_config(ROOT / "config.yaml")
    gm = cfg["gradient_models"]
    ms = cfg["materials_study"]
    for source in INPUTS:
        capped = learn_config(cfg, source)
        assert capped["gradient_models"]["n_hyper"] == min(gm["n_hyper"], ms["n_hyper_max"][source])
        assert all(spec["n_train"] == min(gm[group][k]["n_train"], ms["n_train_max"][source])
                   for group in ("models", "objective_models")
                   for k, spec in capped["gradient_models"][group].items())
        assert capped["camera"]["learn"]["n_t_out"] == ms["camera_n_t_out"]
    assert learn_config(cfg, "camera")["gradient_models"] != gm  # the caps bind in config.yaml
    defaults = learn_config(cfg, LEARN_DEFAULTS)
    assert defaults == cfg and defaults is not cfg
    with pytest.raises(ValueError, match="camera_raw"):
        learn_config(cfg, "camera_raw")
    with pytest.raises(ConfigError, match=r"materials_study\.n_train_max"):
        load_config(SMOKE, {"materials_study": {"n_train_max": 600}})


def test_a_case_is_the_linear_material_plus_its_keys_whatever_the_configs_own_material():
    cfg = load_config(SMOKE, {"rod": {"material": {"bending_law": "exponential", "bending_beta": 0.05}}})
    assert material_case_rod(cfg, "linear").material == Material()
    assert material_case_rod(cfg, "graded").material == Material(
        bending_law="exponential", bending_beta=0.05, stiffness_profile=((0.0, 1.5), (1.0, 0.6)))


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """The study's rules on the smoke config, into a fresh directory."""
    work = tmp_path_factory.mktemp("materials")
    cmd = [sys.executable, "-m", "snakemake", "-s", str(ROOT / "Snakefile"), "-d", str(work), "--configfile",
           str(SMOKE), "-j1", "results/tables/material_laws.csv"]
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=1200,
                         env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-4000:]
    return work


@pytest.mark.slow
def test_the_study_writes_one_row_per_case_input_and_angle(study):
    cfg = load_config(SMOKE)
    ms = cfg["materials_study"]
    table = pd.read_csv(study / "results" / "tables" / "material_laws.csv")
    assert list(table.columns) == list(COLUMNS)
    keys = {(c, i, float(a)) for c in ms["cases"] for i in INPUTS for a in ms["test_deg"]}
    assert set(zip(table["case"], table["input"], table["theta0_deg"], strict=True)) == keys
    assert len(table) == len(keys)
    assert np.all(np.isfinite(table[["rmse_theta", "tip_rmse_over_L", "nominal_rmse_theta"]]))
    # the control case's true rod is the nominal one: the nominal rollout is the truth itself
    lin = table[table["case"] == "linear"]
    assert (lin["nominal_rmse_theta"] == 0.0).all() and lin["ratio_to_nominal"].isna().all()
    graded = table[table["case"] == "graded"]
    assert (graded["nominal_rmse_theta"] > 0).all()
    np.testing.assert_allclose(graded["ratio_to_nominal"],
                               graded["rmse_theta"] / graded["nominal_rmse_theta"])
    assert ((table["law_band_coverage"] >= 0) & (table["law_band_coverage"] <= 1)).all()
    for case in ms["cases"]:
        assert (study / "results" / "figures" / f"material_{case}.png").read_bytes()[:4] == b"\x89PNG"
        for source in INPUTS:
            assert (study / "benchmarks" / "materials" / f"learn_{case}_{source}.tsv").is_file()
            # the laws are learned or nominal as the data decide: the learned rod is also compared
            # with the nominal one on the record's held-out blocks, and a fall-back keeps no law
            man = json.loads((study / "results" / "materials" / case / "models" / source / "manifest.json"
                              ).read_text())
            fit, damping = man["record_fit"], man["bending_damping"] or {}
            if man["models"] or man["models_refused"] or damping.get("kept"):
                assert math.isfinite(fit["rmse_compared"]) and not math.isnan(fit["rmse_nominal"])
                better = fit["nominal_log_ratio"] > 1.96 * fit["nominal_log_ratio_se"]
                assert fit["nominal_fallback"] == (better or fit["rmse_nominal"] < fit["rmse_compared"])
            else:  # nothing learned: the learned rod is the nominal one, not compared
                assert not fit["nominal_fallback"] and math.isnan(fit["nominal_log_ratio"])
            if fit["nominal_fallback"]:
                assert man["models"] == [] and man["models_refused"] and not fit["kept"]


def test_a_nominal_bending_law_is_scored_as_the_nominal_rod_with_no_band(tmp_path):
    """Where the data chose the nominal bending law (``obj_m`` not learned), the law scored is
    EI (kappa - kappa0) with sd 0 for every segment: exact against a linear true rod, and its
    zero-width band misses a true rod that is stiffer."""
    from crgpr.learning.law_tables import bending_law_at_segments
    from crgpr.physics.rod import segment_moment_law

    params = rod_params(load_config(SMOKE))
    x = np.linspace(-5.0, 5.0, 21)
    mean, sd = bending_law_at_segments(tmp_path, ["obj_n1"], params, x, 100, 0, 10)
    assert mean.shape == sd.shape == (x.size, params.N) and not sd.any()
    where = np.ones((x.size, params.N), bool)
    exact = law_accuracy(mean, sd, segment_moment_law(params, x), where)
    assert exact["law_rmse"] == pytest.approx(0.0, abs=1e-12) and exact["law_band_coverage"] == 1.0
    stiffer = law_accuracy(mean, sd, segment_moment_law(params.replace(E=1.2 * params.E), x), where)
    assert stiffer["law_rmse"] > 0.05 and stiffer["law_band_coverage"] < 0.1
