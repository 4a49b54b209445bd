from crgpr.commands import camera
from crgpr.commands.smk import run_rule

out = snakemake.output
run_rule(snakemake, camera.camera_rollout, cfg=dict(snakemake.params.cfg), model_dir=snakemake.input.models,
         angles=[int(a) for a in snakemake.params.angles], outs=list(out.traj),
         energy_outs=list(out.energy))
