#!/usr/bin/env bash
# The UQ speed target: the whole UQ stage (every uq.methods entry, the six test angles, the
# default S) timed on its own, from the models and mean rollouts of a complete run.
#
#   bash benchmarks/uq_stage.sh WORKDIR [CONFIG]
#
# WORKDIR holds a complete `snakemake all` run (results/...). The mean rollouts of the UQ methods
# and everything upstream of them are marked current (`--touch`: the run may predate the
# checked-out code), then every UQ rule is forced (samples, rollouts, coverage, calibration,
# figures) at -j2. Prints the wall time and each UQ job's Snakemake benchmark (s, cpu_time); the
# WORKDIR's UQ outputs are regenerated in place.
set -euo pipefail
work=$(realpath "$1")
repo=$(cd "$(dirname "$0")/.." && pwd)
cfg=$(realpath "${2:-$repo/config.yaml}")
smk=(snakemake --snakefile "$repo/Snakefile" --configfile "$cfg" -d "$work")
lists=$(python -c '
import sys, yaml
u = yaml.safe_load(open(sys.argv[1]))["uq"]
out = ["results/tables/uq_coverage.csv", "results/tables/uq_function_calibration.csv",
       "results/figures/uq_reliability.png"]
a = u["figure_angle_deg"]
out += [f"results/figures/uq_band_{m}_{a}.png" for m in u["methods"]]
up = [f"results/rollouts/{m}/{a}.parquet" for m in u["methods"] for a in u["angles_deg"]]
print(" ".join(out) + ";" + " ".join(up))' "$cfg")
targets=${lists%%;*}
upstream=${lists#*;}
uq_rules=(uq_samples uq_samples_learned uq_rollout uq_rollout_learned uq_coverage uq_calibration uq_figure
          uq_reliability)
"${smk[@]}" -j1 --touch $upstream >/dev/null 2>&1
rm -rf "$work/benchmarks/uq"
start=$(date +%s)
"${smk[@]}" -j2 $targets --forcerun "${uq_rules[@]}" >"$work/uq_stage.log" 2>&1
echo "UQ stage: $(( $(date +%s) - start )) s wall at -j2 (log: $work/uq_stage.log)"
cd "$work"
for f in $(find benchmarks/uq -name '*.tsv' | sort); do
    printf '%-62s %s\n' "$f" "$(awk 'NR==2 {print $1 " s wall, cpu " $NF " s"}' "$f")"
done
