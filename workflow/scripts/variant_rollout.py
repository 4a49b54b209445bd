from crgpr.commands.rollout import variant_rollout
from crgpr.commands.smk import run_rule

run_rule(snakemake, variant_rollout, cfg=snakemake.params.cfg, method=snakemake.wildcards.method,  # noqa: F821
         angle=int(snakemake.wildcards.angle), out=snakemake.output.traj,  # noqa: F821
         energy_out=snakemake.output.energy, model_json=snakemake.input.models[0])  # noqa: F821
