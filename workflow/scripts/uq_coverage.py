from crgpr.commands.smk import run_rule
from crgpr.commands.uq import uq_coverage

i, o = snakemake.input, snakemake.output
run_rule(snakemake, uq_coverage, uq_paths=list(i.uq), ground_truth=list(i.ground_truth),
         mean_models=list(i.mean_models), uq=snakemake.params.cfg["uq"], out=o.coverage, table=o.table)
