from crgpr.commands.smk import run_rule
from crgpr.commands.uq import uq_samples_learned

cfg = snakemake.params.cfg  # noqa: F821
run_rule(snakemake, uq_samples_learned, model_dir=snakemake.input.models, uq=cfg["uq"], seed=cfg["seed"],  # noqa: F821
         out_dir=snakemake.output[0])  # noqa: F821
