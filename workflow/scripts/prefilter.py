from crgpr.commands.smk import run_rule
from crgpr.learning import prefilter

run_rule(snakemake, prefilter.rule, cfg=snakemake.config, method=snakemake.wildcards.method,
         angle=int(snakemake.wildcards.angle), gt=snakemake.input.gt, out=snakemake.output[0])
