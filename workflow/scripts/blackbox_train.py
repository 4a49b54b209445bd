from crgpr.baselines import blackbox
from crgpr.commands.smk import run_rule

run_rule(snakemake, blackbox.rule_train, cfg=snakemake.config, prefiltered=snakemake.input.prefiltered,
         out_dir=snakemake.output.models, summary=snakemake.output.summary)
