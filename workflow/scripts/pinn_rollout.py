from crgpr.baselines import pinn
from crgpr.commands.smk import run_rule

run_rule(snakemake, pinn.rule_predict, cfg=snakemake.config, variant=snakemake.wildcards.method,
         weights=snakemake.input.weights, ground_truth=snakemake.input.ground_truth,
         angle=int(snakemake.wildcards.angle), out=snakemake.output[0], threads=snakemake.threads)
