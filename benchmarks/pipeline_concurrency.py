"""Benchmark: how busy the cores were during a Snakemake run, from its log.

    python benchmarks/pipeline_concurrency.py .snakemake/log/<run>.snakemake.log

(docs/performance.md, "The full pipeline"). Reads each job's start (the ``[timestamp]`` line
before its ``rule``/``localrule`` block and its ``jobid``) and end (``Finished jobid``) from the
log, to the second, and prints the span from the first start to the last end and how many of
its seconds had no job, one job and two or more jobs running; then every stretch of at least
``--min-alone`` seconds with one job alone, with that job's rule. With ``-j2`` the seconds with
one job are the run's idle core time.
"""

from __future__ import annotations

import argparse
import datetime as dt
import re
import sys
from pathlib import Path

import numpy as np

_STAMP = re.compile(r"^\[(\w{3} \w{3} +\d+ [\d:]+ \d{4})\]")
_RULE = re.compile(r"^(?:local)?rule (\w+):")
_JOBID = re.compile(r"^\s+jobid: (\d+)")
_DONE = re.compile(r"^Finished jobid: (\d+)")


def job_spans(lines: list[str]) -> dict[int, tuple[str, dt.datetime, dt.datetime]]:
    """jobid -> (rule, start, end) of every finished job of a Snakemake log."""
    stamp, rule = None, None
    start: dict[int, tuple[str, dt.datetime]] = {}
    out = {}
    for line in lines:
        if m := _STAMP.match(line):
            stamp = dt.datetime.strptime(m.group(1), "%a %b %d %H:%M:%S %Y")
        elif m := _RULE.match(line):
            rule = m.group(1)
        elif (m := _JOBID.match(line)) and rule is not None and stamp is not None:
            start[int(m.group(1))], rule = (rule, stamp), None
        elif (m := _DONE.match(line)) and int(m.group(1)) in start and stamp is not None:
            name, t0 = start[int(m.group(1))]
            out[int(m.group(1))] = (name, t0, stamp)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log", help="a Snakemake log (.snakemake/log/*.snakemake.log, or the run's stderr)")
    ap.add_argument("--min-alone", type=int, default=20, help="report stretches of one job this long [s]")
    args = ap.parse_args()
    path = Path(args.log)
    if not path.is_file():
        print(f"pipeline_concurrency.py: {path}: no such file", file=sys.stderr)
        return 2
    spans = job_spans(path.read_text().splitlines())
    if not spans:
        print(f"pipeline_concurrency.py: {path}: no finished job in the log", file=sys.stderr)
        return 2
    t0 = min(s for _, s, _ in spans.values())
    n = int((max(e for _, _, e in spans.values()) - t0).total_seconds())
    running = np.zeros(n, dtype=int)
    for _, s, e in spans.values():
        running[int((s - t0).total_seconds()):int((e - t0).total_seconds())] += 1
    print(f"{len(spans)} jobs over {n} s: {int(np.sum(running == 0))} s with no job, "
          f"{int(np.sum(running == 1))} s with one, {int(np.sum(running >= 2))} s with two or more")
    alone = np.r_[False, running == 1, False].astype(int)
    for a, b in zip(np.flatnonzero(np.diff(alone) == 1), np.flatnonzero(np.diff(alone) == -1), strict=True):
        if b - a >= args.min_alone:
            who = [r for r, s, e in spans.values()
                   if (s - t0).total_seconds() <= a and (e - t0).total_seconds() >= b]
            print(f"  one job alone {a}-{b} s ({b - a} s): {', '.join(who) or '?'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
