from crgpr.commands.smk import run_rule
from crgpr.report import metrics

run_rule(snakemake, metrics.rule_accuracy, cfg=snakemake.config, methods=list(snakemake.params.methods),
         angles=list(snakemake.config["angles"]["test_deg"]), results="results",
         out=snakemake.output.accuracy, table1_out=snakemake.output.table1,
         table4_out=snakemake.output.table4)
