from crgpr.commands.smk import run_rule
from crgpr.learning import gradient_models

run_rule(snakemake, gradient_models.rule, cfg=snakemake.config, model=snakemake.wildcards.model,
         prefilter_method=snakemake.wildcards.prefilter, prefiltered=snakemake.input.prefiltered,
         out_npz=snakemake.output.npz)
