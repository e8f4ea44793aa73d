rule dataset:
    output:
        "results/{grid}/data/{cell}.npz",
    params:
        args=dataset_args,
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/dataset/{cell}.log",
    shell:
        "python -m experiments.jobs.make_dataset {params.args} out={output} > {log} 2>&1"
