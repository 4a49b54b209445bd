from crgpr.commands.smk import run_rule
from crgpr.uq import ensemble as uq

run_rule(snakemake, uq.figure_rule, cfg=snakemake.params.cfg, uq_path=snakemake.input.uq,
         gt_path=snakemake.input.ground_truth, out=snakemake.output[0], mean_path=snakemake.input.mean_model)
