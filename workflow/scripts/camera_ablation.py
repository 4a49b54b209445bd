from crgpr.commands import camera
from crgpr.commands.smk import run_rule

run_rule(snakemake, camera.camera_ablation, cells=list(snakemake.input.cells),
         noise_mm=list(snakemake.params.noise_mm), prefilters=list(snakemake.params.prefilters),
         features=list(snakemake.params.features), out_csv=snakemake.output.table,
         out_fig=snakemake.output.figure)
