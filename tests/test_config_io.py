"""Configuration validation, CLI and Parquet I/O (bad input fails clearly)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from crgpr.cli import main
from crgpr.config import ConfigError, load_config, rod_params, sim_settings
from crgpr.io import load_npz, read_metadata, read_parquet, write_npz, write_parquet
from crgpr.physics.params import RodParams, SimSettings
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
        ({"angles": {"test_deg": [60, 85]}}, "angles.test_deg"),
        ({"simulation": {"record_every": 0}}, "simulation.record_every"),
        ({"typo_section": {}}, "typo_section"),
    ],
)
def test_bad_config_names_the_key(override, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load_config(CONFIG, override)


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
    p = RodParams(E=2.0e6, base_spring=3.0)
    assert RodParams.from_dict(p.to_dict()) == p
    assert RodParams.from_dict(RodParams().to_dict()).clamped
    with pytest.raises(KeyError, match="unknown rod parameter"):
        RodParams.from_dict({"L": 1.0})
    assert SimSettings().n_steps == 20000
