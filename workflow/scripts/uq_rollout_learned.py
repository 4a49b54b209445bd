from crgpr.commands.smk import run_rule
from crgpr.commands.uq import uq_rollout_learned

p = snakemake.params  # noqa: F821
run_rule(snakemake, uq_rollout_learned, samples_dir=snakemake.input.samples, model_dir=snakemake.input.models,  # noqa: F821
         method=snakemake.wildcards.method, angles=[int(a) for a in p.angles],  # noqa: F821
         simulation=p.cfg["simulation"], uq=p.cfg["uq"], outs=list(snakemake.output))  # noqa: F821
