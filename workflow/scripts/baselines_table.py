from crgpr.commands.report import baselines_table
from crgpr.commands.smk import run_rule

n = len(snakemake.params.cfg["angles"]["test_deg"])
files = list(snakemake.input.rollouts)
run_rule(snakemake, baselines_table, cfg=snakemake.params.cfg, accuracy=snakemake.input.accuracy,
         rollouts={m: files[i * n:(i + 1) * n] for i, m in enumerate(snakemake.params.methods)},
         ground_truth=list(snakemake.input.ground_truth),
         pinn_histories=dict(zip(snakemake.params.variants, snakemake.input.histories, strict=True)),
         table=snakemake.output.table, notes=snakemake.output.notes, figure=snakemake.output.figure)
