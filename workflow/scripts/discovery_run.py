from crgpr import discovery
from crgpr.smk import run_rule

run_rule(snakemake, discovery.rule_discover, cfg=snakemake.config, measured=snakemake.input.measured,
         out=snakemake.output.json)
