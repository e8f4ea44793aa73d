# The tracking grids (configs/grid/tracking*.yaml, docs/tracking.md): the records of every cell in one job,
# one job per tracker over every cell, then the report and the MLflow run logging (tracking_runlog: serial,
# local), as for the identification grids. Every step is a command a user can type:
#   python -m experiments.jobs.track_job data tracking --out results/tracking/data
#   python -m experiments.jobs.track_job run tracking --tracker akf --data results/tracking/data --out ...
#   python -m experiments.report.tracking_report ... ;  python -m experiments.runlog.tracker_runs ...
from experiments.workflow.tracking import (TRACKING_GRIDS, check_requested_tracking_grids, tracker_dirs,
                                               tracking_runtime)

check_requested_tracking_grids(sys.argv[1:])
# The tracking grids' names as a wildcard constraint; with no tracking grid at all it matches nothing (an
# empty constraint would match every grid, and tracking_data would then compete with datasets).
TRACKING_GRID_RE = "|".join(TRACKING_GRIDS) or "(?!)"


localrules:
    tracking,
    tracking_report,
    tracking_runlog,


rule tracking:
    input:
        "results/tracking/README.md",
        "results/tracking/mlflow_runs.json",


rule tracking_data:
    output:
        directory("results/{tgrid}/data"),
    wildcard_constraints:
        tgrid=TRACKING_GRID_RE,
    threads: 1
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
        "python -m experiments.jobs.track_job data {wildcards.tgrid} --out {output} > {log} 2>&1"


rule tracking_run:
    input:
        data="results/{tgrid}/data",
    output:
        directory("results/{tgrid}/track/{tracker}"),
    wildcard_constraints:
        tgrid=TRACKING_GRID_RE,
    threads: 1
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
    shell:
        "python -m experiments.report.tracking_report --grid {wildcards.tgrid} --data {input.data}"
        " --out results/{wildcards.tgrid} --page {output.page} -- {input.results} > {log} 2>&1"


rule tracking_runlog:
    input:
        results=lambda wc: tracker_dirs(wc.tgrid),
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
    shell:
        "python -m experiments.runlog.tracker_runs --grid {wildcards.tgrid} --out {output.record}"
        " --summary {input.summary} --page {output.page} --aggregate {input.tables} {input.figures}"
        " -- {input.results} > {log} 2>&1"
