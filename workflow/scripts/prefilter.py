from crgpr import prefilter
from crgpr.smk import run_rule

run_rule(snakemake, prefilter.rule, cfg=snakemake.config, method=snakemake.wildcards.method,
         angle=int(snakemake.wildcards.angle), gt=snakemake.input.gt, out=snakemake.output[0])
