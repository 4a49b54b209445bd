"""Trajectory UQ of a `crgpr learn` model directory (the camera method):
its learned GPs sampled, its nominal laws kept, rolled out through the mean model's assembly
(``commands.learn.learned_components``) and rollout; a large 1D law sampled sparsely and
tabulated on the rollout's grid; the rows of an odd law kept with their reflections."""

from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from crgpr.commands.camera import camera_frame
from crgpr.commands.learn import (
    learn,
    learned_components,
    learned_damping,
    learned_models,
    load_learned,
    read_manifest,
)
from crgpr.commands.uq import uq_rollout_learned, uq_samples_learned
from crgpr.config import ConfigError, load_config, validate_config
from crgpr.io import read_metadata, read_parquet, write_parquet
from crgpr.learning.extrapolation import TangentContinuation
from crgpr.learning.learned import rollout
from crgpr.learning.nominal import NominalLaw, SelectedInputs
from crgpr.physics.params import SimSettings
from crgpr.uq.rollout import UQ_COLUMNS, rollout_samples
from crgpr.uq.samples import TabulatedSamples, draw_model_samples, load_gp_spec, load_samples
from crgpr.uq.settings import UQSettings

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "tests" / "smoke_config.yaml"
SHORT = SimSettings(dt=1e-4, t_end=0.03, record_every=10, scheme="variational")


@pytest.fixture(scope="module")
def grey_box(tmp_path_factory, smoke_training_run) -> tuple[dict, Path]:
    """A grey-box model directory (n1, n2 nominal, m(kappa) odd and learned, momentum maps) from
    1 mm camera positions of the smoke training run."""
    cfg, tr = smoke_training_run
    d = tmp_path_factory.mktemp("uq_learned")
    write_parquet(camera_frame(tr.t, tr.q, 1e-3, np.random.default_rng(7)), d / "cam.parquet")
    grey = copy.deepcopy(cfg)
    grey["camera"]["learn"]["nominal_laws"] = ["n1", "n2"]  # the bending law and momentum maps learned
    grey["camera"]["learn"]["bending_arclength"] = "never"  # m(kappa): one input, tabulated samples
    learn(d / "cam.parquet", d / "model", grey, "objective", "gp")
    man = read_manifest(d / "model")
    assert man["nominal_laws"] == ["n1", "n2"] and man["rest_state"]["symmetric"]
    rest = man["rest_state"]  # the band contains the straight rod's 0: mirrored about the nominal 0
    assert rest["band_lo"] <= 0.0 <= rest["band_hi"] and man["bending_odd_about"] == 0.0
    print("bending damping of the smoke camera model:", man["bending_damping"])
    return cfg, d


def _settings(cfg: dict, **changes) -> UQSettings:
    return dataclasses.replace(UQSettings.from_section(cfg["uq"]), **changes)


def test_learned_rod_with_zero_variance_samples_reproduces_the_mean_rollout(grey_box):
    """Every learned GP replaced by S copies of its rollout table (zero posterior variance), the
    nominal laws kept: the sampled rod, assembled by the same ``learned_components``, rolls out
    the mean model's trajectory for every sample (to round-off)."""
    _, d = grey_box
    mean, man = load_learned(d / "model")
    ref = rollout(mean, 125.0, SHORT)
    S = 3
    zero = {}
    for m in learned_models(man):
        with np.load(d / "model" / f"{m}.npz", allow_pickle=False) as a:
            zero[m] = TabulatedSamples(a["table_x"], np.repeat(a["table_y"][None], S, axis=0))
    comps, center = learned_components(d / "model", man, zero.__getitem__)
    assert isinstance(comps["obj_n1"], NominalLaw) and isinstance(comps["obj_m"], TangentContinuation)
    assert isinstance(comps["obj_m"].component, SelectedInputs)  # each sample continued beyond the reach
    t, q, p, keep, div = rollout_samples(comps, "objective", mean.params, center, 125.0, SHORT,
                                         learned_damping(man))
    assert div == [] and list(keep) == list(range(S))
    np.testing.assert_array_equal(t, ref.t)
    assert np.abs(ref.q[-1] - ref.q[0]).max() > 1e-3  # the rod moved
    for s in range(S):
        # the tables' interpolation in another order of operations: round-off only, accumulated
        # over the rollout's steps (measured up to 1.1e-12 rad; any model difference is > 1e-6)
        np.testing.assert_allclose(q[s], ref.q, rtol=0, atol=1e-10)
        np.testing.assert_allclose(p[s], ref.p, rtol=1e-7, atol=1e-9 * np.abs(ref.p).max())


def test_odd_law_rows_are_kept_next_to_their_reflections(grey_box):
    """m(kappa) is trained on samples and their reflections (2 k_r - kappa, -m), k_r the rest
    curvature estimated from the data; the UQ stage orders them pairwise, so that a contiguous
    held-out block is a time block with its mirror."""
    _, d = grey_box
    about = read_manifest(d / "model")["bending_odd_about"]
    spec, _, grid = load_gp_spec(d / "model" / "obj_m", "obj_m")
    X, y = spec.X[:, 0], np.ravel(spec.Y)
    np.testing.assert_allclose(X[0::2], 2.0 * about - X[1::2], rtol=0, atol=1e-12 * (1.0 + np.abs(X).max()))
    np.testing.assert_allclose(y[0::2], -y[1::2], rtol=0, atol=1e-12)
    assert grid is not None and "table_y" in spec.rollout_arrays


def test_a_large_1d_law_is_sampled_sparsely_and_centred_on_its_table(grey_box):
    """Above ``uq.tabulated_exact_max_n`` points a tabulated 1D GP is sampled on inducing inputs
    and tabulated on the rollout's grid: the samples scatter around exactly the rollout's table
    (the exact mean) with the exact posterior's sd."""
    cfg, d = grey_box
    spec, Z, grid = load_gp_spec(d / "model" / "obj_m", "obj_m")
    st = _settings(cfg, n_samples=400, tabulated_exact_max_n=10, posterior_scale="none", inducing=60)
    tab, info = draw_model_samples(spec, st, 3, Z, grid)
    assert isinstance(tab, TabulatedSamples) and info["tabulated"].startswith("sparse samples")
    assert info["sparse_mean_vs_rollout_table_max_over_sd"] < 0.05
    assert info["sd_ratio_median"] == pytest.approx(1.0, abs=0.05)
    table = spec.rollout_arrays["table_y"]
    inside = (grid > spec.x_mean[0] - 2 * spec.x_std[0]) & (grid < spec.x_mean[0] + 2 * spec.x_std[0])
    g = grid[inside][::50]
    from crgpr.gp.sampling import exact_posterior

    _, var = exact_posterior(spec).mean_var(g[:, None])
    f = tab(np.broadcast_to(g, (400, g.size)))
    assert np.all(np.abs(f.mean(0) - np.interp(g, grid, table)) < 5.0 * np.sqrt(var / 400))
    np.testing.assert_allclose(f.std(0), np.sqrt(var), rtol=0.25)


def test_rule_functions_sample_the_learned_gps_and_roll_them_out(grey_box, tmp_path):
    """``uq_samples_learned`` writes one sample set per learned GP (none for a nominal law) and
    the manifest last; ``uq_rollout_learned`` rolls the S samples out at every angle, the
    samples scatter, and the metadata name the nominal laws."""
    cfg, d = grey_box
    uq = {**cfg["uq"], "n_samples": 4, "paper_n_samples": 2}
    uq_samples_learned(str(d / "model"), uq, 5, str(tmp_path / "s"))
    names = sorted(p.stem for p in (tmp_path / "s").glob("*.npz"))
    assert names == sorted(learned_models(read_manifest(d / "model"))) and "obj_n1" not in names
    assert json.loads((tmp_path / "s" / "manifest.json").read_text())["samples_of"] == str(d / "model")
    smp = load_samples({m: tmp_path / "s" / f"{m}.npz" for m in names})
    assert {s.n_samples for s in smp.values()} == {4}
    sim = {**cfg["simulation"], "t_end_s": 0.03}
    outs = [str(tmp_path / "60.parquet"), str(tmp_path / "125.parquet")]
    uq_rollout_learned(str(tmp_path / "s"), str(d / "model"), "cam", [60, 125], sim, uq, outs)
    df = read_parquet(outs[1], required=UQ_COLUMNS)
    assert sorted(df["sample"].unique()) == [0, 1, 2, 3]
    tip = df[(df["node"] == df["node"].max()) & (df["t"] == df["t"].max())]
    assert tip["theta"].std() > 0
    meta = read_metadata(outs[0])
    assert meta["nominal_laws"] == ["n1", "n2"] and meta["n_diverged"] == 0


def test_uq_methods_may_name_the_camera_method_but_nothing_unknown():
    cfg = load_config(SMOKE)
    cfg["uq"]["methods"] = ["cr_gpr_objective", "cr_gpr_objective_camera"]
    validate_config(cfg, "smoke")
    cfg["uq"]["methods"] = ["cr_gpr_objective", "no_such_method"]
    with pytest.raises(ConfigError, match="no_such_method"):
        validate_config(cfg, "smoke")


def test_a_model_whose_force_laws_are_all_nominal_is_the_same_rod_for_every_member():
    """A model whose force laws the data left all nominal (``camera.learn.nominal_laws: auto``,
    e.g. the materials study's linear rod from camera data): its posterior rod is deterministic,
    every member alike."""
    from crgpr.config import load_config, rod_params
    from crgpr.learning.nominal import NOMINAL_LAWS
    from crgpr.physics.rod import straight_rod
    from crgpr.uq.rollout import n_samples_of, sampled_rod

    P = rod_params(load_config("tests/smoke_config.yaml"))
    comps = {c: NominalLaw(law, P) for law, c in NOMINAL_LAWS.items()}
    with pytest.raises(ValueError, match="none is sampled"):
        n_samples_of(comps)
    assert n_samples_of(comps, default=1) == 1
    q = np.stack([straight_rod(np.radians(a), P) for a in (40.0, 40.0, 70.0)])
    q[..., 2] += 0.01 * np.sin(np.linspace(0, 3, P.N + 1))  # bent, so the laws act
    f = sampled_rod(comps, "objective", P, None).internal(q)
    assert np.array_equal(f[0], f[1]) and not np.allclose(f[0], f[2]) and np.abs(f).max() > 0
