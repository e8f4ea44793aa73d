# One job per (method, cell), all replicates inside; MLflow logging is left to the serial `track` step.
# Beside the table the job writes <cell>.json: its resolved config, the dataset's digest and the code
# version, which is all the track step reads besides the table.
rule identify:
    input:
        data="results/{grid}/data/{cell}.npz",
        code=method_code,
    output:
        table="results/{grid}/identify/{method}/{cell}.csv",
        provenance="results/{grid}/identify/{method}/{cell}.json",
    params:
        run_dir="results/{grid}/runs/{method}/{cell}",
        overrides=method_overrides,
        method_config=resolved_config,
        versions=method_versions,
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
        "python -m experiments.jobs.identify method={wildcards.method} data.dataset={input.data}"
        " out={output.table} grid_name={wildcards.grid} tracking.enabled=false hydra.run.dir={params.run_dir}"
        " {params.overrides} > {log} 2>&1"
