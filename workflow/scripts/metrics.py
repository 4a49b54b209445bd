from crgpr.commands.report import metrics
from crgpr.commands.smk import run_rule

i, o = snakemake.input, snakemake.output
run_rule(snakemake, metrics, cfg=snakemake.params.cfg, methods=list(snakemake.params.methods),
         angles=list(snakemake.params.angles), ground_truth=list(i.gt), rollouts=list(i.rollouts),
         out=o.accuracy, table1_out=o.table1, table4_out=o.table4)
