"""Benchmark: Snakemake's own CPU under its job rate limiter (docs/performance.md).

    python benchmarks/scheduler_overhead.py --csv benchmarks/scheduler_overhead.csv

Builds a throw-away workflow in a temporary directory (``--jobs`` jobs of ``sleep --sleep``,
each with ``--inputs`` input files, as this project's jobs list their script's code closure) and
runs it with ``-j2`` twice: with Snakemake's default ``--max-jobs-per-timespan`` (100/1s) and with
the value of ``profiles/default/config.yaml`` plus the pending-timer cancellation of
``workflow/rules/common.smk``. The jobs sleep, so the CPU time of the process tree is Snakemake's
own (its scheduler passes, plus start-up and the shell of each job). Rows: setting, wall and CPU
seconds (user + system of Snakemake and its children).
"""

from __future__ import annotations

import argparse
import csv
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]

SNAKEFILE = """\
import threading
CODE = [f"code/f{{i}}.py" for i in range({inputs})]
rule all:
    input: expand("out/{{i}}.txt", i=range({jobs}))
rule a:
    input: CODE
    output: "out/{{i}}.txt"
    shell: "sleep {sleep}; touch {{output}}"
"""

CANCEL = """
def cancel_pending_scheduler_passes():
    for thread in threading.enumerate():
        if isinstance(thread, threading.Timer):
            thread.cancel()
onsuccess:
    cancel_pending_scheduler_passes()
onerror:
    cancel_pending_scheduler_passes()
"""


def run(workdir: Path, extra: list[str]) -> tuple[float, float]:
    """Wall and CPU seconds of one ``snakemake -j2 all`` in ``workdir`` from scratch."""
    for sub in ("out", ".snakemake"):
        subprocess.run(["rm", "-rf", str(workdir / sub)], check=True)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "snakemake", "-j2", "-q", *extra, "all"], cwd=workdir, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--jobs", type=int, default=150)
    ap.add_argument("--inputs", type=int, default=80)
    ap.add_argument("--sleep", type=float, default=1.0)
    ap.add_argument("--csv", type=Path)
    args = ap.parse_args()
    profile = yaml.safe_load((ROOT / "profiles" / "default" / "config.yaml").read_text())
    timespan = str(profile["max-jobs-per-timespan"])
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        settings = (("default 100/1s", [], False),
                    (f"{timespan}, timers cancelled", ["--max-jobs-per-timespan", timespan], True))
        for setting, extra, cancel in settings:
            work = Path(tmp) / setting.split()[0].replace("/", "_")
            (work / "code").mkdir(parents=True)
            for i in range(args.inputs):
                (work / "code" / f"f{i}.py").write_text(f"{i}\n")
            text = SNAKEFILE.format(inputs=args.inputs, jobs=args.jobs, sleep=args.sleep)
            (work / "Snakefile").write_text(text + (CANCEL if cancel else ""))
            wall, cpu = run(work, extra)
            rows.append({"setting": setting, "jobs": args.jobs, "inputs_per_job": args.inputs,
                         "sleep_s": args.sleep, "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
                         "cores": os.cpu_count()})
            print(rows[-1], flush=True)
    if args.csv:
        with open(args.csv, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)


if __name__ == "__main__":
    main()
