from crgpr.commands.smk import run_rule
from crgpr.commands.uq import uq_samples

p = snakemake.params
run_rule(snakemake, uq_samples, model_npz=snakemake.input.model, uq=p.uq, seed=p.seed,
         out=snakemake.output.samples, diagnostics=snakemake.output.diagnostics)
