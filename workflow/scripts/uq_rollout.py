from crgpr.commands.smk import run_rule
from crgpr.uq import ensemble as uq

run_rule(snakemake, uq.rollout_rule, cfg=snakemake.params.cfg, angle=int(snakemake.wildcards.angle),
         samples=list(snakemake.input.samples), models=list(snakemake.input.models), out=snakemake.output[0])
