"""Measured runtime and memory per rule next to the resources each rule declares.

    python benchmarks/rule_resources.py [WORKDIR ...] [--margin-mem 1.5] [--margin-cpu 5]
                                        [--margin-wall 2]

Reads the Snakemake ``benchmark:`` files (``WORKDIR/benchmarks/**/*.tsv``, columns ``s`` =
wall seconds, ``cpu_time`` = CPU seconds and ``max_rss`` = peak resident memory of the job's
process tree in MB) of one or more runs, maps each file to its rule through the rule's
``benchmark:`` pattern in ``workflow/rules/*.smk`` (the most specific pattern where two match),
and prints per rule: jobs measured, wall time (median / max), CPU time (max), peak RSS (max),
the declared ``threads``, ``mem_mb`` and ``runtime`` (minutes), and what the resource policy
of environment-notes ("Running under Slurm") asks for:

- mem_mb: margin-mem x the peak RSS, rounded up to 250 MB, at least 500 MB;
- runtime: the larger of margin-cpu x the longest job's CPU time (the unloaded wall time of a
  single-threaded job) and margin-wall x the longest wall time (on a loaded machine an upper
  bound), rounded up to 5 min, at least 5 min.

A rule that declares less than that is marked ``UNDER mem`` / ``UNDER runtime``; ``sampled``
marks a rule with a job longer than 15 s, whose peak RSS is a lower bound (Snakemake samples
memory every 0.5 s for the first ~15 s of a job, then every 30 s). Exit code 2 if a benchmark
file matches no rule or a rule's resources cannot be read.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
import statistics
import sys
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


TARGET_RULES = {"sweeps"}  # rules that only collect other rules' outputs (like `all`)

@dataclass
class Rule:
    name: str
    source: str
    benchmark: str | None = None
    threads: int = 1
    mem_mb: float | None = None
    runtime: float | None = None
    seconds: list[float] = field(default_factory=list)
    rss: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)

    def pattern(self) -> re.Pattern[str] | None:
        if self.benchmark is None:
            return None
        parts = re.split(r"\{(\w+)\}", self.benchmark)
        regex = "".join(re.escape(p) if i % 2 == 0 else r"[^/]+" for i, p in enumerate(parts))
        return re.compile(f"^{regex}$")


def parse_rules(rule_dir: Path) -> dict[str, Rule]:
    """Rules with their benchmark pattern, threads and resources, read from the .smk files."""
    rules: dict[str, Rule] = {}
    for smk in sorted(rule_dir.glob("*.smk")):
        current: Rule | None = None
        section = None
        for line in smk.read_text().splitlines():
            m = re.match(r"^rule (\w+):", line)
            u = re.match(r"^use rule (\w+) as (\w+) with:", line)
            if m or u:
                if u:  # inherits the parent's threads and resources; its own sections override
                    current = rules[u.group(2)] = dataclasses.replace(
                        rules[u.group(1)], name=u.group(2), source=smk.name, benchmark=None,
                        seconds=[], rss=[], cpu=[])
                else:
                    current = rules[m.group(1)] = Rule(m.group(1), smk.name)
                section = None
                continue
            if current is None:
                continue
            if line and not line[0].isspace():
                current = None
                continue
            m = re.match(r"^    (\w+):\s*(.*)$", line)
            if m:
                section, rest = m.groups()
                if section == "threads":
                    current.threads = int(rest.split("#")[0])
                continue
            m = re.match(r'^        (?:(\w+)=)?(.+?),?\s*(#.*)?$', line)
            if not m:
                continue
            key, value = m.group(1), m.group(2)
            if section == "benchmark" and current.benchmark is None:
                current.benchmark = value.strip().strip('"')
            elif section == "resources" and key in ("mem_mb", "runtime"):
                setattr(current, key, float(value))
    return rules


def literal_length(rule: Rule) -> int:
    """Characters of a rule's benchmark pattern outside its ``{wildcards}``."""
    return len(re.sub(r"\{\w+\}", "", rule.benchmark or ""))


def most_specific(owners: list[Rule]) -> list[Rule]:
    """Of the rules whose benchmark pattern matches one file, the one with the longest literal
    part (``rollouts/cr_gpr_objective_camera`` over ``rollouts/{method}``: the
    wildcard constraints that keep Snakemake's rules apart are code, not read here); all of
    them if that is not unique."""
    if len(owners) < 2:
        return owners
    longest = max(map(literal_length, owners))
    best = [r for r in owners if literal_length(r) == longest]
    return best if len(best) == 1 else owners


def read_benchmark(path: Path) -> tuple[float, float, float]:
    """(wall seconds, peak RSS MB, CPU seconds) of one benchmark file (last row if repeated);
    NaN where absent."""
    lines = path.read_text().splitlines()
    header, row = lines[0].split("\t"), lines[-1].split("\t")
    values = dict(zip(header, row, strict=False))

    def number(key: str) -> float:
        try:
            return float(values.get(key, "nan"))
        except ValueError:  # "NA" when the job ended before the first memory sample
            return math.nan

    return number("s"), number("max_rss"), number("cpu_time")


def suggest(rule: Rule, margin_mem: float = 1.5, margin_cpu: float = 5.0,
            margin_wall: float = 2.0) -> tuple[int | None, int | None]:
    """(mem_mb, runtime in minutes) the resource policy asks for (module docstring); None
    where nothing was measured."""
    rss = [r for r in rule.rss if not math.isnan(r)]
    mem = max(500, 250 * math.ceil(margin_mem * max(rss) / 250)) if rss else None
    cpu = [c for c in rule.cpu if not math.isnan(c)]
    wall = [w for w in rule.seconds if not math.isnan(w)]
    if not (cpu or wall):
        return mem, None
    seconds = max(margin_cpu * max(cpu, default=0.0), margin_wall * max(wall, default=0.0))
    return mem, max(5, 5 * math.ceil(seconds / 300))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdirs", nargs="*", type=Path, default=[ROOT], help="run directories (default: repo)")
    ap.add_argument("--margin-mem", type=float, default=1.5)
    ap.add_argument("--margin-cpu", type=float, default=5.0)
    ap.add_argument("--margin-wall", type=float, default=2.0)
    args = ap.parse_args(argv)

    rules = parse_rules(ROOT / "workflow" / "rules")
    rules = {k: r for k, r in rules.items() if k not in TARGET_RULES}
    bad = [r.name for r in rules.values() if r.mem_mb is None or r.runtime is None or r.benchmark is None]
    if bad:
        print(f"rule_resources: rules without benchmark/mem_mb/runtime: {', '.join(bad)}", file=sys.stderr)
        return 2
    patterns = [(r, r.pattern()) for r in rules.values()]
    n_files = 0
    for wd in args.workdirs:
        for tsv in sorted((wd / "benchmarks").rglob("*.tsv")):
            rel = tsv.relative_to(wd).as_posix()
            owners = most_specific([r for r, p in patterns if p is not None and p.match(rel)])
            if len(owners) != 1:
                print(f"rule_resources: {tsv}: matches {len(owners)} rules", file=sys.stderr)
                return 2
            s, rss, cpu = read_benchmark(tsv)
            owners[0].seconds.append(s)
            owners[0].rss.append(rss)
            owners[0].cpu.append(cpu)
            n_files += 1

    head = (f"{'rule':<24} {'jobs':>4} {'wall s med':>10} {'wall s max':>10} {'cpu s max':>9} "
            f"{'rss MB max':>10} | {'threads':>7} {'mem_mb':>7} {'runtime':>7} | "
            f"{'policy mem':>10} {'policy min':>10}")
    print(f"{n_files} benchmark files from {', '.join(map(str, args.workdirs))}; policy: mem_mb = "
          f"{args.margin_mem} x peak RSS (250 MB steps, >= 500), runtime = max({args.margin_cpu} x "
          f"CPU s, {args.margin_wall} x wall s) (5 min steps, >= 5)")
    print(head)
    print("-" * len(head))

    def fmt(x: float | None, spec: str) -> str:
        return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)

    for r in sorted(rules.values(), key=lambda r: (r.source, r.name)):
        mem, run = suggest(r, args.margin_mem, args.margin_cpu, args.margin_wall)
        rss = [x for x in r.rss if not math.isnan(x)]
        cpu = [x for x in r.cpu if not math.isnan(x)]
        flag = ""
        if mem is not None and r.mem_mb < mem:
            flag += " UNDER mem"
        if run is not None and r.runtime < run:
            flag += " UNDER runtime"
        if r.seconds and max(r.seconds) > 15:
            flag += " sampled"
        print(
            f"{r.name:<24} {len(r.seconds):>4} "
            f"{fmt(statistics.median(r.seconds) if r.seconds else None, '10.1f')} "
            f"{fmt(max(r.seconds) if r.seconds else None, '10.1f')} "
            f"{fmt(max(cpu) if cpu else None, '9.1f')} "
            f"{fmt(max(rss) if rss else None, '10.0f')} | "
            f"{r.threads:>7} {r.mem_mb:>7.0f} {r.runtime:>7.0f} | {fmt(mem, '>10')} {fmt(run, '>10')}{flag}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
