"""Measured runtime and memory per rule next to the resources each rule declares.

    python benchmarks/rule_resources.py [WORKDIR ...] [--margin-mem 1.5] [--margin-time 3]

Reads the Snakemake ``benchmark:`` files (``WORKDIR/benchmarks/**/*.tsv``, columns ``s`` =
wall seconds and ``max_rss`` = peak resident memory of the job's process tree in MB) of one or
more runs, maps each file to its rule through the rule's ``benchmark:`` pattern in
``workflow/rules/*.smk``, and prints per rule: jobs measured, wall time (median / max),
peak RSS (max), the declared ``threads``, ``mem_mb`` and ``runtime`` (minutes), and the value
the margins would give (mem: margin x peak RSS rounded up to 250 MB, at least 500 MB; runtime:
margin x the longest job rounded up to whole minutes, at least 2 min). Rules whose measured
peak exceeds what they declare are marked ``OVER``. Exit code 2 if a benchmark file matches no
rule or a rule's resources cannot be read.
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
                        seconds=[], rss=[])
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


def read_benchmark(path: Path) -> tuple[float, float]:
    """(wall seconds, peak RSS MB) of one benchmark file (last row if repeated); NaN if absent."""
    lines = path.read_text().splitlines()
    header, row = lines[0].split("\t"), lines[-1].split("\t")
    values = dict(zip(header, row, strict=False))

    def number(key: str) -> float:
        try:
            return float(values.get(key, "nan"))
        except ValueError:  # "NA" when the job ended before the first memory sample
            return math.nan

    return number("s"), number("max_rss")


def suggest(rule: Rule, margin_mem: float, margin_time: float) -> tuple[int | None, int | None]:
    rss = [r for r in rule.rss if not math.isnan(r)]
    mem = max(500, 250 * math.ceil(margin_mem * max(rss) / 250)) if rss else None
    run = max(2, math.ceil(margin_time * max(rule.seconds) / 60)) if rule.seconds else None
    return mem, run


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdirs", nargs="*", type=Path, default=[ROOT], help="run directories (default: repo)")
    ap.add_argument("--margin-mem", type=float, default=1.5)
    ap.add_argument("--margin-time", type=float, default=3.0)
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
            owners = [r for r, p in patterns if p is not None and p.match(rel)]
            if len(owners) != 1:
                print(f"rule_resources: {tsv}: matches {len(owners)} rules", file=sys.stderr)
                return 2
            s, rss = read_benchmark(tsv)
            owners[0].seconds.append(s)
            owners[0].rss.append(rss)
            n_files += 1

    head = (f"{'rule':<20} {'jobs':>4} {'wall s med':>10} {'wall s max':>10} {'rss MB max':>10} | "
            f"{'threads':>7} {'mem_mb':>7} {'runtime':>7} | {'sugg mem':>8} {'sugg min':>8}")
    print(f"{n_files} benchmark files from {', '.join(map(str, args.workdirs))}; "
          f"suggestion = {args.margin_mem} x peak RSS, {args.margin_time} x longest wall time")
    print(head)
    print("-" * len(head))
    for r in sorted(rules.values(), key=lambda r: (r.source, r.name)):
        mem, run = suggest(r, args.margin_mem, args.margin_time)
        rss = [x for x in r.rss if not math.isnan(x)]
        flag = ""
        if rss and max(rss) > r.mem_mb:
            flag += " OVER mem"
        if r.seconds and max(r.seconds) > 60 * r.runtime:
            flag += " OVER runtime"

        def fmt(x: float | None, spec: str) -> str:
            return "-" if x is None else format(x, spec)

        print(
            f"{r.name:<20} {len(r.seconds):>4} "
            f"{fmt(statistics.median(r.seconds) if r.seconds else None, '10.1f')} "
            f"{fmt(max(r.seconds) if r.seconds else None, '10.1f')} "
            f"{fmt(max(rss) if rss else None, '10.0f')} | "
            f"{r.threads:>7} {r.mem_mb:>7.0f} {r.runtime:>7.0f} | {fmt(mem, '>8')} {fmt(run, '>8')}{flag}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
