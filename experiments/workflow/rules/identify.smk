# One job per (grid, method) runs the method on every cell of the grid, all replicates, in one process
# (experiments.jobs.batch: identify's job for each cell; a process per cell spent a third of the job time
# starting up). Its folder is the output: results/<grid>/identify/<method>/<cell>.csv and, beside each table,
# <cell>.json: the cell's resolved config, the dataset's digest and the code version, which is all the runlog
# step reads besides the table. MLflow logging is left to the serial `runlog` step. The batch's cells are
# shared by IDENTIFY_THREADS worker processes (common.smk: 1; `--set-threads identify=N` changes it).
rule identify:
    message:
        "identify: {wildcards.method} on every cell of grid {wildcards.grid} -> {output}"
    input:
        data=dataset_files,
        folder=dataset_folder,
        code=method_code,
    output:
        directory("results/{grid}/identify/{method}"),
    params:
        jobs=identify_jobs,
        method_config=resolved_config,
        versions=method_versions,
    threads: IDENTIFY_THREADS
    # the longest batches first (their last run's benchmark, the cost model, or the committed table of costs):
    # experiments/workflow/resources.py
    priority: identify_priority
    resources:
        mem_mb=MEM_MB_JOB,
        runtime=identify_runtime,
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/identify/{method}.log",
    benchmark:
        "results/{grid}/benchmarks/identify/{method}.tsv"
    shell:
        "python -m experiments.jobs.batch identify {params.jobs} --workers {threads} > {log} 2>&1"
