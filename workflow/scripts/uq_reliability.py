from crgpr.commands.smk import run_rule
from crgpr.commands.uq import uq_reliability

run_rule(snakemake, uq_reliability, coverage=snakemake.input.coverage, out=snakemake.output[0])
