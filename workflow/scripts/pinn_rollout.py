from crgpr.commands.pinn import pinn_rollout
from crgpr.commands.smk import run_rule

run_rule(snakemake, pinn_rollout, cfg=snakemake.params.cfg, variant=snakemake.wildcards.method,
         weights=snakemake.input.weights, ground_truths=list(snakemake.input.ground_truths),
         angles=[int(a) for a in snakemake.params.angles], outs=list(snakemake.output),
         threads=snakemake.threads)
