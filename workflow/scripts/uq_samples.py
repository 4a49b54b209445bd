from crgpr.commands.smk import run_rule
from crgpr.uq import ensemble as uq

run_rule(snakemake, uq.samples_rule, cfg=snakemake.params.cfg, models=list(snakemake.input.models),
         samples=list(snakemake.output.samples), diagnostics=snakemake.output.diagnostics)
