# Missing-physics workflow (issue 6, beyond the paper): hidden-effect camera data, discovery per
# case, summary table and figure. The truth files live in their own folder, which the
# discovery rule never reads.

DISCOVERY_CASES = [c["name"] for c in config["discovery"]["cases"]]
DISCOVERY_CODE = ("config", "rod", "integrator", "simulate", "effects", "measured", "discovery", "smk")


rule discovery_data:
    input:
        code=lib(*DISCOVERY_CODE),
    output:
        measured=f"{RESULTS}/discovery/{{case}}/measured.parquet",
        truth=f"{RESULTS}/discovery_truth/{{case}}.json",
    wildcard_constraints:
        case=r"[A-Za-z0-9_]+",
    log:
        "logs/discovery/data_{case}.log",
    benchmark:
        "benchmarks/discovery/data_{case}.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/discovery_data.py"


rule discovery_run:
    input:
        measured=f"{RESULTS}/discovery/{{case}}/measured.parquet",
        code=lib(*DISCOVERY_CODE, "gp"),
    output:
        json=f"{RESULTS}/discovery/{{case}}/discovery.json",
        report=f"{RESULTS}/discovery/{{case}}/report.md",
        figures=multiext(f"{RESULTS}/discovery/{{case}}/", "heatmap.png", "before_after.png", "residual.png"),
    wildcard_constraints:
        case=r"[A-Za-z0-9_]+",
    log:
        "logs/discovery/run_{case}.log",
    benchmark:
        "benchmarks/discovery/run_{case}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/discovery_run.py"


rule discovery_summary:
    input:
        truth=expand(f"{RESULTS}/discovery_truth/{{case}}.json", case=DISCOVERY_CASES),
        results=expand(f"{RESULTS}/discovery/{{case}}/discovery.json", case=DISCOVERY_CASES),
        code=lib(*DISCOVERY_CODE),
    output:
        table=report(
            f"{RESULTS}/tables/discovery.csv",
            caption="../report/discovery_table.rst",
            category="Missing physics",
        ),
        figure=report(
            f"{RESULTS}/figures/discovery_gap.png",
            caption="../report/discovery_figure.rst",
            category="Missing physics",
        ),
    params:
        cases=DISCOVERY_CASES,
    log:
        "logs/discovery/summary.log",
    benchmark:
        "benchmarks/discovery/summary.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/discovery_summary.py"


ALL_TARGETS.extend([f"{RESULTS}/tables/discovery.csv", f"{RESULTS}/figures/discovery_gap.png"])
