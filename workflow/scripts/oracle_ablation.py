from pathlib import Path

from crgpr.commands import oracle_ablation
from crgpr.commands.smk import run_rule

run_rule(snakemake, oracle_ablation.oracle_ablation,
         cfg={"rod": snakemake.params.rod, "simulation": snakemake.params.simulation},
         theta_closure=snakemake.params.theta_closure, model_dir=str(Path(snakemake.input.models[0]).parent),
         gt_train=snakemake.input.gt_train, gt_tests=list(snakemake.input.gt_tests),
         out_csv=snakemake.output.table, out_pointwise=snakemake.output.pointwise,
         learned_rollouts=list(snakemake.input.learned), out_fig=snakemake.output.figure)
