from crgpr.baselines import pinn
from crgpr.commands.smk import run_rule

angles = pinn.variant_angles(snakemake.config, snakemake.wildcards.variant)
run_rule(snakemake, pinn.rule_train, cfg=snakemake.config, variant=snakemake.wildcards.variant,
         data=dict(zip(angles, snakemake.input.data, strict=True)), weights_out=snakemake.output.weights,
         history_out=snakemake.output.history, threads=snakemake.threads)
