from crgpr.commands.rollout import rollout
from crgpr.commands.smk import run_rule


def _files(x):
    return [x] if isinstance(x, str) else list(x)  # one angle (variant_rollout) or all (rollout)


out = snakemake.output  # noqa: F821
run_rule(snakemake, rollout, cfg=snakemake.params.cfg, method=snakemake.wildcards.method,  # noqa: F821
         angles=[int(a) for a in snakemake.params.angles], outs=_files(out.traj),  # noqa: F821
         energy_outs=_files(out.energy), model_json=snakemake.input.models[0])  # noqa: F821
