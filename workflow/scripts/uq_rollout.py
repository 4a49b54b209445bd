from crgpr.commands.smk import run_rule
from crgpr.commands.uq import uq_rollout

p = snakemake.params
run_rule(snakemake, uq_rollout, samples=list(snakemake.input.samples), models=list(snakemake.input.models),
         method=snakemake.wildcards.method, method_cfg=p.method_cfg, angle=int(snakemake.wildcards.angle),
         rod=p.cfg["rod"], simulation=p.cfg["simulation"], uq=p.cfg["uq"], out=snakemake.output[0])
