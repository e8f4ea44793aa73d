# One job per (method, cell), all replicates inside; MLflow logging is left to the serial `track` step.
rule identify:
    input:
        "results/{grid}/data/noise{noise}ug_n{n}.npz",
    output:
        "results/{grid}/identify/{method}/noise{noise}ug_n{n}.csv",
    params:
        run_dir="results/{grid}/runs/{method}/noise{noise}ug_n{n}",
        overrides=method_overrides,
    threads: 1
    resources:
        mem_mb=MEM_MB_JOB,
        runtime=identify_runtime,
    group:
        "cells"
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/identify/{method}/noise{noise}ug_n{n}.log",
    benchmark:
        "results/{grid}/benchmarks/identify/{method}/noise{noise}ug_n{n}.tsv"
    shell:
        "python -m experiments.jobs.identify method={wildcards.method} data.dataset={input} out={output}"
        " grid_name={wildcards.grid} tracking.enabled=false hydra.run.dir={params.run_dir}"
        " {params.overrides} > {log} 2>&1"
