from crgpr.commands import materials
from crgpr.commands.smk import run_rule

run_rule(snakemake, materials.material_data, cfg=snakemake.params.cfg, case=snakemake.wildcards.case,
         train_out=snakemake.output.train, camera_out=snakemake.output.camera, test_out=snakemake.output.test)
