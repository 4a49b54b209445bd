from crgpr.commands import camera
from crgpr.commands.smk import run_rule

run_rule(snakemake, camera.camera_ablation_cell, cfg=dict(snakemake.params.cfg),
         model_dir=snakemake.input.models, gts=list(snakemake.input.gts),
         angles=list(snakemake.params.angles), t_end=float(snakemake.params.t_end), out=snakemake.output[0])
