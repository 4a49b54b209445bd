from crgpr.commands.pinn import pinn_rollout
from crgpr.commands.smk import run_rule

run_rule(snakemake, pinn_rollout, cfg=snakemake.params.cfg, variant=snakemake.wildcards.method,
         weights=snakemake.input.weights, ground_truth=snakemake.input.ground_truth,
         angle=int(snakemake.wildcards.angle), out=snakemake.output[0], threads=snakemake.threads)
