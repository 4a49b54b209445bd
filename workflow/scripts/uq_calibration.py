from crgpr.commands.smk import run_rule
from crgpr.commands.uq import uq_calibration

run_rule(snakemake, uq_calibration, models=list(snakemake.input.models),
         ground_truth=list(snakemake.input.ground_truth), rod=snakemake.params.cfg["rod"],
         out=snakemake.output[0])
