"""The README contract: its test command is exactly what CI runs."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text()
    cmd = re.search(r"TEST_COMMAND='(.+)'", ci).group(1)
    readme = (ROOT / "README.md").read_text()
    assert cmd in readme
    assert "snakemake -j2 all" in readme


def test_torch_is_pinned_to_the_cpu_build():
    assert 'pinn = ["torch==2.13.0"]' in (ROOT / "pyproject.toml").read_text()
