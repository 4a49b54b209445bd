from crgpr.commands.smk import run_rule
from crgpr.uq import ensemble as uq

run_rule(snakemake, uq.calibration_rule, cfg=snakemake.params.cfg, models=list(snakemake.input.models),
         gt_paths=list(snakemake.input.ground_truth), out=snakemake.output[0])
