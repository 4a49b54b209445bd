"""The paper, regenerated: our numbers beside the paper's, tolerance bands and claim verdicts.

The paper's values live in ``workflow/paper_values.yaml`` (each with its table or sentence).
A reference such as ``accuracy:cr_gpr:mean:rmse_theta`` names one of our numbers:

    accuracy:<method>:<angle|mean>:<column>   results/metrics/accuracy.parquet
    hyper:<model>:<column>                    results/tables/table2_hyperparameters.csv
    timing:<stage>                            results/metrics/timing.parquet (minutes)
    uq:<method>:<S>:<level>:<angle|mean>:<column>   results/tables/uq_coverage.csv

Claims are small expressions over references, e.g.
``ratio(accuracy:blackbox_gp:mean:rmse_theta, accuracy:cr_gpr:mean:rmse_theta) > 20``,
parsed by a tiny recursive-descent parser (no ``eval``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from crgpr.io import read_parquet, write_csv, write_text

MATCH, OUTSIDE, MISSING = "match", "outside band", "missing"
HOLDS, FAILS, UNKNOWN = "holds", "does not hold", "not evaluated"


@dataclass
class Sources:
    """Our numbers: the tables the references point into (any may be None if not produced)."""

    accuracy: pd.DataFrame | None = None
    hyper: pd.DataFrame | None = None
    timing: pd.DataFrame | None = None
    uq: pd.DataFrame | None = None
    noise: pd.DataFrame | None = None  # results/tables/noise_ablation.csv (camera sweeps)


def load_values(path: str | Path) -> dict[str, Any]:
    data = yaml.safe_load(Path(path).read_text())
    ids = [q["id"] for q in data["quantities"]] + [c["id"] for c in data["claims"]]
    dup = {i for i in ids if ids.count(i) > 1}
    if dup:
        raise ValueError(f"{path}: duplicate ids {sorted(dup)}")
    return data


def _mean_or_angle(df: pd.DataFrame, key_col: str, key: str, col: str) -> float:
    if col not in df.columns:
        raise KeyError(col)
    if key == "mean":
        return float(df[col].mean())
    sel = df[np.isclose(df[key_col].astype(float), float(key))]
    if sel.empty:
        raise KeyError(key)
    return float(sel[col].iloc[0])


def resolve(ref: str, src: Sources) -> float:
    """Our value for a reference; NaN when the source or row does not exist."""
    kind, *parts = ref.split(":")
    try:
        if kind == "accuracy" and src.accuracy is not None:
            method, key, col = parts
            df = src.accuracy[src.accuracy["method"] == method]
            if df.empty:
                return math.nan
            return _mean_or_angle(df, "theta0_deg", key, col)
        if kind == "hyper" and src.hyper is not None:
            model, col = parts
            row = src.hyper[src.hyper["model"] == model]
            return float(row[col].iloc[0]) if not row.empty and col in row else math.nan
        if kind == "timing" and src.timing is not None:
            (stage,) = parts
            row = src.timing[src.timing["stage"] == stage]
            return float(row["minutes"].iloc[0]) if not row.empty else math.nan
        if kind == "uq" and src.uq is not None:
            method, n_samples, level, key, col = parts
            u = src.uq
            df = u[(u["method"] == method) & (u["n_samples"] == int(n_samples))
                   & (u["level"] == float(level)) & u["theta0_deg"].notna()]
            if df.empty:
                return math.nan
            return _mean_or_angle(df, "theta0_deg", key, col)
        if kind == "noise" and src.noise is not None:
            noise_mm, prefilter, features, col = parts
            d = src.noise
            row = d[np.isclose(d["noise_mm"].astype(float), float(noise_mm)) & (d["prefilter"] == prefilter)
                    & (d["features"] == features)]
            return float(row[col].iloc[0]) if not row.empty and col in row else math.nan
    except (KeyError, ValueError, IndexError):
        return math.nan
    if kind not in {"accuracy", "hyper", "timing", "uq", "noise"}:
        raise ValueError(f"unknown reference kind in {ref!r}")
    return math.nan


def in_band(paper: float, ours: float, tol: dict[str, float]) -> bool:
    """Whether ``ours`` lies in the declared tolerance band around ``paper``."""
    (kind, x), = tol.items()
    eps = 1e-12  # band edges are inclusive up to round-off
    if kind == "rel":
        return abs(ours - paper) <= x * abs(paper) * (1 + eps)
    if kind == "abs":
        return abs(ours - paper) <= x * (1 + eps)
    if kind == "factor":
        return ours > 0 and paper > 0 and 1.0 / x <= ours / paper <= x
    if kind == "at_most":
        return ours <= x * paper
    raise ValueError(f"unknown tolerance kind {kind!r}")


def _tol_text(tol: dict[str, float]) -> str:
    (kind, x), = tol.items()
    return {"rel": f"±{x:.0%}", "abs": f"±{x:g}", "factor": f"within {x:g}x",
            "at_most": f"<= {x:g} x paper"}[kind]


def compare_quantities(values: dict[str, Any], src: Sources) -> pd.DataFrame:
    rows = []
    for q in values["quantities"]:
        ours = resolve(q["ours"], src)
        paper = float(q["paper"])
        verdict = (MISSING if math.isnan(ours)
                   else MATCH if in_band(paper, ours, q["tolerance"]) else OUTSIDE)
        rows.append({
            "id": q["id"], "source": q["source"], "quantity": q["label"], "paper": paper,
            "ours": ours, "abs_diff": ours - paper,
            "rel_diff": (ours - paper) / abs(paper) if paper else math.nan,
            "tolerance": _tol_text(q["tolerance"]), "verdict": verdict,
            "known_deviation": q.get("known_deviation", ""),
        })
    return pd.DataFrame(rows)


# ---- claims: a tiny expression language -----------------------------------------------------

_TOKEN = re.compile(r"\s*(?:(?P<num>-?\d+(?:\.\d*)?(?:e[-+]?\d+)?)|(?P<op><=|>=|<|>)|"
                    r"(?P<name>[A-Za-z_][\w:.\-]*)|(?P<punct>[(),\[\]]))")


def _tokenize(text: str) -> list[tuple[str, str]]:
    pos, out = 0, []
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if not m or m.end() == pos:
            if text[pos:].strip() == "":
                break
            raise ValueError(f"cannot parse claim at {text[pos:]!r}")
        kind = m.lastgroup
        out.append((kind, m.group(kind)))
        pos = m.end()
    return out


class _Parser:
    def __init__(self, text: str, src: Sources):
        self.toks = _tokenize(text)
        self.i = 0
        self.src = src

    def peek(self) -> tuple[str, str] | None:
        return self.toks[self.i] if self.i < len(self.toks) else None

    def take(self, value: str | None = None) -> tuple[str, str]:
        tok = self.peek()
        if tok is None or (value is not None and tok[1] != value):
            raise ValueError(f"expected {value!r}, got {tok}")
        self.i += 1
        return tok

    def parse(self) -> Any:
        left = self.term()
        tok = self.peek()
        if tok and tok[0] == "op":
            op = self.take()[1]
            right = self.term()
            left = {"<": left < right, ">": left > right, "<=": left <= right, ">=": left >= right}[op]
        if self.peek() is not None:
            raise ValueError(f"trailing tokens {self.toks[self.i:]}")
        return left

    def term(self) -> Any:
        kind, val = self.take()
        if kind == "num":
            return float(val)
        if val == "[":
            items = []
            while self.peek() and self.peek()[1] != "]":
                items.append(self.term())
                if self.peek() and self.peek()[1] == ",":
                    self.take(",")
            self.take("]")
            return items
        if kind == "name":
            if self.peek() and self.peek()[1] == "(":
                self.take("(")
                args = []
                while self.peek() and self.peek()[1] != ")":
                    args.append(self.term())
                    if self.peek() and self.peek()[1] == ",":
                        self.take(",")
                self.take(")")
                return self.call(val, args)
            if ":" in val:
                return resolve(val, self.src)
            return val  # a bare name (method or column), used by best()
        raise ValueError(f"unexpected token {val!r}")

    def call(self, name: str, a: list[Any]) -> Any:
        if name == "ratio":
            return a[0] / a[1]
        if name == "lt":
            return a[0] < a[1]
        if name == "gt":
            return a[0] > a[1]
        if name == "ge":
            return a[0] >= a[1]
        if name == "sum":
            return float(sum(a))
        if name == "within":
            return abs(a[0] - a[1]) <= a[2] * min(abs(a[0]), abs(a[1]))
        if name == "best":
            method, others, cols = a
            ok = True
            for col in cols:
                mine = resolve(f"accuracy:{method}:mean:{col}", self.src)
                theirs = [resolve(f"accuracy:{o}:mean:{col}", self.src) for o in others]
                if math.isnan(mine) or any(math.isnan(t) for t in theirs):
                    return math.nan
                ok &= all(mine < t for t in theirs)
            return ok
        raise ValueError(f"unknown function {name!r}")


def evaluate_claim(check: str, src: Sources) -> str:
    """HOLDS / FAILS, or UNKNOWN when a number it needs was not produced."""
    result = _Parser(check, src).parse()
    if isinstance(result, float) and math.isnan(result):
        return UNKNOWN
    if isinstance(result, (bool, np.bool_)):
        # comparisons with NaN are False: recheck whether any operand was missing
        refs = re.findall(r"[A-Za-z_]+:[\w:.\-]+", check)
        if any(math.isnan(resolve(r, src)) for r in refs):
            return UNKNOWN
        return HOLDS if result else FAILS
    raise ValueError(f"claim {check!r} did not evaluate to a truth value")


def sweep_claims(values: dict[str, Any], src: Sources) -> list[str]:
    """Ids of the claims on the noise ablation when it was not given: they belong to the
    ``sweeps`` target (workflow/rules/camera.smk), not to ``all``."""
    return [c["id"] for c in values["claims"] if src.noise is None and "noise:" in c["check"]]


def compare_claims(values: dict[str, Any], src: Sources, only: set[str] | None = None) -> pd.DataFrame:
    """Verdict of every claim (of those in ``only`` if given); the ``sweep_claims`` are left out
    of the table when their sources are missing."""
    skip = set(sweep_claims(values, src))
    return pd.DataFrame([{"id": c["id"], "source": c["source"], "claim": c["text"], "check": c["check"],
                          "verdict": evaluate_claim(c["check"], src)} for c in values["claims"]
                         if c["id"] not in skip and (only is None or c["id"] in only)])


def build_sweep_claims(values_path: str, noise: str, out_claims: str) -> pd.DataFrame:
    """Entry point of rule ``paper_claims_sweeps``: the claims that ``paper_tables`` leaves out
    (``sweep_claims``: those on the noise ablation of target ``sweeps``), evaluated on it."""
    values = load_values(values_path)
    ids = set(sweep_claims(values, Sources()))
    ct = compare_claims(values, Sources(noise=pd.read_csv(noise)), only=ids)
    write_csv(ct, out_claims)
    return ct


def _fmt(x: float) -> str:
    if isinstance(x, float) and math.isnan(x):
        return "—"
    return f"{x:.4g}"


def render_markdown(qt: pd.DataFrame, ct: pd.DataFrame, timing: pd.DataFrame | None,
                    skipped: list[str] | None = None, verdict: list[str] | None = None) -> str:
    """The comparison as Markdown; ``verdict``: the sentences of ``verdict`` in
    paper_values.yaml (the study's verdict on the paper's CR-GPR, each naming its table row)."""
    lines = ["# Paper vs reproduction", "",
             "Generated by rule `paper_tables` from `workflow/paper_values.yaml` and our metrics. "
             "Verdict `match`: our number lies in the declared band; `outside band`: it does not "
             "(see `known_deviation`); `missing`: not produced by this run.", ""]
    if verdict:
        lines += ["## Verdict on the paper's CR-GPR", ""] + [f"- {v}" for v in verdict] + [""]
    lines += ["## Numbers", "", "| source | quantity | paper | ours | diff | rel. diff | band | verdict |",
              "| --- | --- | ---: | ---: | ---: | ---: | --- | --- |"]
    for r in qt.itertuples():
        rel = "—" if math.isnan(r.rel_diff) else f"{r.rel_diff:+.0%}"
        verdict = r.verdict + (f" ({r.known_deviation})" if r.known_deviation else "")
        lines.append(f"| {r.source} | {r.quantity} | {_fmt(r.paper)} | {_fmt(r.ours)} | "
                     f"{_fmt(r.abs_diff)} | {rel} | {r.tolerance} | {verdict} |")
    lines += ["", "## Claims", "", "| source | claim | verdict |", "| --- | --- | --- |"]
    for r in ct.itertuples():
        lines.append(f"| {r.source} | {r.claim} | **{r.verdict}** |")
    if skipped:
        lines += ["", f"Not in this table: {', '.join(skipped)} (on the camera noise ablation, target "
                  "`snakemake sweeps`, which evaluates them in `paper_claims_sweeps.csv`)."]
    if timing is not None and not timing.empty:
        lines += ["", "## Timing (Snakemake `benchmark:` files of the run)", "",
                  "| stage | description | ours [min] | jobs | paper [min] |",
                  "| --- | --- | ---: | ---: | ---: |"]
        for r in timing.itertuples():
            lines.append(f"| {r.stage} | {r.description} | {r.minutes:.2f} | {r.jobs} | "
                         f"{_fmt(r.paper_minutes)} |")
        lines.append("")
        lines.append(f"Our machine: {timing['machine'].iloc[0]}. Paper: MATLAB R2024b, 16-core AMD "
                     "workstation, 128 GB RAM.")
    return "\n".join(lines) + "\n"


def _maybe(path: str | None, reader) -> pd.DataFrame | None:
    if not path or not Path(path).exists():
        return None
    return reader(path)


def build(values_path: str, accuracy: str | None, hyper: str | None, timing: str | None,
          uq: str | None, out_csv: str, out_md: str, out_claims: str,
          noise: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Entry point of rule ``paper_tables``: write the comparison (csv, md) and the claims csv."""
    src = Sources(
        accuracy=_maybe(accuracy, read_parquet),
        hyper=_maybe(hyper, pd.read_csv),
        timing=_maybe(timing, read_parquet),
        uq=_maybe(uq, pd.read_csv),
        noise=_maybe(noise, pd.read_csv),
    )
    values = load_values(values_path)
    qt = compare_quantities(values, src)
    ct = compare_claims(values, src)
    write_csv(qt, out_csv, float_format="%.6g")
    write_csv(ct, out_claims)
    write_text(render_markdown(qt, ct, src.timing, sweep_claims(values, src), values.get("verdict")), out_md)
    return qt, ct
