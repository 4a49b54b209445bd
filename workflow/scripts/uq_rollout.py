from crgpr import uq
from crgpr.smk import run_rule

run_rule(snakemake, uq.rollout_rule, cfg=snakemake.config, angle=int(snakemake.wildcards.angle),
         samples=list(snakemake.input.samples), models=list(snakemake.input.models), out=snakemake.output[0])
