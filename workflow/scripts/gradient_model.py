from crgpr import gradient_models
from crgpr.smk import run_rule

run_rule(snakemake, gradient_models.rule, cfg=snakemake.config, model=snakemake.wildcards.model,
         prefilter_method=snakemake.wildcards.prefilter, prefiltered=snakemake.input.prefiltered,
         out_npz=snakemake.output.npz)
