from crgpr.commands import camera
from crgpr.commands.smk import run_rule

run_rule(snakemake, camera.camera_rollout, cfg=dict(snakemake.params.cfg), model_dir=snakemake.input.models,
         angle=int(snakemake.wildcards.angle), out=snakemake.output.traj, energy_out=snakemake.output.energy)
