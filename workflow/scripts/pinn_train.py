from crgpr.commands.pinn import pinn_train
from crgpr.commands.smk import run_rule

o = snakemake.output
run_rule(snakemake, pinn_train, cfg=snakemake.params.cfg, variant=snakemake.wildcards.variant,
         data=dict(zip(snakemake.params.angles, snakemake.input.data, strict=True)),
         weights_out=o.weights, history_out=o.history, threads=snakemake.threads)
