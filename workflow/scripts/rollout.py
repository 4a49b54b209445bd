from crgpr.commands.rollout import rollout
from crgpr.commands.smk import run_rule

out = snakemake.output  # noqa: F821
run_rule(snakemake, rollout, cfg=snakemake.params.cfg, method=snakemake.wildcards.method,  # noqa: F821
         angles=[int(a) for a in snakemake.params.angles], outs=list(out.traj),  # noqa: F821
         energy_outs=list(out.energy), model_json=snakemake.input.models[0])  # noqa: F821
