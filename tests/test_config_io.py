"""Configuration validation, CLI and file I/O: bad input fails clearly (one line, exit 2)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from paper_rod import paper_rod, paper_sim

from crgpr.cli import main
from crgpr.config import ConfigError, check_config_files, load_config, rod_params, sim_settings
from crgpr.io import (
    OutputLocked,
    atomic_dir,
    load_npz,
    read_metadata,
    read_parquet,
    write_json,
    write_npz,
    write_parquet,
)
from crgpr.physics.params import RodParams
from crgpr.physics.simulate import TRAJECTORY_COLUMNS

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config.yaml"


def test_default_config_is_the_paper():
    cfg = load_config(CONFIG)
    p = rod_params(cfg)
    assert (p.L0, p.N, p.r, p.E, p.rho, p.zeta, p.g) == (0.5, 25, 0.01, 3.0e6, 1000.0, 1.0e-3, 9.81)
    assert p.ds == pytest.approx(0.02)
    assert p.A == pytest.approx(np.pi * 0.01**2 / 4)
    assert p.I == pytest.approx(p.A**2 / (4 * np.pi))
    s = sim_settings(cfg)
    assert (s.dt, s.t_end, s.n_records) == (1.0e-4, 2.0, 4001)
    ang = cfg["angles"]
    assert ang["train_deg"] == 85 and ang["test_deg"] == [60, 125, 160, 180, 225, 325]
    pinn = ang["pinn_train_deg"]
    assert len(pinn) == 8 and 85 in pinn and min(pinn) == 30 and max(pinn) == 330
    assert not set(pinn) & set(ang["test_deg"])


@pytest.mark.parametrize(
    ("override", "key"),
    [
        ({"rod": {"L0": -0.5}}, "rod.L0"),
        ({"rod": {"stiffness": 1.0}}, "rod.stiffness"),
        ({"simulation": {"dt_s": 1.0e-3}}, "simulation.dt_s"),
        ({"angles": {"train_deg": "eighty-five"}}, "angles.train_deg"),
        ({"angles": {"train_deg": 80.0, "pinn_train_deg": [30, 80.0]}}, "angles.train_deg"),
        ({"uq": {"n_samples": 16.0}}, "uq.n_samples"),
        ({"angles": {"test_deg": [60, 85]}}, "angles.test_deg"),
        ({"simulation": {"record_every": 0}}, "simulation.record_every"),
        ({"typo_section": {}}, "typo_section"),
        ({"rod": {"E": float("nan")}}, "rod.E"),
        ({"rod": {"zeta": float("inf")}}, "rod.zeta"),
        ({"prefilter": {"noise_var_min": float("nan")}}, "prefilter.noise_var_min"),
        ({"simulation": {"t_end_s": 0.01, "dt_s": 3.0e-5}}, "simulation.t_end_s / simulation.dt_s"),
        ({"discovery": {"sweep_cases": ["no_such_case"]}}, "discovery.sweep_cases"),
        ({"discovery": {"sweep_cases": ["tip_mass", "tip_mass"]}}, "discovery.sweep_cases"),
    ],
)
def test_bad_config_names_the_key(override, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load_config(CONFIG, override)


def test_discovery_sweep_cases_must_leave_a_case_for_all():
    names = [c["name"] for c in load_config(CONFIG)["discovery"]["cases"]]
    with pytest.raises(ConfigError, match=r"discovery\.sweep_cases leaves no case for `all`"):
        load_config(CONFIG, {"discovery": {"sweep_cases": names}})


def test_missing_config_file(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "nope.yaml")


def test_cli_simulate_writes_parquet_with_metadata(tmp_path):
    out = tmp_path / "run.parquet"
    en = tmp_path / "energy.parquet"
    rc = main(["simulate", "--theta0", "85", "--out", str(out), "--energy-out", str(en),
               "--t-end", "0.05", "--set", "E=2e6", "--config", str(CONFIG)])
    assert rc == 0
    df = read_parquet(out, TRAJECTORY_COLUMNS)
    assert list(df.columns) == list(TRAJECTORY_COLUMNS)
    assert len(df) == 101 * 26
    assert set(df["theta0_deg"]) == {85.0}
    meta = read_metadata(out)
    assert meta["rod"]["E"] == 2.0e6 and meta["simulation"]["t_end"] == 0.05
    assert "code_version" in meta
    e = read_parquet(en, ["t", "H", "dissipation_rate"])
    assert len(e) == 101 and np.all(np.isfinite(e["H"]))


def test_a_key_given_twice_is_an_error_naming_both_lines(tmp_path, capsys):
    """YAML keeps the last of two equal keys without a word; an edit to the first would be lost."""
    cfg = tmp_path / "c.yaml"
    text = (ROOT / "config.yaml").read_text()
    cfg.write_text(text + "seed: 3\n")
    first = 1 + text.splitlines().index(next(ln for ln in text.splitlines() if ln.startswith("seed:")))
    with pytest.raises(ConfigError, match=rf"{cfg}: .*'seed' at line {len(text.splitlines()) + 1} "
                                          rf"is already given at line {first}"):
        load_config(cfg)
    out = tmp_path / "x.parquet"
    rc = main(["simulate", "--config", str(cfg), "--theta0", "85", "--out", str(out)])
    assert rc == 2 and "given at line" in capsys.readouterr().err and not out.exists()
    # the shipped files are clean
    check_config_files([ROOT / "config.yaml", ROOT / "tests" / "smoke_config.yaml"])


def test_cli_rejects_unknown_parameter(tmp_path, capsys):
    rc = main(["simulate", "--theta0", "85", "--out", str(tmp_path / "x.parquet"), "--set", "Q=1"])
    assert rc == 2
    assert "unknown rod parameter" in capsys.readouterr().err
    assert not (tmp_path / "x.parquet").exists()


def test_cli_unstable_dt_writes_nothing(tmp_path, capsys):
    out = tmp_path / "x.parquet"
    rc = main(["simulate", "--theta0", "85", "--out", str(out), "--dt", "1e-3", "--t-end", "0.01"])
    assert rc == 2 and "too large" in capsys.readouterr().err
    assert not out.exists() and not list(tmp_path.iterdir())


def test_failed_write_leaves_no_file(tmp_path):
    target = tmp_path / "out.parquet"
    bad = pd.DataFrame({"a": [object()]})
    with pytest.raises(Exception):  # noqa: B017 - any pyarrow error
        write_parquet(bad, target)
    assert not target.exists() and not list(tmp_path.iterdir())


def test_npz_refuses_object_arrays(tmp_path):
    with pytest.raises(TypeError, match="pickle"):
        write_npz(tmp_path / "m.npz", x=np.array([{"a": 1}], dtype=object))
    write_npz(tmp_path / "m.npz", x=np.arange(3.0))
    assert np.array_equal(load_npz(tmp_path / "m.npz")["x"], np.arange(3.0))


def test_params_roundtrip():
    p = paper_rod(E=2.0e6, base_spring=3.0)
    assert RodParams.from_dict(p.to_dict()) == p
    assert RodParams.from_dict(paper_rod().to_dict()).clamped
    with pytest.raises(KeyError, match="unknown rod parameter"):
        RodParams.from_dict({"L": 1.0})
    assert paper_sim().n_steps == 20000


def test_nan_in_the_config_file_is_rejected(tmp_path):
    bad = tmp_path / "c.yaml"
    bad.write_text(CONFIG.read_text().replace("E: 3.0e+6 ", "E: .nan "))
    with pytest.raises(ConfigError, match=r"rod\.E: nan is not a finite number"):
        load_config(bad)


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--set", "L0=-1"], "rod.L0"),
        (["--set", "N=1"], "rod.N"),
        (["--set", "N=0"], "rod.N"),
        (["--set", "N=2.5"], "rod.N"),
        (["--set", "r=-0.01"], "rod.r"),
        (["--set", "E=nan"], "rod.E"),
        (["--set", "tip_mass=-1"], "rod.tip_mass"),
        (["--t-end", "0"], "simulation.t_end_s"),
        (["--dt", "0"], "simulation.dt_s"),
        (["--record-every", "0"], "simulation.record_every"),
        (["--dt", "3e-5", "--t-end", "0.01"], "simulation.t_end_s / simulation.dt_s"),
        (["--theta0", "nan"], "--theta0"),
    ],
)
@pytest.mark.parametrize("with_config", [True, False])
def test_cli_values_are_validated_like_the_config(tmp_path, capsys, monkeypatch, args, named, with_config):
    """Every command-line value goes through the config's schema and checks: one line naming
    the key, exit code 2, nothing written (with and without a config file)."""
    monkeypatch.chdir(tmp_path)  # no ./config.yaml: the paper's defaults
    out = tmp_path / "x.parquet"
    argv = ["simulate", "--theta0", "85", "--out", str(out), *args]
    argv += ["--config", str(CONFIG)] if with_config else []
    if "--theta0" in args:
        argv = argv[:1] + argv[3:]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert named in err and "Traceback" not in err
    assert err.count("\n") == 1 and err.startswith("crgpr simulate: error: ")
    assert not out.exists()


def test_cli_without_config_runs_the_papers_rod(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "r.parquet"
    assert main(["simulate", "--theta0", "60", "--out", str(out), "--t-end", "0.01", "--dt", "1e-4",
                 "--set", "base_spring=inf", "--set", "tip_mass=0.001"]) == 0
    meta = read_metadata(out)
    assert meta["rod"]["N"] == 25 and meta["rod"]["tip_mass"] == 0.001
    assert meta["simulation"]["t_end"] == 0.01


def test_output_files_get_the_usual_permissions(tmp_path):
    expected = 0o666 & ~_umask()
    write_parquet(pd.DataFrame({"a": [1.0]}), tmp_path / "a.parquet")
    write_json({"a": 1}, tmp_path / "a.json")
    write_npz(tmp_path / "a.npz", a=np.zeros(2))
    for f in tmp_path.iterdir():
        assert f.stat().st_mode & 0o777 == expected, f


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_atomic_dir_replaces_on_success_only_and_is_locked(tmp_path):
    out = tmp_path / "models"
    with atomic_dir(out) as d:
        (d / "a.txt").write_text("one")
        assert not out.exists()  # nothing visible before success
    assert (out / "a.txt").read_text() == "one"
    assert out.stat().st_mode & 0o777 == 0o777 & ~_umask()
    with pytest.raises(RuntimeError, match="boom"), atomic_dir(out) as d:
        (d / "a.txt").write_text("two")
        raise RuntimeError("boom")
    assert (out / "a.txt").read_text() == "one"  # the old result survives a failed run
    with atomic_dir(out) as d:
        (d / "b.txt").write_text("three")
        with pytest.raises(OutputLocked, match="another run"), atomic_dir(out):
            pass  # a second writer of the same directory fails at once
    assert sorted(p.name for p in out.iterdir()) == ["b.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["models"]  # no temporaries, no lock file
    (tmp_path / "file").write_text("x")
    with pytest.raises(FileExistsError), atomic_dir(tmp_path / "file"):
        pass


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_code_version_marks_uncommitted_code(tmp_path):
    repo = tmp_path / "repo"
    shutil.copytree(ROOT / "src", repo / "src", ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "PYTHONPATH": str(repo / "src"), "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t",
           "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t"}
    git = ["git", "-C", str(repo)]
    subprocess.run([*git, "init", "-q"], check=True, env=env)
    subprocess.run([*git, "add", "-A"], check=True, env=env)
    subprocess.run([*git, "commit", "-qm", "x"], check=True, env=env)
    probe = [sys.executable, "-c", "from crgpr.io import code_version; print(code_version())"]

    def version() -> str:
        return subprocess.run(probe, env=env, capture_output=True, text=True, check=True,
                              cwd=tmp_path).stdout.strip()

    clean = version()
    assert clean.startswith("0.") and "+g" in clean and not clean.endswith(".dirty")
    (repo / "results.csv").write_text("a run's output is not code\n")
    assert version() == clean
    io = repo / "src" / "crgpr" / "io.py"
    io.write_text(io.read_text() + "\n# an uncommitted edit\n")
    assert version() == clean + ".dirty"


@pytest.mark.parametrize("section", ["rod", "simulation"])
def test_schema_defaults_are_the_config_values(section):
    """The paper's rod and time grid live in config.yaml; the schema's defaults (used by
    ``crgpr simulate`` without a config) must be the same values, key for key."""
    from crgpr.config import schema_defaults

    assert schema_defaults(section) == load_config(CONFIG)[section]
