from crgpr.commands import materials
from crgpr.commands.smk import run_rule

run_rule(snakemake, materials.material_learn, cfg=snakemake.params.cfg, source=snakemake.wildcards.source,
         measured=snakemake.input.measured, out_dir=snakemake.output[0])
