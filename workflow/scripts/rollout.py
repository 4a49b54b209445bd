from crgpr.commands.rollout import rollout
from crgpr.commands.smk import run_rule

run_rule(snakemake, rollout, cfg=snakemake.params.cfg, method=snakemake.wildcards.method,
         angle=int(snakemake.wildcards.angle), out=snakemake.output.traj, energy_out=snakemake.output.energy,
         model_json=snakemake.input.models[0])
