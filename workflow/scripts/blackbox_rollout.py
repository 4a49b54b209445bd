from crgpr.baselines import blackbox
from crgpr.commands.smk import run_rule

run_rule(snakemake, blackbox.rule_rollout, cfg=snakemake.config, model_dir=snakemake.input.models,
         summary=snakemake.input.summary, angle=int(snakemake.wildcards.angle), out=snakemake.output[0])
