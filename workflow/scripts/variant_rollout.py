from crgpr.commands.smk import run_rule
from crgpr.commands.variants import variant_rollout

run_rule(snakemake, variant_rollout, cfg=snakemake.params.cfg, method=snakemake.wildcards.method,
         angle=int(snakemake.wildcards.angle), out=snakemake.output.traj, energy_out=snakemake.output.energy,
         model_json=snakemake.input.models[0])
