from crgpr.commands.smk import run_rule
from crgpr.report import figures as figures_crgpr

i, o = snakemake.input, snakemake.output
run_rule(snakemake, figures_crgpr.rule, cfg=snakemake.config, method=snakemake.wildcards.method,
         angle=float(snakemake.wildcards.angle), gt_train=i.gt_train, gt_test=i.gt_test,
         gt_test_energy=i.gt_test_energy, rollout=i.rollout, rollout_energy=i.rollout_energy,
         overlays_out=o.overlays, shapes_out=o.shapes, energy_out=o.energy)
