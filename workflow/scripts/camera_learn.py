from crgpr.commands import camera
from crgpr.commands.smk import run_rule

run_rule(snakemake, camera.camera_learn, cfg=dict(snakemake.params.cfg), measured=snakemake.input.measured,
         out_dir=snakemake.output[0], features=snakemake.wildcards.features,
         prefilter=snakemake.wildcards.prefilter)
