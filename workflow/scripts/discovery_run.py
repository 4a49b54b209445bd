from crgpr.commands.smk import run_rule
from crgpr.discovery import selection as discovery

run_rule(snakemake, discovery.rule_discover, cfg=snakemake.config, measured=snakemake.input.measured,
         out=snakemake.output.json)
