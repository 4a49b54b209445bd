from crgpr.commands.smk import run_rule
from crgpr.uq import ensemble as uq

run_rule(snakemake, uq.coverage_rule, cfg=snakemake.params.cfg, uq_paths=list(snakemake.input.uq),
         gt_paths=list(snakemake.input.ground_truth), out=snakemake.output.coverage,
         table=snakemake.output.table)
