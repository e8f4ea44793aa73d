rule dataset:
    output:
        "results/{grid}/data/{cell}.npz",
    params:
        args=dataset_args,
    threads: 1
    resources:
        mem_mb=MEM_MB_JOB,
        runtime=5,
    group:
        "cells"
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/dataset/{cell}.log",
    shell:
        "python -m experiments.jobs.make_dataset {params.args} out={output} > {log} 2>&1"
