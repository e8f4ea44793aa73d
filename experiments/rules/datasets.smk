# One job per grid simulates every cell (experiments.jobs.batch: make_dataset's job for each cell, in one
# process). The folder is the output: a failed or interrupted job leaves nothing behind.
rule datasets:
    message:
        "datasets: every cell of grid {wildcards.grid} -> {output}"
    output:
        directory("results/{grid}/data"),
    params:
        jobs=dataset_jobs,
    threads: 1
    resources:
        mem_mb=MEM_MB_JOB,
        runtime=dataset_runtime,
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/datasets.log",
    benchmark:
        "results/{grid}/benchmarks/datasets.tsv"
    shell:
        "python -m experiments.jobs.batch dataset {params.jobs} > {log} 2>&1"
