from crgpr.commands.smk import run_rule
from crgpr.discovery import selection as discovery

run_rule(snakemake, discovery.rule_data, cfg=snakemake.config, case=snakemake.wildcards.case,
         out=snakemake.output.measured, truth_out=snakemake.output.truth)
