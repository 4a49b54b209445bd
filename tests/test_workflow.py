"""The Snakemake workflow: lint, the whole DAG on the smoke config, and what reruns after a
config change or a code edit (exactly the affected rules and their dependants)."""

from __future__ import annotations

import ast
import os
import re
import shutil
import subprocess
import sys
from modulefinder import ModuleFinder
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from crgpr.io import read_metadata, read_parquet
from crgpr.physics.simulate import TRAJECTORY_COLUMNS

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "tests" / "smoke_config.yaml"


COPY_IGNORE = shutil.ignore_patterns("results", ".snakemake", ".git", "logs", "__pycache__", ".venv",
                                     "*.egg-info", ".hypothesis", ".pytest_cache", ".ruff_cache", "*.tsv")


def snakemake(*args: str, cwd: Path = ROOT,
              snakefile: Path = ROOT / "Snakefile") -> subprocess.CompletedProcess:
    """Run Snakemake on ``snakefile``; its scripts import crgpr from the same checkout."""
    cmd = [sys.executable, "-m", "snakemake", "-s", str(snakefile), *args]
    env = {**os.environ, "PYTHONPATH": str(snakefile.parent / "src")}
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=1800, env=env)


def planned_jobs(res: subprocess.CompletedProcess) -> dict[str, list[str]]:
    """Rule -> output lines of every job a dry run plans."""
    jobs: dict[str, list[str]] = {}
    rule = None
    for line in (res.stdout + res.stderr).splitlines():
        m = re.match(r"^(?:local)?rule (\w+):$", line.strip())
        if m:
            rule = m.group(1)
            jobs.setdefault(rule, [])
        elif rule and line.strip().startswith("output:"):
            jobs[rule].append(line.strip().removeprefix("output:").strip())
    jobs.pop("all", None)
    return jobs


def test_lint_is_clean():
    res = snakemake("--lint")
    assert res.returncode == 0, res.stdout + res.stderr


def test_a_config_key_given_twice_stops_the_workflow(tmp_path):
    """Snakemake's own loader would keep the second of two equal keys without a word."""
    cfg = tmp_path / "c.yaml"
    text = SMOKE.read_text()
    cfg.write_text(text + "seed: 3\n")
    res = snakemake("-d", str(tmp_path), "--configfile", str(cfg), "-n", "all")
    assert res.returncode != 0
    assert f"'seed' at line {len(text.splitlines()) + 1} is already given" in res.stdout + res.stderr


@pytest.fixture(scope="module")
def smoke_repo(tmp_path_factory):
    """A copy of the checkout (its code can be edited) and a complete smoke run of its DAG."""
    repo = tmp_path_factory.mktemp("repo") / "crgpr"
    shutil.copytree(ROOT, repo, ignore=COPY_IGNORE)
    work = tmp_path_factory.mktemp("smoke")
    # `sweeps`: the camera noise ablation (not in `all`, workflow/rules/camera.smk)
    res = snakemake("-d", str(work), "--configfile", str(SMOKE), "-j2", "all", "sweeps",
                    snakefile=repo / "Snakefile")
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-4000:]
    return repo, work


@pytest.fixture(scope="module")
def smoke_run(smoke_repo):
    return smoke_repo[1]


@pytest.mark.slow
def test_smoke_dag_runs_end_to_end(smoke_repo, smoke_run):
    gt = smoke_run / "results" / "ground_truth"
    for angle in (85, 60, 125, 30):
        df = read_parquet(gt / f"{angle}.parquet", TRAJECTORY_COLUMNS)
        assert set(df["theta0_deg"]) == {float(angle)}
        assert df["node"].max() == 10  # smoke config: N = 10
        assert np.all(np.isfinite(df[list(TRAJECTORY_COLUMNS)].to_numpy()))
        assert read_metadata(gt / f"{angle}.parquet")["rod"]["N"] == 10
        e = read_parquet(gt / f"{angle}_energy.parquet", ["t", "H", "dissipation_rate"])
        assert np.all(e["dissipation_rate"] >= 0)
    # the final products of every stage exist with their schema
    res = smoke_run / "results"
    cols = ["method", "theta0_deg", "rmse_theta", "r2_theta", "tip_rmse_over_L", "group_nrmse", "diverged",
            "t_diverged"]
    acc = read_parquet(res / "metrics" / "accuracy.parquet", cols)
    assert {"cr_gpr", "cr_gpr_fd", "cr_gpr_objective", "blackbox_gp", "pinn_physics", "pinn_data_1",
            "pinn_data_8", "cr_gpr_objective_camera"} == set(acc["method"])
    assert set(acc["theta0_deg"]) == {60.0, 125.0}
    assert np.all(acc["rmse_theta"] >= 0)
    # the studies of `sweeps`: same columns, their own file
    studies = read_parquet(res / "metrics" / "accuracy_studies.parquet", cols)
    assert set(studies["method"]) == {"cr_gpr_paper_hyp", "cr_gpr_collocated"}
    assert set(studies["theta0_deg"]) == {60.0, 125.0}
    tables = res / "tables"
    cov = pd.read_csv(tables / "uq_coverage.csv")
    assert set(cov["method"]) == {"cr_gpr", "cr_gpr_objective", "cr_gpr_objective_camera"}
    assert (res / "figures" / "uq_band_cr_gpr_objective_camera_125.png").exists()
    for name, cols in {
        "table1_accuracy.csv": [], "table2_hyperparameters.csv": ["model", "sigma_f", "sigma_n", "n"],
        "table4_ablation.csv": [], "baselines.csv": [],
        "uq_coverage.csv": ["method", "theta0_deg", "level", "theta_coverage", "expected_coverage"],
        "discovery.csv": ["case", "hidden", "named", "verdict"], "discovery_sweeps.csv": ["case", "verdict"],
        "uq_function_calibration.csv": [], "paper_claims.csv": ["id", "verdict"],
        "noise_ablation.csv": ["noise_mm", "prefilter", "features", "rmse_theta_mean", "divergences"],
        "crgpr_sensitivity.csv": ["variant", "method", "overlay", "rmse_theta_mean", "divergences"],
        "oracle_ablation.csv": ["variant", "theta0_deg", "rmse_theta"],
        "actuated_accuracy.csv": ["method", "train_signal", "test_signal", "theta0_deg", "rmse_theta",
                                  "tip_rmse_over_L", "energy_balance_residual"],
        "actuated_uq.csv": ["method", "test_signal", "n_samples", "n_diverged", "level", "expected_coverage",
                            "tip_coverage", "tip_band_width_mean_over_L"],
        "paper_vs_reproduction.csv": ["id", "source", "paper", "ours", "abs_diff", "rel_diff", "tolerance",
                                      "verdict"],
    }.items():
        df = pd.read_csv(tables / name)
        assert len(df) > 0, name
        assert set(cols) <= set(df.columns), (name, list(df.columns))
    assert (tables / "paper_vs_reproduction.md").read_text().startswith("# Paper vs reproduction")
    # discovery: `all` tabulates the cases not in discovery.sweep_cases, `sweeps` every case
    assert set(pd.read_csv(tables / "discovery.csv")["case"]) == {"tip_mass"}
    assert set(pd.read_csv(tables / "discovery_sweeps.csv")["case"]) == {"tip_mass", "none"}
    act = pd.read_csv(tables / "actuated_accuracy.csv")
    assert set(act["method"]) == {"cr_gpr_objective", "cr_gpr_objective_camera", "cr_gpr", "nominal_prior",
                                  "blackbox_gp"}
    band = pd.read_csv(tables / "actuated_uq.csv")
    assert set(band["method"]) == {"cr_gpr_objective", "cr_gpr_objective_camera"}
    done = band[band["n_diverged"] < band["n_samples"] - 1]
    assert done["tip_coverage"].between(0, 1).all() and (done["tip_band_width_mean_over_L"] > 0).all()
    pngs = list((res / "figures").glob("*.png"))
    assert len(pngs) >= 5
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)
    # every rule left a benchmark file and a log
    assert (smoke_run / "benchmarks" / "ground_truth" / "85.tsv").exists()
    assert (smoke_run / "logs" / "ground_truth" / "85.log").exists()
    # nothing left to do after a complete run
    repo = smoke_repo[0]
    res = snakemake("-d", str(smoke_run), "--configfile", str(SMOKE), "-n", "all", "sweeps",
                    snakefile=repo / "Snakefile")
    assert res.returncode == 0
    assert "Nothing to be done" in res.stdout + res.stderr


def _smoke_with(tmp_path: Path, old: str, new: str) -> Path:
    text = SMOKE.read_text()
    assert text.count(old) == 1, old
    path = tmp_path / "config.yaml"
    path.write_text(text.replace(old, new))
    return path


N_GP_MODELS = 9  # the smoke config's gp-prefilter models: 6 paper + 3 objective
N_FD_MODELS = 6  # cr_gpr_fd: the paper's six
DISCOVERY = {"discovery_data", "discovery_run", "discovery_summary"}
UPSTREAM = {"ground_truth", "pinn_train", "pinn_rollout", *DISCOVERY}


@pytest.mark.slow
@pytest.mark.parametrize(
    ("old", "new", "reruns", "untouched"),
    [
        # a gradient-model setting: every gradient GP and what uses them, nothing upstream
        # (the paper-hyperparameter models search nothing: they and their rollouts stay)
        ("  n_hyper: 100\n  n_restarts: 1\n  hyper_bounds",
         "  n_hyper: 120\n  n_restarts: 1\n  hyper_bounds",
         {"gradient_model": N_GP_MODELS + N_FD_MODELS, "gradient_model_paper_hyp": 0,
          "rollout": 3,  # one job per method (all test angles in one batch)
          "table2": 1, "metrics": 1, "baselines_table": 1, "paper_tables": 1,
          "uq_samples": 12,  # one job per GP of each uq.methods entry: 2 methods x 6 GPs
          "paper_hyp_lml": 0},  # rollouts.study_methods (cr_gpr_paper_hyp) are not in `all`
         UPSTREAM | {"prefilter", "blackbox_train", "blackbox_rollout"}),
        # a setting of the GP prefilter: the gp branch only, not the finite-difference ablation
        ("hyper_points: 41", "hyper_points: 30",
         {"prefilter": 1, "gradient_model": N_GP_MODELS, "gradient_model_paper_hyp": 0,
          "blackbox_train": 1, "blackbox_rollout": 1, "rollout": 2, "metrics": 1},
         UPSTREAM),
        # the simulated time: every ground truth and everything downstream, not the discovery cases
        ("\n  dt_s: 1.0e-4\n  t_end_s: 0.2", "\n  dt_s: 1.0e-4\n  t_end_s: 0.25",
         {"ground_truth": 4, "pinn_train": 3, "pinn_rollout": 3, "prefilter": 2,
          "gradient_model": N_GP_MODELS + N_FD_MODELS, "gradient_model_paper_hyp": 0,
          "blackbox_train": 1, "rollout": 3, "metrics": 1},
         DISCOVERY),
    ],
    ids=["gradient_models.n_hyper", "prefilter.hyper_points", "simulation.t_end_s"],
)
def test_a_config_change_reruns_what_depends_on_it_and_nothing_else(smoke_repo, tmp_path, old, new,
                                                                     reruns, untouched):
    repo, work = smoke_repo
    cfg = _smoke_with(tmp_path, old, new)
    res = snakemake("-d", str(work), "--configfile", str(cfg), "-n", "all", snakefile=repo / "Snakefile")
    assert res.returncode == 0, res.stderr[-3000:]
    jobs = planned_jobs(res)
    for rule, n in reruns.items():
        assert len(jobs.get(rule, [])) == n, (rule, jobs.get(rule))
    assert not untouched & set(jobs), sorted(untouched & set(jobs))
    if "hyper_points" in old:  # the fd branch is untouched
        assert not [o for outs in jobs.values() for o in outs if "/fd/" in o or "cr_gpr_fd" in o]


def _imports_module(script: Path, src: Path, module: str) -> bool:
    """Whether ``script`` imports ``module``, directly or not (modulefinder, independent of deps.py)."""
    finder = ModuleFinder(path=[str(src)])
    finder.run_script(str(script))
    return module in finder.modules


def _rule_scripts(repo: Path) -> dict[str, str]:
    """Rule name -> the script it runs, from the rule files."""
    out = {}
    for smk in (repo / "workflow" / "rules").glob("*.smk"):
        for m in re.finditer(r"^rule (\w+):\n(?:(?!^rule ).*\n)*?\s+\"\.\./scripts/(\w+)\.py\"",
                             smk.read_text(), re.M):
            out[m.group(1)] = m.group(2)
    return out


@pytest.mark.slow
def test_editing_a_module_reruns_every_rule_that_imports_it(smoke_repo):
    """Edit learning/features.py: every rule whose script imports it, however indirectly
    (blackbox_train and blackbox_rollout included), reruns; rules that do not import it and
    have no input downstream of one that does, do not."""
    repo, work = smoke_repo
    src = repo / "src"
    module = src / "crgpr" / "learning" / "features.py"
    scripts = _rule_scripts(repo)
    importers = {rule for rule, script in scripts.items() if _imports_module(
        repo / "workflow" / "scripts" / f"{script}.py", src, "crgpr.learning.features")}
    assert {"gradient_model", "rollout", "blackbox_train", "blackbox_rollout"} <= importers
    independent = {"ground_truth", "prefilter", "pinn_train", "pinn_rollout", "discovery_data"}
    assert not independent & importers
    text, stat = module.read_text(), module.stat()
    try:
        module.write_text(text + "\n# an edit\n")
        res = snakemake("-d", str(work), "--configfile", str(SMOKE), "-n", "all", "sweeps",
                        snakefile=repo / "Snakefile")
    finally:
        module.write_text(text)
        os.utime(module, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert res.returncode == 0, res.stderr[-3000:]
    jobs = planned_jobs(res)
    assert importers <= set(jobs), sorted(importers - set(jobs))
    assert not independent & set(jobs), sorted(independent & set(jobs))


def test_rule_script_and_function_names_line_up():
    """Rule X runs workflow/scripts/X.py; a script that calls crgpr.commands calls its function X."""
    scripts = _rule_scripts(ROOT)
    assert scripts and all(rule == script for rule, script in scripts.items()), scripts
    assert {p.stem for p in (ROOT / "workflow" / "scripts").glob("*.py")} == set(scripts)
    for rule in scripts:
        tree = ast.parse((ROOT / "workflow" / "scripts" / f"{rule}.py").read_text())
        called = [a.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
                  and (node.module or "").startswith("crgpr.commands.")
                  and node.module != "crgpr.commands.smk" for a in node.names]
        if called:
            assert called == [rule], (rule, called)


# Scripts not yet converted to params (their stages' owners convert them; then drop them here).
PARAMS_PENDING: tuple[str, ...] = ()


def test_scripts_read_params_not_the_whole_config():
    for script in (ROOT / "workflow" / "scripts").glob("*.py"):
        if script.stem.startswith(PARAMS_PENDING):
            continue
        assert "snakemake.config" not in script.read_text(), script.name


@pytest.mark.slow
def test_editing_the_simulator_reruns_ground_truth(tmp_path):
    """Snakemake sees library edits: editing rod.py schedules the ground-truth jobs again.

    (Snakemake 9 ignores a bare ``touch``: it compares checksums of newer inputs.)"""
    repo = tmp_path / "repo"
    shutil.copytree(ROOT, repo, ignore=COPY_IGNORE)
    work = tmp_path / "work"
    snakefile = repo / "Snakefile"
    target = "results/ground_truth/85.parquet"
    res = snakemake("-d", str(work), "--configfile", str(SMOKE), "-j1", target, snakefile=snakefile)
    assert res.returncode == 0, res.stderr[-3000:]
    res = snakemake("-d", str(work), "--configfile", str(SMOKE), "-n", target, snakefile=snakefile)
    assert "Nothing to be done" in res.stdout + res.stderr
    rod = repo / "src" / "crgpr" / "physics" / "rod.py"
    rod.write_text(rod.read_text() + "\n# an edit\n")
    res = snakemake("-d", str(work), "--configfile", str(SMOKE), "-n", target, snakefile=snakefile)
    out = res.stdout + res.stderr
    assert res.returncode == 0
    assert "ground_truth" in out and "Nothing to be done" not in out


def test_bad_config_fails_before_any_job(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(SMOKE.read_text().replace("L0: 0.5", "L0: -0.5"))
    res = snakemake("-d", str(tmp_path / "w"), "--configfile", str(bad), "-n", "all")
    assert res.returncode != 0
    assert "L0" in res.stdout + res.stderr
