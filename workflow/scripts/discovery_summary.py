from crgpr.commands.smk import run_rule
from crgpr.discovery import selection as discovery

run_rule(snakemake, discovery.rule_summary, cfg=snakemake.config, cases=list(snakemake.params.cases),
         truths=list(snakemake.input.truth), results=list(snakemake.input.results),
         out_csv=snakemake.output.table, out_fig=snakemake.output.figure)
