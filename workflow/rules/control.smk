# Control on the learned model (docs/control.md, beyond the paper): a controller designed on the
# actuated study's learned model (feedforward by energy shaping plus tip feedback), run as a digital
# controller on the ground-truth and a finer-grid simulator, against the same controller designed on
# the nominal model with E off and plain PD (results/tables/control.csv, in `all`).

CONTROL_MODEL = config["control"]["study"]["model"]


rule control_study:
    input:
        code=code_closure("control_study.py"),
        models=f"{RESULTS}/actuated/models/{CONTROL_MODEL}",
    output:
        table=f"{RESULTS}/tables/control.csv",
        figure=f"{RESULTS}/figures/control.png",
    params:
        cfg=cfg_params("seed", "rod", "simulation.dt_s", "simulation.scheme", "ports.tendon_offset_m", "control",
                       "uq"),
    log:
        "logs/control/study.log",
    benchmark:
        "benchmarks/control/study.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/control_study.py"


ALL_TARGETS.extend([f"{RESULTS}/tables/control.csv", f"{RESULTS}/figures/control.png"])
