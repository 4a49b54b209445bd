from crgpr.commands.blackbox import blackbox_rollout
from crgpr.commands.smk import run_rule

run_rule(snakemake, blackbox_rollout, cfg=snakemake.params.cfg, model_dir=snakemake.input.models,
         summary=snakemake.input.summary, angles=[int(a) for a in snakemake.params.angles],
         outs=list(snakemake.output))
