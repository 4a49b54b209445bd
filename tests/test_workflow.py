"""The Snakemake workflow: lint, the whole DAG on the smoke config, and code-change reruns."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from crgpr.io import read_metadata, read_parquet
from crgpr.physics.simulate import TRAJECTORY_COLUMNS

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "tests" / "smoke_config.yaml"


def snakemake(*args: str, cwd: Path = ROOT,
              snakefile: Path = ROOT / "Snakefile") -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "snakemake", "-s", str(snakefile), *args]
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=1200)


def test_lint_is_clean():
    res = snakemake("--lint")
    assert res.returncode == 0, res.stdout + res.stderr


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    work = tmp_path_factory.mktemp("smoke")
    res = snakemake("-d", str(work), "--configfile", str(SMOKE), "-j2", "all")
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-4000:]
    return work


@pytest.mark.slow
def test_smoke_dag_runs_end_to_end(smoke_run):
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
    acc = read_parquet(res / "metrics" / "accuracy.parquet",
                       ["method", "theta0_deg", "rmse_theta", "r2_theta", "tip_rmse_over_L", "group_nrmse"])
    assert {"cr_gpr", "cr_gpr_fd", "cr_gpr_objective", "blackbox_gp", "pinn_physics", "pinn_data_1",
            "pinn_data_8"} <= set(acc["method"])
    assert set(acc["theta0_deg"]) == {60.0, 125.0}
    assert np.all(acc["rmse_theta"] >= 0)
    tables = res / "tables"
    for name, cols in {
        "table1_accuracy.csv": [], "table2_hyperparameters.csv": ["model", "sigma_f", "sigma_n", "n"],
        "table4_ablation.csv": [], "baselines.csv": [],
        "uq_coverage.csv": ["method", "theta0_deg", "level", "theta_coverage", "expected_coverage"],
        "discovery.csv": [], "paper_claims.csv": ["id", "verdict"],
        "paper_vs_reproduction.csv": ["id", "source", "paper", "ours", "abs_diff", "rel_diff", "tolerance",
                                      "verdict"],
    }.items():
        df = pd.read_csv(tables / name)
        assert len(df) > 0, name
        assert set(cols) <= set(df.columns), (name, list(df.columns))
    assert (tables / "paper_vs_reproduction.md").read_text().startswith("# Paper vs reproduction")
    pngs = list((res / "figures").glob("*.png"))
    assert len(pngs) >= 5
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)
    # every rule left a benchmark file and a log
    assert (smoke_run / "benchmarks" / "ground_truth" / "85.tsv").exists()
    assert (smoke_run / "logs" / "ground_truth" / "85.log").exists()
    # nothing left to do after a complete run
    res = snakemake("-d", str(smoke_run), "--configfile", str(SMOKE), "-n", "all")
    assert res.returncode == 0
    assert "Nothing to be done" in res.stdout + res.stderr


@pytest.mark.slow
def test_editing_the_simulator_reruns_ground_truth(tmp_path):
    """Snakemake sees library edits: editing rod.py schedules the ground-truth jobs again.

    (Snakemake 9 ignores a bare ``touch``: it compares checksums of newer inputs.)"""
    repo = tmp_path / "repo"
    shutil.copytree(ROOT, repo, ignore=shutil.ignore_patterns(
        "results", ".snakemake", ".git", "logs", "benchmarks", "__pycache__", ".venv", "*.egg-info"))
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
