# One job per (method, cell), all replicates inside; MLflow logging is left to the serial `track` step.
rule identify:
    input:
        "results/{grid}/data/{cell}.npz",
    output:
        "results/{grid}/identify/{method}/{cell}.csv",
    params:
        run_dir="results/{grid}/runs/{method}/{cell}",
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
        "results/{grid}/logs/identify/{method}/{cell}.log",
    benchmark:
        "results/{grid}/benchmarks/identify/{method}/{cell}.tsv"
    shell:
        "python -m experiments.jobs.identify method={wildcards.method} data.dataset={input} out={output}"
        " grid_name={wildcards.grid} tracking.enabled=false hydra.run.dir={params.run_dir}"
        " {params.overrides} > {log} 2>&1"
