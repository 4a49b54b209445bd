"""Pipeline variants: a named config overlay reruns the faithful CR-GPR pipeline.

The overlay is deep-merged and the result validated like config.yaml; a bad overlay stops the
workflow with one line naming the key (exit 2); a variant reruns only the stages whose config
values or inputs differ from the main run's; a change to one variant reruns only that variant.
"""

from __future__ import annotations

import copy
import math
import shutil

import numpy as np
import pandas as pd
import pytest
import yaml
from test_workflow import COPY_IGNORE, ROOT, SMOKE, planned_jobs, snakemake

from crgpr.commands.smk import config_subset
from crgpr.commands.variants import dotted_keys, variant_config, variant_configs
from crgpr.config import ConfigError, load_config
from crgpr.io import read_metadata, read_parquet
from crgpr.report import sensitivity


@pytest.fixture(scope="module")
def smoke_cfg() -> dict:
    return load_config(SMOKE)


def _with_variant(cfg: dict, name: str, overlay: dict, method: str = "cr_gpr") -> dict:
    cfg = copy.deepcopy(cfg)
    cfg["variants"]["definitions"][name] = {"method": method, "overlay": overlay}
    return cfg


def test_overlay_is_deep_merged_and_leaves_the_rest(smoke_cfg):
    cfg = _with_variant(smoke_cfg, "x", {"rod": {"nu": 0.3},
                                         "gradient_models": {"models": {"q_x": {"n_train": 150}}}})
    v = variant_config(cfg, "x")
    assert v["rod"]["nu"] == 0.3
    assert {k: val for k, val in v["rod"].items() if k != "nu"} == {
        k: val for k, val in smoke_cfg["rod"].items() if k != "nu"}
    # a nested mapping merges key by key: q_x keeps its kernel, basis and floor
    assert v["gradient_models"]["models"]["q_x"] == {**smoke_cfg["gradient_models"]["models"]["q_x"],
                                                      "n_train": 150}
    assert v["gradient_models"]["models"]["q_y"] == smoke_cfg["gradient_models"]["models"]["q_y"]
    for section in set(smoke_cfg) - {"rod", "gradient_models", "variants"}:
        assert v[section] == smoke_cfg[section], section
    assert cfg["rod"]["nu"] == smoke_cfg["rod"]["nu"]  # the main config is not modified


def test_an_empty_overlay_is_the_main_config(smoke_cfg):
    assert variant_config(smoke_cfg, "paper") == smoke_cfg


@pytest.mark.parametrize(("overlay", "named"), [
    ({"rod": {"nuu": 0.3}}, "rod.nuu"),                      # unknown key
    ({"rod": {"nu": 0.7}}, "rod.nu"),                        # out of the schema's range
    ({"simulation": {"dt_s": 1.0e-2}}, "simulation.dt_s"),   # physical check: unstable step
    ({"gradient_models": {"theta_wrap": "no"}}, "gradient_models.theta_wrap"),
])
def test_an_overlaid_config_is_validated_like_config_yaml(smoke_cfg, overlay, named):
    cfg = _with_variant(smoke_cfg, "bad", overlay)
    with pytest.raises(ConfigError) as err:
        variant_config(cfg, "bad")
    msg = str(err.value)
    assert "variants.definitions.bad.overlay" in msg and named in msg, msg
    assert "\n" not in msg


def test_variant_references_are_checked(smoke_cfg):
    cfg = copy.deepcopy(smoke_cfg)
    cfg["variants"]["sensitivity"] = ["paper", "nope"]
    with pytest.raises(ConfigError, match="variants.sensitivity: 'nope'"):
        variant_configs(cfg)
    cfg = copy.deepcopy(smoke_cfg)
    cfg["variants"]["methods"] = {"cr_gpr_fd": "paper"}  # a method name already taken
    with pytest.raises(ConfigError, match="variants.methods: cr_gpr_fd"):
        variant_configs(cfg)
    cfg = _with_variant(smoke_cfg, "m", {}, method="cr_gpr_nope")
    with pytest.raises(ConfigError, match="variants.definitions.m.method"):
        variant_configs(cfg)
    # a variant keeps its method's prefilter and features (another method is the way to change them)
    cfg = _with_variant(smoke_cfg, "m", {"rollouts": {"methods": {"cr_gpr": {"prefilter": "fd"}}}})
    with pytest.raises(ConfigError, match="rollouts.methods.cr_gpr"):
        variant_configs(cfg)


@pytest.mark.parametrize("keys", [
    ("rod", "simulation"),
    ("seed", "rod", "prefilter.n_t_out"),
    ("rod.L0", "rollouts.table1_method", "rollouts.ablation_methods"),
    ("seed", "rod", "gradient_models.theta_wrap", "gradient_models.models.q_x"),
    ("rollouts.methods.cr_gpr",),
])
def test_dotted_keys_recover_a_rules_params_keys(smoke_cfg, keys):
    """A variant rule reads the main rule's keys from its own config: the keys recovered from
    the main rule's params give the same subset of the main config and pick up the overlay."""
    sub = config_subset(smoke_cfg, *keys)
    got = dotted_keys(sub, smoke_cfg)
    assert config_subset(smoke_cfg, *got) == sub
    changed = variant_config(_with_variant(smoke_cfg, "x", {"rod": {"L0": 0.6, "nu": 0.3}}), "x")
    vsub = config_subset(changed, *got)
    if "rod" in keys:
        assert vsub["rod"]["nu"] == 0.3 and vsub["rod"]["L0"] == 0.6
    elif "rod.L0" in keys:
        assert vsub["rod"] == {"L0": 0.6}
    else:
        assert vsub == sub


def test_sensitivity_table_counts_divergences_and_keeps_missing_angles_missing():
    def acc(variant, rmse, diverged):
        return pd.DataFrame({"variant": variant, "method": "cr_gpr", "theta0_deg": [60.0, 125.0][:len(rmse)],
                             "rmse_theta": rmse, "r2_theta": 0.5, "tip_rmse_over_L": 0.1,
                             "diverged": diverged, "t_diverged": [0.3 if d else math.nan for d in diverged]})
    defs = {"a": {"method": "cr_gpr", "overlay": {}},
            "b": {"method": "cr_gpr", "overlay": {"rod": {"nu": 0.3}}},
            "c": {"method": "cr_gpr", "overlay": {}}}
    tab = sensitivity.table({"a": acc("a", [1.0, 3.0], [False, False]),
                             "b": acc("b", [2.0, 4.0], [False, True]),
                             "c": acc("c", [1.0], [False])}, defs, [60, 125])
    assert list(tab["variant"]) == ["a", "b", "c"]
    assert tab["rmse_theta_mean"].iloc[0] == pytest.approx(2.0)
    assert list(tab["divergences"]) == [0, 1, 0]
    assert tab["diverged_at"].iloc[1] == "125 deg at 0.3 s"
    assert yaml.safe_load(tab["overlay"].iloc[1]) == {"rod": {"nu": 0.3}}
    assert np.isnan(tab["rmse_theta_mean"].iloc[2]) and tab["n_angles"].iloc[2] == 1


def _smoke_variants(tmp_path, definitions: dict, sensitivity_rows: list[str], **sections) -> str:
    """The smoke config with these variants (and ``sections`` merged over its own), as a file."""
    cfg = yaml.safe_load(SMOKE.read_text())
    cfg["variants"] = {"definitions": definitions, "methods": {}, "sensitivity": sensitivity_rows}
    for name, values in sections.items():
        cfg[name].update(values)
    tmp_path.mkdir(parents=True, exist_ok=True)
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return str(path)


def test_a_bad_variant_key_stops_the_workflow_with_one_line(tmp_path):
    cfg = _smoke_variants(tmp_path, {"nu": {"method": "cr_gpr", "overlay": {"rod": {"nuu": 0.3}}}}, ["nu"])
    res = snakemake("-d", str(tmp_path / "w"), "--configfile", cfg, "-n", "all")
    assert res.returncode == 2, res.stdout[-2000:] + res.stderr[-2000:]
    err = [line for line in res.stderr.splitlines() if "error" in line.lower()]
    assert len(err) == 1 and "variants.definitions.nu.overlay" in err[0] and "rod.nuu" in err[0], res.stderr
    assert "Traceback" not in res.stderr


DEFS = {"paper": {"method": "cr_gpr", "overlay": {}},
        "no_wrap": {"method": "cr_gpr", "overlay": {"gradient_models": {"theta_wrap": False}}},
        "nu_0_3": {"method": "cr_gpr", "overlay": {"rod": {"nu": 0.3}}}}


@pytest.fixture(scope="module")
def variant_run(tmp_path_factory):
    """A smoke run of two variants: ``paper`` (reuses everything) and ``no_wrap`` (own models)."""
    repo = tmp_path_factory.mktemp("repo") / "crgpr"
    shutil.copytree(ROOT, repo, ignore=COPY_IGNORE)
    tmp = tmp_path_factory.mktemp("variants")
    cfg = _smoke_variants(tmp, DEFS, ["paper", "no_wrap"])
    work = tmp / "work"
    res = snakemake("-d", str(work), "--configfile", cfg, "-j2", "results/tables/crgpr_sensitivity.csv",
                    snakefile=repo / "Snakefile")
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-4000:]
    return repo, work, tmp


@pytest.mark.slow
def test_a_variant_runs_end_to_end_and_reuses_what_it_does_not_change(variant_run):
    repo, work, _ = variant_run
    res = work / "results"
    # no_wrap changes only the gradient GPs: it refits them on the main ground truth and prefilter
    assert not (res / "variants" / "no_wrap" / "ground_truth").exists()
    assert not (res / "variants" / "no_wrap" / "prefilter").exists()
    for m in ("q_x", "q_y", "dH_dtheta", "dH_dp_x", "dH_dp_y", "dH_dp_theta"):
        meta = yaml.safe_load((res / "variants" / "no_wrap" / "models" / "gp" / f"{m}.json").read_text())
        main = yaml.safe_load((res / "models" / "gp" / f"{m}.json").read_text())
        assert meta["n"] == main["n"]
    # ... and the paper variant is the main run's cr_gpr itself: nothing of its own but its metrics
    assert sorted(p.name for p in (res / "variants" / "paper").iterdir()) == ["metrics"]
    acc = {v: read_parquet(res / "variants" / v / "metrics" / "accuracy.parquet")
           for v in ("paper", "no_wrap")}
    for v, a in acc.items():
        assert list(a["theta0_deg"]) == [60.0, 125.0] and set(a["variant"]) == {v}
        assert np.all(np.isfinite(a["rmse_theta"])) and np.all(a["rmse_theta"] >= 0)
    # the paper variant scores the main run's rollouts against the main ground truth
    assert read_metadata(res / "variants" / "paper" / "metrics" / "accuracy.parquet")["inputs"].keys() == {
        "results/rollouts/cr_gpr/60.parquet", "results/rollouts/cr_gpr/125.parquet"}
    tab = pd.read_csv(res / "tables" / "crgpr_sensitivity.csv")
    assert list(tab["variant"]) == ["paper", "no_wrap"]
    assert tab["rmse_theta_mean"].to_numpy() == pytest.approx(
        [acc["paper"]["rmse_theta"].mean(), acc["no_wrap"]["rmse_theta"].mean()], rel=1e-3)
    assert (res / "figures" / "crgpr_sensitivity.png").read_bytes()[:4] == b"\x89PNG"
    # a variant that changes the rod has its own ground truth and prefilter (dry run)
    cfg = _smoke_variants(work.parent / "nu", DEFS, ["paper", "no_wrap", "nu_0_3"])
    dry = snakemake("-d", str(work), "--configfile", cfg, "-n", "results/tables/crgpr_sensitivity.csv",
                    snakefile=repo / "Snakefile")
    jobs = planned_jobs(dry)
    assert len(jobs["variant_ground_truth"]) == 3 and len(jobs["variant_prefilter"]) == 1
    assert all("results/variants/nu_0_3/" in o for r, outs in jobs.items() if r != "crgpr_sensitivity"
               for o in outs), jobs


@pytest.mark.slow
def test_changing_one_variant_reruns_only_that_variant(variant_run):
    repo, work, tmp = variant_run
    target = "results/tables/crgpr_sensitivity.csv"
    changed = copy.deepcopy(DEFS)
    changed["no_wrap"]["overlay"]["gradient_models"]["n_hyper"] = 60
    cfg = _smoke_variants(tmp / "changed", changed, ["paper", "no_wrap"])
    jobs = _dry(repo, work, cfg, target)
    assert {r: len(o) for r, o in jobs.items()} == {"variant_gradient_model": 6, "variant_rollout": 2,
                                                    "variant_metrics": 1, "crgpr_sensitivity": 1}, jobs
    assert all("variants/no_wrap/" in o for r, outs in jobs.items() if r != "crgpr_sensitivity" for o in outs)
    # a main-config value that a variant inherits reruns the main stage and every variant using it
    cfg = _smoke_variants(tmp / "main", DEFS, ["paper", "no_wrap"], gradient_models={"n_hyper": 120})
    jobs = _dry(repo, work, cfg, target)
    assert len(jobs["gradient_model"]) == 6 and len(jobs["variant_gradient_model"]) == 6, jobs
    # the main rollout: one job for both test angles; a variant's: one job per angle
    assert len(jobs["rollout"]) == 1 and len(jobs["variant_rollout"]) == 2
    assert len(jobs["variant_metrics"]) == 2
    assert not {"ground_truth", "prefilter", "variant_ground_truth", "variant_prefilter"} & set(jobs)


def _dry(repo, work, cfg: str, target: str) -> dict[str, list[str]]:
    res = snakemake("-d", str(work), "--configfile", cfg, "-n", target, snakefile=repo / "Snakefile")
    assert res.returncode == 0, res.stderr[-3000:]
    return planned_jobs(res)
