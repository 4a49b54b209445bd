from crgpr.commands.prefilter import prefilter
from crgpr.commands.smk import run_rule

run_rule(snakemake, prefilter, cfg=snakemake.params.cfg, method=snakemake.wildcards.method,
         angle=int(snakemake.wildcards.angle), gt=snakemake.input.gt, out=snakemake.output[0])
