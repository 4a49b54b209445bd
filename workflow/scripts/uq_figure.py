from crgpr.commands.smk import run_rule
from crgpr.commands.uq import uq_figure

run_rule(snakemake, uq_figure, uq_path=snakemake.input.uq, ground_truth=snakemake.input.ground_truth,
         mean_model=snakemake.input.mean_model, uq=snakemake.params.cfg["uq"], out=snakemake.output[0])
