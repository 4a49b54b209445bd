from crgpr.commands.report import timing
from crgpr.commands.smk import run_rule

run_rule(snakemake, timing, stage_files=snakemake.params.stage_files, out=snakemake.output[0])
