from crgpr import uq
from crgpr.smk import run_rule

run_rule(snakemake, uq.samples_rule, cfg=snakemake.config, models=list(snakemake.input.models),
         samples=list(snakemake.output.samples), diagnostics=snakemake.output.diagnostics)
