from crgpr import discovery
from crgpr.smk import run_rule

run_rule(snakemake, discovery.rule_data, cfg=snakemake.config, case=snakemake.wildcards.case,
         out=snakemake.output.measured, truth_out=snakemake.output.truth)
