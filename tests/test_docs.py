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


# --- the configuration reference is generated from the schemas -------------------------------

def test_configuration_page_equals_the_generators_output():
    from crgpr.commands.config_doc import config_page

    page = ROOT / "docs" / "configuration.md"
    assert page.read_text() == config_page(str(ROOT / "config.yaml")), \
        "docs/configuration.md is stale: run `crgpr config-doc --out docs/configuration.md`"


def test_every_config_key_has_a_description_and_a_row():
    import yaml

    from crgpr.commands.config_doc import schema_sections
    from crgpr.config import schema
    from crgpr.report.config_doc import undocumented_keys

    main = schema()
    assert undocumented_keys(main, schema_sections(main)) == []
    page = (ROOT / "docs" / "configuration.md").read_text()

    def leaves(d, prefix=""):
        for k, v in d.items():
            key = f"{prefix}{k}"
            if isinstance(v, dict) and key not in {"rollouts.methods", "variants.definitions",
                                                    "variants.methods", "ports.signals",
                                                    "materials_study.cases"}:
                yield from leaves(v, key + ".")
            else:
                yield key

    cfg = yaml.safe_load((ROOT / "config.yaml").read_text())
    missing = [k for k in leaves(cfg) if f"| `{k}` |" not in page]
    assert missing == []


def test_unit_is_the_bracketed_part_of_the_description():
    from crgpr.report.config_doc import split_unit

    assert split_unit("rod length [m]") == ("rod length", "m")
    assert split_unit("noise floor [m/s or rad/s]") == ("noise floor", "m/s or rad/s")
    assert split_unit("a subset of [n1, n2] x [-]") == ("a subset of [n1, n2] x", "-")
    assert split_unit("no unit here") == ("no unit here", "")


def test_config_doc_command_writes_the_page(tmp_path):
    from crgpr.cli import main

    out = tmp_path / "configuration.md"
    assert main(["config-doc", "--config", str(ROOT / "config.yaml"), "--out", str(out)]) == 0
    assert "| `rod.L0` | number | m | rod length | `0.5` |" in out.read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text("seed: -1\n")
    assert main(["config-doc", "--config", str(bad), "--out", str(tmp_path / "x.md")]) == 2
    assert not (tmp_path / "x.md").exists()


# --- every results file is described in docs/data-formats.md ---------------------------------

def test_every_results_table_and_metric_has_a_heading_in_data_formats():
    page = (ROOT / "docs" / "data-formats.md").read_text()
    headings = set(re.findall(r"^### `([^`]+)`\s*$", page, flags=re.M))
    files = sorted(p.name for d in ("results/tables", "results/metrics")
                   for p in (ROOT / d).iterdir() if p.is_file())
    assert [f for f in files if f not in headings] == []


# --- the project's files describe the project, not how it was made ----------------------------

# Written with character classes so that this file does not match itself.
PROCESS_WORDS = {
    "issue number": r"\bis[s]ues? ?#?\d+|(?<![\w&*])#\d{1,3}\b",
    "work name": r"\b(?:u[q]|dis[c]|discover[y]|camer[a])\d\b|\bhelpe[r]\b|\blead engine[e]r\b|\bLea[d],",
    "sitting of work": r"(?<!scope=\")\bsessio[n]s?\b",
    "date of work": r"\b\d{1,2} (?:Ja[n]|Fe[b]|Ma[r]|Ap[r]|Ma[y]|Ju[n]|Ju[l]|Au[g]|Se[p]|Oc[t]|No[v]|De[c])\b"
                    r"|\b(?:No[v]|De[c]) \d{1,2}\b|\b202[4-9]-\d\d-\d\d\b",
    "scratch path": r"(?<!-d )/tm[p]/",  # cited as a source (a command's run directory is fine)
}
SCANNED = ["README.md", "environment-notes.md", "ARCHITECTURE.md", "config.yaml", "pyproject.toml",
           "docs", "workflow", "tests", "src", "benchmarks", "profiles", "results/tables"]
# (file, text on the matching line): each a use of the words that is not about how the work went
ALLOWED = [
    ("tests/test_cluster.py", "2026]"),  # timestamps of a sample Slurm log
    ("workflow/cluster/test-slurm.sh", "/test-slurm-"),  # the script's own temporary log files
]


def _scanned_files():
    for name in SCANNED:
        path = ROOT / name
        files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
        for f in files:
            if f.suffix in {".md", ".py", ".yaml", ".yml", ".smk", ".sh", ".rst", ".txt", ".toml"} \
                    or f.name == "Snakefile":
                yield f


def test_no_process_words_in_the_projects_files():
    pattern = re.compile("|".join(f"(?:{p})" for p in PROCESS_WORDS.values()), flags=re.I)
    hits = []
    for f in _scanned_files():
        rel = f.relative_to(ROOT).as_posix()
        for n, line in enumerate(f.read_text(errors="replace").splitlines(), 1):
            m = pattern.search(line)
            if m and not any(rel == a and text in line for a, text in ALLOWED):
                hits.append(f"{rel}:{n}: {m.group(0)!r} in {line.strip()[:100]}")
    assert hits == [], "\n".join(hits)
