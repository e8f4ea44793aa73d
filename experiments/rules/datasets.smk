rule dataset:
    output:
        "results/{grid}/data/noise{noise}ug_n{n}.npz",
    params:
        grid=lambda wc: GRIDS[wc.grid],
    threads: 1
    resources:
        mem_mb=MEM_MB_JOB,
        runtime=5,
    group:
        "cells"
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/dataset/noise{noise}ug_n{n}.log",
    shell:
        "python -m experiments.jobs.make_dataset noise_ug={wildcards.noise} n_samples={wildcards.n}"
        " replicates={params.grid[replicates]} seed={params.grid[seed]} dt_s={params.grid[dt_s]}"
        " bias_m_s2={params.grid[bias_m_s2]} out={output} > {log} 2>&1"
