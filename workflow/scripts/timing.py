from crgpr import timing
from crgpr.smk import run_rule

run_rule(snakemake, timing.rule, stage_files=snakemake.params.stage_files, out=snakemake.output[0])
