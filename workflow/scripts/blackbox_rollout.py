from crgpr.commands.blackbox import blackbox_rollout
from crgpr.commands.smk import run_rule

run_rule(snakemake, blackbox_rollout, cfg=snakemake.params.cfg, model_dir=snakemake.input.models,
         summary=snakemake.input.summary, angle=int(snakemake.wildcards.angle), out=snakemake.output[0])
