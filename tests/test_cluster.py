"""Running on a Slurm cluster: the profile, the extra, the resources every rule declares, and the
checks workflow/cluster/test-slurm.sh relies on (the end-to-end Slurm run itself is that script,
run by CI where root and apt-get are available)."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from crgpr.io import write_parquet

ROOT = Path(__file__).resolve().parents[1]


def _load(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


check = _load("check_slurm_run", ROOT / "workflow" / "cluster" / "check_slurm_run.py")
rule_resources = _load("rule_resources", ROOT / "benchmarks" / "rule_resources.py")


def test_slurm_extra_and_profile():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert any(d.startswith("snakemake-executor-plugin-slurm>=") and "<" in d for d in extras["slurm"])
    profile = yaml.safe_load((ROOT / "profiles" / "slurm" / "config.yaml").read_text())
    assert profile["executor"] == "slurm"
    assert set(profile["default-resources"]) >= {"mem_mb", "runtime"}


def test_every_rule_declares_benchmark_threads_mem_and_runtime():
    rules = rule_resources.parse_rules(ROOT / "workflow" / "rules")
    listed = subprocess.run(
        [sys.executable, "-m", "snakemake", "--list-rules", "-s", str(ROOT / "Snakefile")],
        cwd=ROOT, capture_output=True, text=True, check=True,
    ).stdout.split()
    targets = {"all", "sweeps"}  # rules that only collect other rules' outputs (in the Snakefile)
    assert set(listed) - targets == set(rules)
    for r in rules.values():
        if r.name in targets:
            continue
        assert r.benchmark and r.benchmark.startswith("benchmarks/"), r.name
        assert r.mem_mb is not None and 100 <= r.mem_mb <= 16000, r.name
        assert r.runtime is not None and 1 <= r.runtime <= 240, r.name
        assert r.threads >= 1


def test_benchmark_files_map_to_exactly_one_rule():
    rules = rule_resources.parse_rules(ROOT / "workflow" / "rules")
    examples = {
        "benchmarks/ground_truth/125.tsv": "ground_truth",
        "benchmarks/models/gp/dH_dtheta.tsv": "gradient_model",
        "benchmarks/figures/cr_gpr_objective_125.tsv": "figures_crgpr",
        "benchmarks/baselines/pinn_rollout/pinn_data_8.tsv": "pinn_rollout",
        "benchmarks/baselines/blackbox_rollout.tsv": "blackbox_rollout",
        "benchmarks/rollouts/cr_gpr_objective.tsv": "rollout",
        "benchmarks/discovery/run_tip_mass.tsv": "discovery_run",
        "benchmarks/uq/cr_gpr_objective/samples/obj_m.tsv": "uq_samples",
        "benchmarks/uq/cr_gpr/rollout.tsv": "uq_rollout",
        "benchmarks/uq/cr_gpr_objective_camera/learned_rollout.tsv": "uq_rollout_learned",
    }
    for path, rule in examples.items():
        owners = [r.name for r in rules.values() if r.benchmark and r.pattern().match(path)]
        assert owners == [rule], path


SNAKEMAKE_LOG = """\
[Sun Nov 22 16:20:01 2026]
rule ground_truth:
    output: results/ground_truth/60.parquet
    jobid: 7
    benchmark: benchmarks/ground_truth/60.tsv
    wildcards: angle=60
    resources: mem_mb=1000, mem_mib=954, disk_mb=1000, tmpdir=<TBD>, runtime=5

Job 7 has been submitted with SLURM jobid 12 (log: {logdir}/rule_ground_truth/angle_60/12.log).
[Sun Nov 22 16:20:02 2026]
rule table2:
    jobid: 9
    threads: 2
    resources: mem_mb=500, runtime=2

Job 9 has been submitted with SLURM jobid 13 (log: {logdir}/rule_table2/13.log).
[Sun Nov 22 16:20:03 2026]
localrule all:
    jobid: 0
"""

JOBCOMP = (
    "JobId=12 UserId=root(0) GroupId=root(0) Name=x JobState=COMPLETED Partition=test TimeLimit=5 "
    "NodeList=vm NodeCnt=1 ProcCnt=1 Tres=cpu=1,mem=1000M,node=1,billing=1 ExitCode=0:0\n"
    "JobId=13 UserId=root(0) GroupId=root(0) Name=x JobState=COMPLETED Partition=test TimeLimit=2 "
    "NodeList=vm NodeCnt=1 ProcCnt=2 Tres=cpu=2,mem=500M,node=1,billing=2 ExitCode=0:0\n"
)


def _slurm_logs(tmp_path: Path) -> Path:
    logdir = tmp_path / "slurm_logs"
    for rel in ("rule_ground_truth/angle_60/12.log", "rule_table2/13.log"):
        (logdir / rel).parent.mkdir(parents=True, exist_ok=True)
        (logdir / rel).write_text("job ran\n")
    return logdir


def test_job_checks_pass_when_slurm_granted_what_the_rules_ask(tmp_path):
    logdir = _slurm_logs(tmp_path)
    log = SNAKEMAKE_LOG.format(logdir=logdir)
    assert check.check_jobs(log, JOBCOMP, logdir, "vm") == []


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda log, jc: (log, jc.replace("mem=1000M", "mem=2000M")), "got cpus/mem_mb/minutes"),
        (lambda log, jc: (log, jc.replace("TimeLimit=2", "TimeLimit=30")), "got cpus/mem_mb/minutes"),
        (lambda log, jc: (log, jc.replace("JobState=COMPLETED Partition=test TimeLimit=2",
                                          "JobState=FAILED Partition=test TimeLimit=2")), "FAILED"),
        (lambda log, jc: (log.replace("Job 9 has been submitted", "Job 9 was run"), jc), "never submitted"),
        (lambda log, jc: (log, jc.splitlines()[0]), "not in the job-completion log"),
        (lambda log, jc: (log, jc + jc.splitlines()[0].replace("JobId=12", "JobId=99")), "not from this run"),
    ],
)
def test_job_checks_fail_on_any_mismatch(tmp_path, edit, expected):
    logdir = _slurm_logs(tmp_path)
    log, jobcomp = edit(SNAKEMAKE_LOG.format(logdir=logdir), JOBCOMP)
    failures = check.check_jobs(log, jobcomp, logdir, "vm")
    assert any(expected in f for f in failures), failures


def test_tres_memory_units():
    assert check.tres_mem_mb("cpu=1,mem=1000M,node=1") == 1000
    assert check.tres_mem_mb("cpu=1,mem=2G,node=1") == 2048


def _run_tree(root: Path, rollout: np.ndarray, seconds: float, minutes: float, md_runtime: str) -> Path:
    res = root / "results"
    (res / "rollouts").mkdir(parents=True)
    (res / "tables").mkdir()
    df = pd.DataFrame({"t": [0.0, 0.1, 0.2], "theta": rollout})
    write_parquet(df, res / "rollouts" / "60.parquet", {"seconds": seconds, "dt_s": 1e-4})
    (res / "tables" / "model.json").write_text(json.dumps({"sigma_n": 1e-3, "fit_seconds": seconds}))
    pd.DataFrame({"stage": ["stage1"], "minutes": [minutes], "paper_minutes": [3.0]}).to_csv(
        res / "tables" / "timing.csv", index=False)
    (res / "tables" / "report.md").write_text(f"# x\n\nGap 0.15 rad.\nRun time {md_runtime} s.\n")
    np.savez(res / "tables" / "arrays.npz", a=rollout)
    return root


def test_outputs_equal_up_to_timing_fields(tmp_path):
    theta = np.array([1.0, np.nan, 0.5])
    a = _run_tree(tmp_path / "a", theta, 1.0, 0.1, "2.5")
    b = _run_tree(tmp_path / "b", theta.copy(), 7.0, 0.9, "9.6")
    assert check.check_outputs(a, b) == []


def test_outputs_differ_in_the_last_bit(tmp_path):
    theta = np.array([1.0, 0.25, 0.5])
    a = _run_tree(tmp_path / "a", theta, 1.0, 0.1, "2.5")
    b = _run_tree(tmp_path / "b", np.nextafter(theta, 2.0), 1.0, 0.1, "2.5")
    failures = check.check_outputs(a, b)
    assert any("rollouts/60.parquet" in f for f in failures), failures
    assert any("arrays.npz" in f for f in failures), failures


def test_non_timing_metadata_and_text_must_match(tmp_path):
    theta = np.array([1.0, 0.25, 0.5])
    a = _run_tree(tmp_path / "a", theta, 1.0, 0.1, "2.5")
    b = _run_tree(tmp_path / "b", theta, 1.0, 0.1, "2.5")
    frame = pd.DataFrame({"t": [0.0, 0.1, 0.2], "theta": theta})
    write_parquet(frame, b / "results" / "rollouts" / "60.parquet", {"seconds": 1.0, "dt_s": 2e-4})
    (b / "results" / "tables" / "report.md").write_text("# x\n\nGap 0.16 rad.\nRun time 2.5 s.\n")
    (b / "results" / "tables" / "extra.png").write_bytes(b"png")
    failures = check.check_outputs(a, b)
    assert any("metadata differs" in f and "dt_s" in f for f in failures), failures
    assert any("report.md: line 3" in f for f in failures), failures
    assert any("only in the Slurm run" in f for f in failures), failures


def test_code_version_is_compared_unless_ignored(monkeypatch):
    a = {"code_version": "0.1.0+ga382ee9", "inputs": {"x.parquet": "0.1.0+ga382ee9"}, "seconds": 1.0}
    b = {"code_version": "0.1.0+ged3b20f", "inputs": {"x.parquet": "0.1.0+ged3b20f"}, "seconds": 2.0}
    differing = check.diff_keys(check.drop_timing(a), check.drop_timing(b))
    assert differing == [".code_version", ".inputs.x.parquet"]
    monkeypatch.setattr(check, "IGNORE_CODE_VERSION", True)
    assert check.diff_keys(check.drop_timing(a), check.drop_timing(b)) == []


def _ci_targets() -> list[str]:
    lines = (ROOT / "workflow" / "cluster" / "ci_targets.txt").read_text().splitlines()
    return [t for line in lines if (t := line.split("#", 1)[0].strip())]


def _dry_run_jobs(tmp_path: Path, *targets: str) -> dict[str, int]:
    """Jobs per rule that `snakemake -n TARGETS` plans on the smoke config in an empty directory."""
    res = subprocess.run(
        [sys.executable, "-m", "snakemake", "-n", "--quiet", "rules", "-s", str(ROOT / "Snakefile"),
         "--configfile", str(ROOT / "tests" / "smoke_config.yaml"), "-d", str(tmp_path), *targets],
        cwd=ROOT, capture_output=True, text=True,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    jobs = {}
    for line in res.stdout.splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[1].isdigit() and parts[0] not in ("job", "total"):
            jobs[parts[0]] = int(parts[1])
    return jobs


def test_ci_targets_are_a_pinn_free_sub_dag_of_all_through_every_stage(tmp_path):
    """The CI Slurm run (.ci/run: CRGPR_SLURM_TARGETS=@workflow/cluster/ci_targets.txt) plans a
    job of every stage kind it stands for, no PINN (torch) job, and only jobs `all` has too."""
    ci = _dry_run_jobs(tmp_path / "ci", *_ci_targets())
    everything = _dry_run_jobs(tmp_path / "all", "all")
    stages = {"ground_truth", "prefilter", "gradient_model", "rollout", "variant_metrics",
              "figures_crgpr", "discovery_data", "discovery_run"}
    assert stages <= set(ci), ci
    assert not any(rule.startswith("pinn") for rule in ci), ci
    assert all(ci[r] <= everything.get(r, 0) for r in ci if r != "variant_metrics"), (ci, everything)
    assert sum(ci.values()) < sum(everything.values()) / 3


def test_slurm_script_skips_with_one_line_where_it_cannot_run(tmp_path):
    """Not root: exit 77 with one SKIPPED line, before it installs or starts anything.

    As root the script runs as user nobody, who may not be able to read the checkout (a clone
    in a private directory): the script is read here and fed to bash on stdin, run from ``/``,
    so the test does not depend on where the checkout lives."""
    script = (ROOT / "workflow" / "cluster" / "test-slurm.sh").read_text()
    cmd = ["bash", "-s"]
    if os.geteuid() == 0:
        if shutil.which("setpriv") is None:
            pytest.skip("root without setpriv: cannot drop to another user")
        cmd = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", *cmd]
    env = {**os.environ, "CRGPR_SLURM_SCRATCH": str(tmp_path)}
    res = subprocess.run(cmd, input=script, cwd="/", env=env, capture_output=True, text=True,
                         timeout=60)
    assert res.returncode == 77, res.stdout + res.stderr
    skipped = [line for line in res.stdout.splitlines() if "SKIPPED" in line]
    assert skipped == ["test-slurm: SKIPPED: needs root (apt-get, munged, slurmd)"], res.stdout
    assert list(tmp_path.iterdir()) == []  # no scratch directory made


def test_benchmark_file_matching_two_patterns_goes_to_the_more_specific_rule():
    generic = rule_resources.Rule("rollout", "", benchmark="benchmarks/rollouts/{method}.tsv")
    camera = rule_resources.Rule("camera_rollout", "",
                                 benchmark="benchmarks/rollouts/cr_gpr_objective_camera.tsv")
    path = "benchmarks/rollouts/cr_gpr_objective_camera.tsv"
    matching = [r for r in (generic, camera) if r.pattern().match(path)]
    assert {r.name for r in matching} == {"rollout", "camera_rollout"}
    assert [r.name for r in rule_resources.most_specific(matching)] == ["camera_rollout"]
    # the workflow's own rules: both patterns match that file, and it goes to camera_rollout
    rules = rule_resources.parse_rules(ROOT / "workflow" / "rules")
    owners = [r for r in rules.values() if r.benchmark and r.pattern().match(path)]
    assert {r.name for r in owners} == {"rollout", "camera_rollout"}
    assert [r.name for r in rule_resources.most_specific(owners)] == ["camera_rollout"]


@pytest.mark.parametrize(
    ("name", "timing"),
    [("seconds", True), ("seconds_exact_weights", True), ("posterior_scale_seconds", True),
     ("fit_seconds", True), ("minutes", True), ("wall_s", True), ("timing_s", True),
     ("dt_s", False), ("t_end_s", False), ("window_s", False), ("seconds2", False), ("sigma_n", False)],
)
def test_timing_fields_are_named_by_convention(name, timing):
    """Wall-clock fields (not compared between the local and the Slurm run) are recognised by
    name, so a new ``seconds_*`` / ``*_seconds`` key needs no checker change, while a physical
    time such as ``dt_s`` is compared."""
    assert check.is_timing(name) is timing
