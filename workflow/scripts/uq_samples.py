from crgpr.commands.smk import run_rule
from crgpr.commands.uq import uq_samples

cfg = snakemake.params.cfg
run_rule(snakemake, uq_samples, model_npz=snakemake.input.model, uq=cfg["uq"], seed=cfg["seed"],
         out=snakemake.output.samples, diagnostics=snakemake.output.diagnostics)
