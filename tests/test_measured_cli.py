"""Commands that read measured data, as a new user meets them outside the repository: a
Parquet or CSV file (by extension), the rod taken as ``crgpr simulate`` takes it (the packaged
default config, the paper's rod; ``--config``; ``--set``), the values used in the output's
manifest, and bad input as one line naming the file and column, exit code 2, nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.pandas import column, data_frames

from crgpr.cli import main
from crgpr.commands.discovery import case_seed
from crgpr.config import (
    ConfigError,
    cli_config,
    load_config,
    packaged_config_path,
    parse_config_sets,
    rod_params,
)
from crgpr.discovery.synthetic import find_case, make_measured
from crgpr.io import load_npz, read_table, write_parquet

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config.yaml"
# small and quick: fewer bootstrap replicates and fit evaluations, fewer frames and LML points;
# each is a --set, so the same runs check that --set reaches the output and its manifest
DISCOVER_SETS = ["discovery.bootstrap_replicates=1", "discovery.refine_max_nfev=10"]
LEARN_SETS = ["gradient_models.n_hyper=200", "camera.learn.n_t_out=40", "E=3.3e6",
              "camera.learn.record_fit.mode=none"]  # what is read and stored, not the fit to the record


@pytest.fixture(scope="module")
def record(tmp_path_factory) -> dict[str, Path]:
    """A 0.3 s camera record (tip-mass case, paper's rod) as Parquet and as the CSV a
    motion-capture tool exports (header, comma-separated, blanks after the commas)."""
    cfg = load_config(CONFIG)
    d = {**cfg["discovery"], "duration_s": 0.3}
    case = find_case(d["cases"], "tip_mass")
    frame, _ = make_measured(rod_params(cfg), d, case, case_seed(cfg["seed"], "tip_mass"))
    base = tmp_path_factory.mktemp("record")
    write_parquet(frame, base / "rec.parquet")
    (base / "rec.csv").write_text(frame.to_csv(index=False).replace(",", ", "))
    return {"parquet": base / "rec.parquet", "csv": base / "rec.csv"}


@pytest.fixture
def elsewhere(tmp_path, monkeypatch) -> Path:
    """An empty working directory outside the repository (no ./config.yaml)."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _one_line_error(capsys, *names: str) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for n in names:
        assert n in err, err
    return err


# --------------------------------------------------------------------------------------------
# read_table: the extension decides the reader; both give the same numbers
# --------------------------------------------------------------------------------------------
@settings(max_examples=30, deadline=None)
@given(data_frames([column("t", dtype=float, elements=st.floats(allow_nan=False, allow_infinity=False)),
                    column("node", dtype=np.int64, elements=st.integers(-2**40, 2**40)),
                    column("x", dtype=float, elements=st.floats(allow_infinity=False, width=64))]))
def test_csv_and_parquet_tables_hold_the_same_numbers(tmp_path_factory, df):
    d = tmp_path_factory.mktemp("tables")
    write_parquet(df, d / "a.parquet")
    df.to_csv(d / "a.CSV", index=False)
    a, b = read_table(d / "a.parquet"), read_table(d / "a.CSV")
    if len(df):
        np.testing.assert_array_equal(a.to_numpy(dtype=float), b.to_numpy(dtype=float))
    assert list(a.columns) == list(b.columns) == ["t", "node", "x"]


@pytest.mark.parametrize(("name", "content", "message"), [
    ("m.txt", "t,node,x,y\n", "expected one of .parquet, .csv"),
    ("m", "t,node,x,y\n", "expected one of .parquet, .csv"),
    ("m.csv", "", "empty CSV file"),
    ("m.parquet", "t,node,x,y\n", "not a readable Parquet file"),
    ("m.csv", 't,node\n0,"1\n', "not a readable CSV file"),
])
def test_read_table_errors_name_the_file(tmp_path, name, content, message):
    (tmp_path / name).write_text(content)
    with pytest.raises(ValueError, match=message) as err:
        read_table(tmp_path / name)
    assert str(tmp_path / name) in str(err.value) and "\n" not in str(err.value)


def test_read_table_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file"):
        read_table(tmp_path / "nope.csv")


# --------------------------------------------------------------------------------------------
# the configuration: packaged default, --config, --set
# --------------------------------------------------------------------------------------------
def test_the_packaged_default_config_is_config_yaml():
    """What a command outside the repository runs with is the repository's config.yaml (the
    paper's rod, Table I)."""
    assert yaml.safe_load(packaged_config_path().read_text()) == yaml.safe_load(CONFIG.read_text())


def test_config_source_order(elsewhere):
    assert cli_config(None, [])[1] == {"config": "the packaged default config", "set": []}
    assert cli_config(str(CONFIG), [])[1]["config"] == str(CONFIG)
    (elsewhere / "config.yaml").write_text(CONFIG.read_text().replace("seed: 20251121", "seed: 7"))
    cfg, prov = cli_config(None, [])
    assert prov["config"] == "config.yaml" and cfg["seed"] == 7  # ./config.yaml, as crgpr simulate


def test_set_takes_rod_parameters_and_dotted_keys():
    cfg = load_config(CONFIG)
    sets = ["L0=0.4", "rod.E=2e6", "camera.learn.bending_inputs=[kappa]", "camera.learn.nominal_laws=auto"]
    assert parse_config_sets(sets, cfg) == {
        "rod": {"L0": 0.4, "E": 2e6},
        "camera": {"learn": {"bending_inputs": ["kappa"], "nominal_laws": "auto"}}}


def test_simulate_takes_the_rod_key_with_or_without_its_section(elsewhere):
    """``--set rod.L0`` (as learn and discover take it) and ``--set L0`` are the same rod."""
    for name, item in (("a", "L0=0.4"), ("b", "rod.L0=0.4")):
        assert main(["simulate", "--theta0", "85", "--t-end", "0.002", "--out", f"{name}.parquet",
                     "--set", item]) == 0
    a, b = read_table(elsewhere / "a.parquet"), read_table(elsewhere / "b.parquet")
    pd.testing.assert_frame_equal(a, b)
    assert a["x"].max() == pytest.approx(0.4 * np.cos(np.radians(85)), rel=1e-3)  # the tip of a 0.4 m rod


@pytest.mark.parametrize(("item", "named"), [
    ("L0", "expected KEY=VALUE"),
    ("tip_mass=0.01", "not a rod parameter"),
    ("camera.learn.nosuch=1", "unknown config key camera.learn.nosuch"),
    ("nosuch.key=1", "unknown config key nosuch"),
])
def test_set_rejects_unknown_keys(item, named):
    with pytest.raises(ConfigError, match=named):
        parse_config_sets([item], load_config(CONFIG))


@pytest.mark.parametrize("command", ["learn", "discover"])
@pytest.mark.parametrize(("item", "named"), [
    ("rod.L0=-1", "rod.L0"),
    ("N=0", "rod.N"),
    ("camera.learn.n_t_out=many", "camera.learn.n_t_out"),
    ("discovery.min_samples=1.5", "discovery.min_samples"),
])
def test_set_values_are_validated_like_the_config(elsewhere, record, capsys, command, item, named):
    rc = main([command, "--measured", str(record["csv"]), "--out", "out", "--set", item])
    assert rc == 2
    _one_line_error(capsys, named, f"--set {item}")
    assert not (elsewhere / "out").exists()


# --------------------------------------------------------------------------------------------
# the commands from an empty directory: CSV = Parquet, values used in the manifest
# --------------------------------------------------------------------------------------------
def test_discover_from_an_empty_directory_csv_equals_parquet(elsewhere, record, capsys):
    res = {}
    for kind in ("csv", "parquet"):
        sets = [x for s in DISCOVER_SETS for x in ("--set", s)]
        assert main(["discover", "--measured", str(record[kind]), "--out", kind, *sets]) == 0
        res[kind] = json.loads((elsewhere / kind / "discovery.json").read_text())
        assert "written to" in capsys.readouterr().out
    for r in res.values():
        r.pop("timing_s")
        r.pop("measured")
    assert res["csv"] == res["parquet"]
    used = res["csv"]["config"]
    assert used["config"] == "the packaged default config" and used["set"] == DISCOVER_SETS
    assert used["discovery"]["bootstrap_replicates"] == 1 and used["discovery"]["refine_max_nfev"] == 10
    assert used["rod"] == rod_params(load_config(CONFIG)).to_dict()  # the paper's rod
    assert used["simulation"]["dt_s"] == load_config(CONFIG)["simulation"]["dt_s"]
    assert "cases" not in used["discovery"]  # only the keys the run reads


def test_learn_from_an_empty_directory_csv_equals_parquet(elsewhere, record):
    mans = {}
    for kind in ("csv", "parquet"):
        sets = [x for s in LEARN_SETS for x in ("--set", s)]
        assert main(["learn", "--measured", str(record[kind]), "--out", kind, *sets]) == 0
        mans[kind] = json.loads((elsewhere / kind / "manifest.json").read_text())
    for m in mans["csv"]["models"]:
        a, b = load_npz(elsewhere / "csv" / f"{m}.npz"), load_npz(elsewhere / "parquet" / f"{m}.npz")
        assert a.keys() == b.keys()
        for k in a:
            np.testing.assert_array_equal(a[k], b[k])
    man = mans["csv"]
    used = man["config"]
    assert used["config"] == "the packaged default config" and used["set"] == LEARN_SETS
    assert used["rod"]["E"] == man["rod"]["E"] == 3.3e6  # --set E reached the model's rod
    assert used["gradient_models"]["n_hyper"] == 200 and used["camera"]["learn"]["n_t_out"] == 40
    assert used["camera"]["learn"]["record_fit"]["mode"] == "none" and man["record_fit"] is None
    assert man["state"]["n_frames_used"] == 40
    assert set(used["discovery"]) == {"min_rate_hz", "min_samples", "outlier_k", "outlier_min_m",
                                      "geometry_tol"}


def test_learn_takes_the_config_file_given(elsewhere, record):
    smoke = ROOT / "tests" / "smoke_config.yaml"
    assert main(["learn", "--measured", str(record["parquet"]), "--out", "m", "--config", str(smoke),
                 "--set", "camera.learn.n_t_out=30", "--set", "camera.learn.record_fit.mode=none"]) == 0
    man = json.loads((elsewhere / "m" / "manifest.json").read_text())
    assert man["config"]["config"] == str(smoke)
    assert man["config"]["gradient_models"] == load_config(smoke)["gradient_models"]


# --------------------------------------------------------------------------------------------
# bad files: one line naming the file (and the column), exit 2, nothing written
# --------------------------------------------------------------------------------------------
def _bad(record: dict[str, Path], d: Path, what: str) -> tuple[Path, tuple[str, ...]]:
    text = record["csv"].read_text()
    lines = text.splitlines()
    if what == "extension":
        p = d / "rec.tsv"
        p.write_text(text)
        return p, ("rec.tsv", ".parquet, .csv")
    p = d / f"{what}.csv"
    if what == "missing_column":
        p.write_text("\n".join(", ".join(r.split(", ")[:3]) for r in lines) + "\n")
        return p, ("missing_column.csv", "missing column", "'y'")
    if what == "non_numeric":
        row = lines[7].split(", ")
        row[2] = "12.3mm"
        p.write_text("\n".join(lines[:7] + [", ".join(row)] + lines[8:]) + "\n")
        return p, ("non_numeric.csv", "'x'", "12.3mm")
    if what == "empty":
        p.write_text("")
        return p, ("empty.csv", "empty CSV file")
    raise AssertionError(what)


@pytest.mark.parametrize("command", ["learn", "discover"])
@pytest.mark.parametrize("what", ["extension", "missing_column", "non_numeric", "empty"])
def test_bad_measured_files_are_one_line_and_write_nothing(elsewhere, record, capsys, command, what):
    path, names = _bad(record, elsewhere, what)
    rc = main([command, "--measured", str(path), "--out", "out"])
    assert rc == 2
    _one_line_error(capsys, f"crgpr {command}: error:", *names)
    assert not (elsewhere / "out").exists()


def test_a_full_state_csv_with_a_non_numeric_momentum_names_the_column(elsewhere, record, capsys):
    df = pd.read_csv(record["csv"], skipinitialspace=True)
    for c in ("theta", "p_x", "p_y", "p_theta"):
        df[c] = 0.0
    df = df.astype({"p_y": object})
    df.loc[3, "p_y"] = "abc"
    df.to_csv(elsewhere / "full.csv", index=False)
    assert main(["learn", "--measured", "full.csv", "--out", "out"]) == 2
    _one_line_error(capsys, "full.csv", "'p_y'")
    assert not (elsewhere / "out").exists()
