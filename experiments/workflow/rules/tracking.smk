# The tracking grids (configs/grid/tracking*.yaml, docs/tracking.md): the records of every cell in one job,
# one job per tracker over every cell, then the report beside the MLflow runs of the (tracker, cell) jobs
# (tracking_runlog_jobs), and the grid's run and page (tracking_runlog; both local), as for the identification
# grids. Every step is a command a user can type:
#   python -m experiments.jobs.track_job data tracking --out results/tracking/data
#   python -m experiments.jobs.track_job run tracking --tracker akf --data results/tracking/data --out ...
#   python -m experiments.report.tracking_report ... ;  python -m experiments.runlog.tracker_runs ...
from experiments.workflow.tracking import (TRACKING_GRIDS, check_requested_tracking_grids, tracker_dirs,
                                               tracking_priority, tracking_runtime)

check_requested_tracking_grids(sys.argv[1:])
# The tracking grids' names as a wildcard constraint; with no tracking grid at all it matches nothing (an
# empty constraint would match every grid, and tracking_data would then compete with datasets).
TRACKING_GRID_RE = "|".join(TRACKING_GRIDS) or "(?!)"


localrules:
    tracking,
    tracking_report,
    tracking_runlog_jobs,
    tracking_runlog,


rule tracking:
    input:
        "results/tracking/README.md",
        "results/tracking/mlflow_runs.json",


# The records of every cell in one job on up to TRACKING_DATA_THREADS processes (Snakemake gives it at most
# --cores; `--set-threads tracking_data=N` sets it per run): every other job waits for it, so it may take the
# cores. The tracking grid's 24 cells took 52 s on one core (2026-11-26).
TRACKING_DATA_THREADS = 4


rule tracking_data:
    output:
        directory("results/{tgrid}/data"),
    wildcard_constraints:
        tgrid=TRACKING_GRID_RE,
    threads: TRACKING_DATA_THREADS
    resources:
        mem_mb=MEM_MB_JOB,
        runtime=lambda wc, attempt: attempt * 10,
    conda:
        CONDA_ENV
    log:
        "results/{tgrid}/logs/data.log",
    benchmark:
        "results/{tgrid}/benchmarks/data.tsv"
    shell:
        "python -m experiments.jobs.track_job data {wildcards.tgrid} --out {output} --workers {threads}"
        " > {log} 2>&1"


rule tracking_run:
    input:
        data="results/{tgrid}/data",
    output:
        directory("results/{tgrid}/track/{tracker}"),
    wildcard_constraints:
        tgrid=TRACKING_GRID_RE,
    threads: 1
    # the longest trackers first (their last run's benchmark file, else experiments/workflow/job_cpu_s.csv)
    priority: tracking_priority
    resources:
        mem_mb=MEM_MB_JOB,
        runtime=tracking_runtime,
    conda:
        CONDA_ENV
    log:
        "results/{tgrid}/logs/track/{tracker}.log",
    benchmark:
        "results/{tgrid}/benchmarks/track/{tracker}.tsv"
    shell:
        "python -m experiments.jobs.track_job run {wildcards.tgrid} --tracker {wildcards.tracker}"
        " --data {input.data} --out {output} > {log} 2>&1"


rule tracking_report:
    input:
        data="results/{tgrid}/data",
        results=lambda wc: tracker_dirs(wc.tgrid),
    output:
        page="results/{tgrid}/summary.md",
        figures=report(
            directory("results/{tgrid}/figures"),
            patterns=["{name}.png"],
            caption="../../report/captions/_figure.rst",
            category=lambda wc: catalog.category_of(wc.name),
            labels=lambda wc: {"result": f"{catalog.title_of(wc.name)} ({wc.name}.png)"},
        ),
        tables=report(
            directory("results/{tgrid}/tables"),
            patterns=["{name}.html"],
            caption="../../report/captions/_table.rst",
            category=lambda wc: catalog.category_of(wc.name),
            labels=lambda wc: {"result": f"{catalog.title_of(wc.name)} ({wc.name}.html)"},
        ),
    wildcard_constraints:
        tgrid=TRACKING_GRID_RE,
    conda:
        CONDA_ENV
    log:
        "results/{tgrid}/logs/report.log",
    benchmark:
        "results/{tgrid}/benchmarks/report.tsv"
    shell:
        "python -m experiments.report.tracking_report --grid {wildcards.tgrid} --data {input.data}"
        " --out results/{wildcards.tgrid} --page {output.page} -- {input.results} > {log} 2>&1"


# The (tracker, cell) MLflow runs beside the report (~0.14 s of CPU per run, 500 runs in the tracking grid); the
# grid's step then only logs the grid's run and makes them its children.
rule tracking_runlog_jobs:
    input:
        results=lambda wc: tracker_dirs(wc.tgrid),
    output:
        "results/{tgrid}/runlog/jobs.json",
    wildcard_constraints:
        tgrid=TRACKING_GRID_RE,
    conda:
        CONDA_ENV
    log:
        "results/{tgrid}/logs/runlog_jobs.log",
    benchmark:
        "results/{tgrid}/benchmarks/runlog_jobs.tsv"
    shell:
        "python -m experiments.runlog.tracker_runs --grid {wildcards.tgrid} --jobs-only --out {output}"
        " -- {input.results} > {log} 2>&1"


rule tracking_runlog:
    input:
        results=lambda wc: tracker_dirs(wc.tgrid),
        jobs="results/{tgrid}/runlog/jobs.json",
        summary="results/{tgrid}/summary.md",
        tables="results/{tgrid}/tables",
        figures="results/{tgrid}/figures",
    output:
        record="results/{tgrid}/mlflow_runs.json",
        page="results/{tgrid}/README.md",
    wildcard_constraints:
        tgrid=TRACKING_GRID_RE,
    conda:
        CONDA_ENV
    log:
        "results/{tgrid}/logs/runlog.log",
    benchmark:
        "results/{tgrid}/benchmarks/runlog.tsv"
    shell:
        "python -m experiments.runlog.tracker_runs --grid {wildcards.tgrid} --out {output.record}"
        " --summary {input.summary} --page {output.page} --aggregate {input.tables} {input.figures}"
        " -- {input.results} > {log} 2>&1"
