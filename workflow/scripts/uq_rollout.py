from crgpr.commands.smk import run_rule
from crgpr.commands.uq import uq_rollout

p = snakemake.params  # noqa: F821
run_rule(snakemake, uq_rollout, samples=list(snakemake.input.samples), models=list(snakemake.input.models),  # noqa: F821
         method=snakemake.wildcards.method, method_cfg=p.method_cfg, angles=[int(a) for a in p.angles],  # noqa: F821
         rod=p.cfg["rod"], simulation=p.cfg["simulation"], uq=p.cfg["uq"], outs=list(snakemake.output))  # noqa: F821
