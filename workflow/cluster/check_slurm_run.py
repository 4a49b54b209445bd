"""Check a Snakemake run through the SLURM executor against Slurm's records and a local run.

Used by workflow/cluster/test-slurm.sh; exits 0 only if every check holds, else prints one line
per failed check and exits 1.

1. Every job went through sbatch. Each job Snakemake scheduled (the "rule NAME:" blocks of its
   log; local rules excepted) has a "submitted with SLURM jobid N" line, a per-job Slurm log
   file ``<slurm-logs>/rule_<rule>/<wildcards>/N.log`` that is not empty, and a record in
   slurmctld's job-completion log (``JobCompType=jobcomp/filetxt``) with JobState=COMPLETED and
   ExitCode=0:0. The number of Slurm jobs equals the number of scheduled jobs.
2. Resources as requested: for each Slurm job, the CPUs, memory and time limit Slurm granted
   (jobcomp ``ProcCnt``, ``Tres mem``, ``TimeLimit``) equal the rule's ``threads``, ``mem_mb``
   (MB) and ``runtime`` (minutes) as Snakemake printed them for that job.
3. Outputs equal those of the local run. The two ``results/`` trees hold the same files, and
   - Parquet: same columns, dtypes and values (bit-equal; NaN equals NaN) except timing
     columns, and the same crgpr metadata (``crgpr.io.read_metadata``) except timing keys;
   - JSON: equal after dropping timing keys at any depth;
   - ``.npz``: same array names, shapes, dtypes and bit-equal values;
   - ``.pt`` (PINN state dicts, loaded with ``weights_only=True``): bit-equal tensors;
   - CSV: equal as tables (values bit-equal after parsing) except timing columns and, in
     ``paper_vs_reproduction.csv``, the measured columns of the timing rows;
   - Markdown: equal line by line, except that in timing lines (``[min]``, ``| stageN |``,
     ``Run time ...``) only the numbers may differ;
   - PNG and anything else: byte-equal.
   Timing keys/columns are wall-clock measurements, named so by the project's convention: a
   key or column ``seconds``, ``seconds_*`` or ``*_seconds`` (``seconds_hyper``,
   ``seconds_exact_weights``, ``fit_seconds``, ``posterior_scale_seconds``, ...), or one of
   ``sampling_s``, ``runtime_s``, ``wall_s``, ``minutes`` and the ``timing_s`` dict (metadata,
   JSON, Parquet and CSV alike). ``code_version`` (package version + git commit)
   is compared like any other key: a local run made at another commit does not count;
   ``--ignore-code-version`` allows it where the commits differ only outside ``src/``.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

TIMING_NAMES = frozenset({"sampling_s", "runtime_s", "wall_s", "minutes", "timing_s"})
TIMING_NAME = re.compile(r"^seconds(_\w+)?$|^\w+_seconds$")


def is_timing(name: object) -> bool:
    """Whether a metadata/JSON key or table column holds a wall-clock measurement."""
    return isinstance(name, str) and (name in TIMING_NAMES or bool(TIMING_NAME.match(name)))


# paper_vs_reproduction.csv: the timing rows' measured columns
TIMING_ROW_SOURCE = "Table (timing)"
TIMING_ROW_COLUMNS = ("ours", "abs_diff", "rel_diff")
TIMING_LINE = re.compile(r"\[min\]|^\| stage\d+ \||^Run time ")
NUMBER = re.compile(r"[-+]?\d+(\.\d+)?([eE][-+]?\d+)?%?")
IGNORED_FILES = frozenset({".snakemake_timestamp"})


# ---------------------------------------------------------------- the Snakemake log and Slurm


def parse_snakemake_log(text: str) -> tuple[dict[int, dict[str, Any]], dict[int, dict[str, str]]]:
    """Jobs scheduled (jobid -> rule, wildcards, threads, resources, local) and submissions
    (jobid -> slurm job id, log path) from a Snakemake log."""
    jobs: dict[int, dict[str, Any]] = {}
    submitted: dict[int, dict[str, str]] = {}
    current: dict[str, Any] | None = None
    for line in text.splitlines():
        m = re.match(r"^(local)?rule (\w+):$", line)
        if m:
            current = {"rule": m.group(2), "local": bool(m.group(1)), "threads": 1,
                       "wildcards": "", "resources": {}}
            continue
        if current is not None:
            m = re.match(r"^\s+(\w+): (.*)$", line)
            if m:
                key, value = m.groups()
                if key == "jobid":
                    current["jobid"] = int(value)
                    jobs[int(value)] = current
                elif key == "wildcards":
                    current["wildcards"] = value
                elif key == "threads":
                    current["threads"] = int(value)
                elif key == "resources":
                    current["resources"] = dict(kv.split("=", 1) for kv in value.split(", "))
                continue
            current = None
        m = re.search(r"Job (\d+) has been submitted with SLURM jobid (\d+) \(log: (.+)\)\.$", line)
        if m:
            submitted[int(m.group(1))] = {"slurm_id": m.group(2), "log": m.group(3)}
    return jobs, submitted


def parse_jobcomp(text: str) -> dict[str, dict[str, str]]:
    """slurmctld's jobcomp/filetxt records: slurm job id -> {field: value}."""
    records = {}
    for line in text.splitlines():
        fields = dict(re.findall(r"(\w+)=(\S*)", line))
        if "JobId" in fields:
            records[fields["JobId"]] = fields
    return records


def tres_mem_mb(tres: str) -> float:
    """Memory in MB from a TRES string such as ``cpu=1,mem=1000M,node=1``."""
    m = re.search(r"(?:^|,)mem=([\d.]+)([KMGT]?)", tres)
    if not m:
        return float("nan")
    scale = {"K": 1 / 1024, "M": 1, "": 1, "G": 1024, "T": 1024**2}[m.group(2)]
    return float(m.group(1)) * scale


def check_jobs(log_text: str, jobcomp_text: str, slurm_logs: Path, host: str | None) -> list[str]:
    """Checks 1 and 2 of the module docstring; returns the failures."""
    jobs, submitted = parse_snakemake_log(log_text)
    records = parse_jobcomp(jobcomp_text)
    remote = {j: job for j, job in jobs.items() if not job["local"]}
    failures = []
    if not remote:
        failures.append("the Snakemake log names no job")
    for jobid, job in sorted(remote.items()):
        what = f"job {jobid} ({job['rule']}{' ' + job['wildcards'] if job['wildcards'] else ''})"
        sub = submitted.get(jobid)
        if sub is None:
            failures.append(f"{what}: never submitted to Slurm")
            continue
        sid = sub["slurm_id"]
        log = Path(sub["log"])
        if not (log.is_file() and log.stat().st_size > 0):
            failures.append(f"{what}: Slurm log {log} missing or empty")
        elif (log.parent.parts[-1 - bool(job["wildcards"])] != f"rule_{job['rule']}"
              or log.name != f"{sid}.log"):
            failures.append(f"{what}: Slurm log {log} not at rule_{job['rule']}/.../{sid}.log")
        elif slurm_logs.resolve() not in log.resolve().parents:
            failures.append(f"{what}: Slurm log {log} outside {slurm_logs}")
        rec = records.get(sid)
        if rec is None:
            failures.append(f"{what}: Slurm job {sid} not in the job-completion log")
            continue
        if rec.get("JobState") != "COMPLETED" or rec.get("ExitCode") != "0:0":
            failures.append(f"{what}: Slurm job {sid} {rec.get('JobState')} exit {rec.get('ExitCode')}")
        if host and rec.get("NodeList") != host:
            failures.append(f"{what}: Slurm job {sid} ran on {rec.get('NodeList')}, not {host}")
        want_mem = float(job["resources"].get("mem_mb", "nan"))
        want_min = float(job["resources"].get("runtime", "nan"))
        got = (int(rec.get("ProcCnt", -1)), tres_mem_mb(rec.get("Tres", "")),
               float(rec.get("TimeLimit", "nan")))
        if got != (job["threads"], want_mem, want_min):
            failures.append(
                f"{what}: Slurm job {sid} got cpus/mem_mb/minutes {got}, "
                f"rule asks {(job['threads'], want_mem, want_min)}"
            )
    extra = set(records) - {s["slurm_id"] for s in submitted.values()}
    if extra:
        failures.append(f"Slurm jobs not from this run: {sorted(extra)}")
    if len(submitted) != len(remote):
        failures.append(f"{len(submitted)} Slurm submissions for {len(remote)} scheduled jobs")
    print(f"check_slurm_run: {len(remote)} jobs scheduled, {len(submitted)} submitted with sbatch, "
          f"{sum(r.get('JobState') == 'COMPLETED' for r in records.values())} COMPLETED in Slurm, "
          f"{len(jobs) - len(remote)} local")
    return failures


# ---------------------------------------------------------------- outputs


CODE_VERSION = re.compile(r"^\d+\.\d+\.\d+(\+g[0-9a-f]+)?$")
IGNORE_CODE_VERSION = False  # set by --ignore-code-version


def drop_timing(obj: Any) -> Any:
    """``obj`` without timing keys, at any depth (and, with --ignore-code-version, with every
    code-version string, e.g. the ``inputs`` map of input file -> code version, masked)."""
    if isinstance(obj, dict):
        return {k: drop_timing(v) for k, v in obj.items() if not is_timing(k)}
    if isinstance(obj, list):
        return [drop_timing(v) for v in obj]
    if IGNORE_CODE_VERSION and isinstance(obj, str) and CODE_VERSION.match(obj):
        return "<code_version>"
    return obj


def frames_equal(a: pd.DataFrame, b: pd.DataFrame) -> str | None:
    """None if equal (same columns, dtypes, bit-equal values, NaN == NaN), else why not."""
    if list(a.columns) != list(b.columns):
        return f"columns {list(a.columns)} != {list(b.columns)}"
    if a.shape != b.shape:
        return f"shape {a.shape} != {b.shape}"
    for col in a.columns:
        x, y = a[col], b[col]
        if x.dtype != y.dtype:
            return f"column {col}: dtype {x.dtype} != {y.dtype}"
        if pd.api.types.is_float_dtype(x.dtype):
            xv, yv = x.to_numpy(), y.to_numpy()
            same = (xv == yv) | (np.isnan(xv) & np.isnan(yv))
            if not same.all():
                diff = np.nanmax(np.abs(xv - yv)[~same]) if (~same).any() else np.nan
                return f"column {col}: {int((~same).sum())} values differ (max |diff| {diff:.3g})"
        elif not x.equals(y):
            return f"column {col}: values differ"
    return None


def compare_parquet(a: Path, b: Path) -> str | None:
    from crgpr.io import read_metadata

    da, db = (d.drop(columns=[c for c in d.columns if is_timing(c)])
              for d in (pd.read_parquet(a), pd.read_parquet(b)))
    why = frames_equal(da, db)
    if why:
        return why
    ma, mb = drop_timing(read_metadata(a)), drop_timing(read_metadata(b))
    return None if ma == mb else f"metadata differs: {diff_keys(ma, mb)}"


def diff_keys(a: Any, b: Any, path: str = "") -> list[str]:
    """Paths at which two JSON-like objects differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += diff_keys(a.get(k), b.get(k), f"{path}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [p for i, (x, y) in enumerate(zip(a, b, strict=True)) for p in diff_keys(x, y, f"{path}[{i}]")]
    return [] if a == b or (a != a and b != b) else [path or "."]  # a != a: NaN


def compare_json(a: Path, b: Path) -> str | None:
    ja, jb = drop_timing(json.loads(a.read_text())), drop_timing(json.loads(b.read_text()))
    keys = diff_keys(ja, jb)
    return f"differs at {keys[:5]}" if keys else None


def compare_npz(a: Path, b: Path) -> str | None:
    with np.load(a, allow_pickle=False) as za, np.load(b, allow_pickle=False) as zb:
        if sorted(za.files) != sorted(zb.files):
            return f"arrays {sorted(za.files)} != {sorted(zb.files)}"
        for k in za.files:
            x, y = za[k], zb[k]
            same = x.dtype == y.dtype and x.shape == y.shape
            if not (same and np.array_equal(x, y, equal_nan=x.dtype.kind in "fc")):
                return f"array {k} differs"
    return None


def compare_pt(a: Path, b: Path) -> str | None:
    import torch

    sa = torch.load(a, map_location="cpu", weights_only=True)
    sb = torch.load(b, map_location="cpu", weights_only=True)
    flat_a, flat_b = _flatten(sa), _flatten(sb)
    if flat_a.keys() != flat_b.keys():
        return "state dict keys differ"
    for k, x in flat_a.items():
        y = flat_b[k]
        if isinstance(x, torch.Tensor):
            if not (isinstance(y, torch.Tensor) and x.dtype == y.dtype and torch.equal(x, y)):
                return f"tensor {k} differs"
        elif drop_timing(x) != drop_timing(y) and not is_timing(k.rsplit(".", 1)[-1]):
            return f"entry {k} differs"
    return None


def _flatten(obj: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(obj, dict):
        out: dict[str, Any] = {}
        for k, v in obj.items():
            out.update(_flatten(v, f"{prefix}.{k}" if prefix else str(k)))
        return out
    return {prefix: obj}


def compare_csv(a: Path, b: Path) -> str | None:
    def without_timing(d: pd.DataFrame) -> pd.DataFrame:
        d = d.drop(columns=[c for c in d.columns if is_timing(c)])
        if "source" in d.columns:
            rows = d["source"] == TIMING_ROW_SOURCE
            for c in TIMING_ROW_COLUMNS:
                if c in d.columns:
                    d[c] = d[c].astype(object)
                    d.loc[rows, c] = "<timing>"
        return d

    return frames_equal(without_timing(pd.read_csv(a)), without_timing(pd.read_csv(b)))


def compare_md(a: Path, b: Path) -> str | None:
    la, lb = a.read_text().splitlines(), b.read_text().splitlines()
    if len(la) != len(lb):
        return f"{len(la)} != {len(lb)} lines"
    for i, (x, y) in enumerate(zip(la, lb, strict=True), 1):
        if x == y:
            continue
        if TIMING_LINE.search(x) and NUMBER.sub("#", x) == NUMBER.sub("#", y):
            continue
        return f"line {i} differs: {x!r} != {y!r}"
    return None


def compare_bytes(a: Path, b: Path) -> str | None:
    return None if a.read_bytes() == b.read_bytes() else "bytes differ"


COMPARE = {".parquet": compare_parquet, ".json": compare_json, ".npz": compare_npz, ".pt": compare_pt,
           ".csv": compare_csv, ".md": compare_md}


def check_outputs(local: Path, cluster: Path) -> list[str]:
    """Check 3 of the module docstring; returns the failures."""
    def files(root: Path) -> set[Path]:
        return {p.relative_to(root) for p in root.rglob("*") if p.is_file() and p.name not in IGNORED_FILES}

    fa, fb = files(local / "results"), files(cluster / "results")
    failures = [f"only in the local run: {p}" for p in sorted(fa - fb)]
    failures += [f"only in the Slurm run: {p}" for p in sorted(fb - fa)]
    counts: dict[str, int] = {}
    for rel in sorted(fa & fb):
        compare = COMPARE.get(rel.suffix, compare_bytes)
        counts[rel.suffix] = counts.get(rel.suffix, 0) + 1
        why = compare(local / "results" / rel, cluster / "results" / rel)
        if why:
            failures.append(f"results/{rel}: {why}")
    print(f"check_slurm_run: compared {len(fa & fb)} output files "
          f"({', '.join(f'{n} {s}' for s, n in sorted(counts.items()))})")
    return failures


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--snakemake-log", type=Path, required=True)
    ap.add_argument("--jobcomp", type=Path, required=True)
    ap.add_argument("--slurm-logs", type=Path, required=True)
    ap.add_argument("--local", type=Path, required=True, help="working directory of the local run")
    ap.add_argument("--cluster", type=Path, required=True, help="working directory of the Slurm run")
    ap.add_argument("--host", help="node every job must have run on")
    ap.add_argument("--ignore-code-version", action="store_true",
                    help="do not compare the code_version metadata key (runs made at different commits)")
    args = ap.parse_args(argv)
    for p in (args.snakemake_log, args.jobcomp):
        if not p.is_file():
            print(f"check_slurm_run: FAIL: {p} missing", file=sys.stderr)
            return 1
    failures = check_jobs(
        args.snakemake_log.read_text(), args.jobcomp.read_text(), args.slurm_logs, args.host
    )
    if args.ignore_code_version:
        global IGNORE_CODE_VERSION
        IGNORE_CODE_VERSION = True
        print("check_slurm_run: code_version not compared (--ignore-code-version)")
    failures += check_outputs(args.local, args.cluster)
    for f in failures:
        print(f"check_slurm_run: FAIL: {f}", file=sys.stderr)
    if not failures:
        print("check_slurm_run: all checks hold")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
