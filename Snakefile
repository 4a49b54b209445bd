"""crgpr: reproduce CR-GPR (Cosserat rod + Gaussian processes) end to end.

    snakemake -j2 all                     # the paper, with config.yaml
    snakemake -j2 all --configfile tests/smoke_config.yaml    # tiny smoke run
    snakemake -j2 sweeps                  # studies beyond the budget of `all`

Rules live in workflow/rules/<stage>.smk, one file per pipeline stage; rule X runs
workflow/scripts/X.py, which calls crgpr.commands.<stage>.X. Each rule declares the config
values its output depends on as params (a change reruns it and its dependants) and the
library files its script imports as inputs (an edit reruns it); see ARCHITECTURE.md.
"""

from snakemake.utils import min_version, validate

min_version("9.0")


configfile: "config.yaml"


validate(config, "src/crgpr/schemas/config.schema.yaml")

from crgpr.config import check_config_files, validate_config  # noqa: E402

check_config_files(["config.yaml", *workflow.overwrite_configfiles])  # a key given twice is an error

validate_config(config, "config")  # also what the schema cannot say: whole-number integers, physics

include: "workflow/rules/common.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/blackbox.smk"
include: "workflow/rules/pinn.smk"
include: "workflow/rules/prefilter.smk"
include: "workflow/rules/models.smk"
include: "workflow/rules/rollout.smk"
include: "workflow/rules/camera.smk"
include: "workflow/rules/ports.smk"
include: "workflow/rules/materials.smk"
include: "workflow/rules/control.smk"
include: "workflow/rules/uq.smk"
include: "workflow/rules/discovery.smk"
include: "workflow/rules/report.smk"
include: "workflow/rules/oracle.smk"
include: "workflow/rules/variant_paths.smk"
include: "workflow/rules/variants.smk"


rule all:
    default_target: True
    input:
        ALL_TARGETS,


# Studies beyond the budget of `all` (the oracle ablation, cr_gpr_paper_hyp and cr_gpr_collocated in
# accuracy_studies.parquet, the CR-GPR sensitivity table, the camera noise ablation, the materials
# study's camera records learned with crgpr learn's own settings): `snakemake -j2 sweeps`.
rule sweeps:
    input:
        SWEEP_TARGETS,
