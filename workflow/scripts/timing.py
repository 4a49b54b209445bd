from crgpr.commands.smk import run_rule
from crgpr.report import timing

run_rule(snakemake, timing.rule, stage_files=snakemake.params.stage_files, out=snakemake.output[0])
