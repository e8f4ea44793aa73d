# One job per grid simulates every cell (experiments.jobs.batch: make_dataset's job for each cell, in one
# process). Its outputs are the cells' files, results/<grid>/data/<cell>.npz, each named, so that a file
# deleted after a run is a missing output Snakemake can remake (a folder as the output hid it: "Nothing to be
# done"). Snakemake remakes a missing file only for a job that must run, so the identify batches also read
# the folder, whose modification time the deletion changes (common.smk, dataset_folder): they rerun, the
# batch first. A rule's outputs cannot depend on its wildcards, so each grid gets its own rule,
# datasets_<grid>, written from the grid's cells when the workflow is read (every grid: ~0.3 s; a grid that
# does not load gets no rule, and is refused in one line when a target asks for it). Each file is written
# atomically; Snakemake removes the outputs of a failed job.
for _grid_name in GRID_NAMES:
    try:
        _cells = WF.cells(_grid_name)
    except GridError:
        continue

    rule:
        name:
            f"datasets_{_grid_name}"
        message:
            f"datasets: every cell of grid {_grid_name} -> results/{_grid_name}/data"
        output:
            [f"results/{_grid_name}/data/{c}.npz" for c in _cells],
        params:
            jobs=shlex.quote(json.dumps(targets.dataset_jobs(WF, _grid_name))),
        threads: 1
        priority: DATASETS_PRIORITY
        resources:
            mem_mb=MEM_MB_JOB,
            runtime=dataset_runtime(_grid_name),
        conda:
            CONDA_ENV
        log:
            f"results/{_grid_name}/logs/datasets.log",
        benchmark:
            f"results/{_grid_name}/benchmarks/datasets.tsv"
        shell:
            "python -m experiments.jobs.batch dataset {params.jobs} > {log} 2>&1"
