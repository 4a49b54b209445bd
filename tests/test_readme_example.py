"""The README's "Use it on your own rod" example, run as written on the smoke config.

The commands are read from the README itself (the first ``bash`` block of that section), so the
example cannot drift from what is tested. Two substitutions make it small: ``config.yaml`` becomes
``tests/smoke_config.yaml`` (a 10-segment rod, a 0.4 s record) and the rollout's ``--t-end`` is
cut to 0.1 s. Everything else (file names, options, their order) is the README's.
"""

from __future__ import annotations

import json
import math
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from crgpr.config import load_config

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "tests" / "smoke_config.yaml"
SECTION = "## Use it on your own rod"
T_END = 0.1  # [s] the rollout's length here (the README asks for 1 s on the full config)


def readme_commands() -> list[list[str]]:
    """The ``crgpr`` command lines of the first bash block under SECTION, as argument lists."""
    text = (ROOT / "README.md").read_text()
    assert SECTION in text, f"README.md has no section {SECTION!r}"
    body = text.split(SECTION, 1)[1]
    block = re.search(r"```bash\n(.*?)```", body, re.S)
    assert block, f"README.md: no bash block under {SECTION!r}"
    lines = block.group(1).replace("\\\n", " ").splitlines()
    return [shlex.split(ln) for ln in lines if ln.strip().startswith("crgpr ")]


def smoke_args(argv: list[str]) -> list[str]:
    """One README command with the smoke config and the short rollout."""
    out = [str(SMOKE) if a == "config.yaml" else a for a in argv[1:]]
    if "--t-end" in out:
        out[out.index("--t-end") + 1] = str(T_END)
    return out


def option(argv: list[str], name: str) -> str:
    return argv[argv.index(name) + 1]


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    """Run the README's commands in order in a fresh directory; returns it and the commands."""
    cmds = readme_commands()
    work = tmp_path_factory.mktemp("readme_example")
    for argv in cmds:
        args = smoke_args(argv)
        res = subprocess.run([sys.executable, "-m", "crgpr.cli", *args], cwd=work, capture_output=True,
                             text=True, timeout=300)
        assert res.returncode == 0, f"crgpr {shlex.join(args)} failed:\n{res.stderr[-2000:]}"
    return work, {argv[1]: argv for argv in cmds}


def test_the_readme_example_is_the_four_step_workflow():
    """The example makes a camera record, learns from it, rolls the model out and runs the
    missing-physics search, in that order, each on the one config."""
    cmds = readme_commands()
    assert [c[1] for c in cmds] == ["discover-data", "learn", "rollout", "discover"]
    assert all(option(c, "--config") == "config.yaml" for c in cmds)
    data, learn, roll, disc = cmds
    assert option(learn, "--measured") == option(disc, "--measured") == option(data, "--out")
    assert option(roll, "--models") == option(learn, "--out")


@pytest.mark.slow
def test_the_camera_record_has_the_measured_file_format(example):
    """t [s], a marker place (node or s), x, y [m]; uniform frames; at least four markers."""
    work, cmds = example
    df = pd.read_parquet(work / option(cmds["discover-data"], "--out"))
    place = "node" if "node" in df.columns else "s"
    assert {"t", place, "x", "y"} <= set(df.columns)
    assert df[place].nunique() >= 4
    dt = np.diff(np.unique(df["t"]))
    assert np.allclose(dt, dt[0], rtol=1e-6)
    L0 = load_config(SMOKE)["rod"]["L0"]
    assert np.all(np.hypot(df["x"], df["y"]) <= 1.05 * L0)


@pytest.mark.slow
def test_learn_writes_a_model_directory_whose_noise_estimate_matches_the_camera(example):
    """The manifest says what the model was trained on, every learned model has its .npz and
    .json, and the noise level the GP prefilter estimates from the positions is the camera's
    (1 mm in the smoke config's discovery section) to within 30 %."""
    work, cmds = example
    d = work / option(cmds["learn"], "--out")
    man = json.loads((d / "manifest.json").read_text())
    assert (man["kind"], man["input"]) == ("crgpr_models", "positions")
    assert (man["features"], man["prefilter"]) == (option(cmds["learn"], "--features"),
                                                 option(cmds["learn"], "--prefilter"))
    for name in man["models"]:
        assert (d / f"{name}.npz").is_file() and (d / f"{name}.json").is_file()
    noise = load_config(SMOKE)["discovery"]["noise_std_m"]
    assert man["state"]["noise_std_m_estimated"] == pytest.approx(noise, rel=0.3)


@pytest.mark.slow
def test_rollout_starts_straight_at_the_requested_angle_and_stays_finite(example):
    work, cmds = example
    roll = cmds["rollout"]
    df = pd.read_parquet(work / option(roll, "--out"))
    N = json.loads((work / option(roll, "--models") / "manifest.json").read_text())["rod"]["N"]
    assert df["t"].max() == pytest.approx(T_END) and sorted(df["node"].unique()) == list(range(N + 1))
    cols = ["x", "y", "theta", "p_x", "p_y", "p_theta"]
    assert np.all(np.isfinite(df[cols].to_numpy()))
    start = df[df["t"] == df["t"].min()]
    assert np.allclose(start["theta"], math.radians(float(option(roll, "--theta0"))), atol=1e-9)
    assert np.allclose(start[["p_x", "p_y", "p_theta"]], 0.0)


@pytest.mark.slow
def test_discover_names_the_hidden_effect_and_closes_the_gap(example):
    """The stand-in record hides a tip mass: the search names exactly the hidden effects, and
    the augmented model's gap is smaller than the nominal model's."""
    work, cmds = example
    out = work / option(cmds["discover"], "--out")
    res = json.loads((out / "discovery.json").read_text())
    truth = json.loads((work / option(cmds["discover-data"], "--truth-out")).read_text())
    assert res["verdict"] == "effect_found"
    assert {e["name"] for e in res["effects"]} == set(truth["effects"])
    assert res["gap_after"] < res["gap_before"]
    assert (out / "report.md").is_file()
