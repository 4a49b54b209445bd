from crgpr.commands import camera
from crgpr.commands.smk import run_rule

run_rule(snakemake, camera.camera_data, gt=snakemake.input.gt, out=snakemake.output[0],
         noise_mm=float(snakemake.wildcards.noise), sample_rate_hz=float(snakemake.params.sample_rate_hz),
         seed=int(snakemake.params.seed))
