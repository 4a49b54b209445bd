from crgpr.commands import materials
from crgpr.commands.smk import run_rule

run_rule(snakemake, materials.material_score, cfg=snakemake.params.cfg, case=snakemake.wildcards.case,
         source=snakemake.wildcards.source, model_dir=snakemake.input.model, train=snakemake.input.train,
         test=snakemake.input.test, out=snakemake.output.scores, tips_out=snakemake.output.tips)
