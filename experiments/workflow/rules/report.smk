# aggregate -> runlog: the grid's page results/<grid>/README.md is written last, by the runlog step (MLflow
# run logging), so one target gives the tables, the figures and the MLflow runs (results/<grid>/summary.md is
# the same page before the runs are logged).
#
# aggregate and runlog are light and serial (runlog is the one writer of the MLflow store): they run on the
# machine that runs Snakemake, never as cluster jobs.
localrules:
    aggregate,
    runlog_jobs,
    runlog,


# The HTML report (`snakemake --report report.html <grid target>`): every figure and table of a grid, in
# categories, with captions. Each output <name> is described by experiments/report/captions/<name>.rst
# (category, title, caption; see experiments/report/catalog.py); the aggregate writes the filled-in caption
# beside the output, and the caption templates below include it. Anything written into a grid's figures/
# (PNG) or tables/ (HTML) folder is picked up. One label per result: with two, Snakemake's report app takes
# a label with two values for an on/off toggle and a category of two results fails to open.
from experiments.report import catalog

report: "../../report/captions/workflow.rst"


# The Bayesian yardstick of a grid that names a prior (yardstick_prior: docs/prior.md): one job per grid,
# the van Trees bound of every plain cell and the posterior mean's RMSE on the records of the cells where the
# CRLB is loose (experiments/simulate/yardstick.py). Its inputs are the datasets and the code; the prior is a
# param (an edit of the prior's config reruns it), so a rerun with nothing changed does nothing.
rule yardstick:
    message:
        "yardstick: the Bayesian yardstick of grid {wildcards.grid} -> {output}"
    input:
        data=yardstick_cells,
        code=["experiments/simulate/bayes.py", "experiments/simulate/yardstick.py", "experiments/jobs/yardstick.py"],
    output:
        "results/{grid}/yardstick.csv",
    params:
        prior=yardstick_args,
    threads: 1
    # started before the identify batches it is longer than (experiments/workflow/resources.py)
    priority: yardstick_priority
    resources:
        mem_mb=MEM_MB_JOB,
        runtime=30,
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/yardstick.log",
    benchmark:
        "results/{grid}/benchmarks/yardstick.tsv"
    # glibc's malloc keeps the memory it frees (its documented tunables; other C libraries ignore them): the
    # SMC allocates and frees arrays of ~0.3 MB thousands of times a cell, each one fresh pages from the
    # kernel with glibc's defaults (2.4 M page faults, ~20 % of the job's CPU: docs/notes/sweep-cost.md)
    shell:
        "GLIBC_TUNABLES=glibc.malloc.mmap_threshold=33554432:glibc.malloc.trim_threshold=268435456"
        " python -m experiments.jobs.yardstick {params.prior} --out {output} -- {input.data} > {log} 2>&1"


rule aggregate:
    message:
        "aggregate: tables, figures and summary of grid {wildcards.grid} -> {output.page}"
    input:
        results=lambda wc: identify_dirs(wc.grid),
        experiments=lambda wc: experiment_dirs(wc.grid),
        yardstick=lambda wc: yardstick_files(wc.grid),
    output:
        page="results/{grid}/summary.md",
        figures=report(
            directory("results/{grid}/figures"),
            patterns=["{name}.png"],
            caption="../../report/captions/_figure.rst",
            category=lambda wc: catalog.category_of(wc.name),
            labels=lambda wc: {"result": f"{catalog.title_of(wc.name)} ({wc.name}.png)"},
        ),
        tables=report(
            directory("results/{grid}/tables"),
            patterns=["{name}.html"],
            caption="../../report/captions/_table.rst",
            category=lambda wc: catalog.category_of(wc.name),
            labels=lambda wc: {"result": f"{catalog.title_of(wc.name)} ({wc.name}.html)"},
        ),
    conda:
        CONDA_ENV
    params:
        tables=lambda wc: result_files(wc.grid),
    log:
        "results/{grid}/logs/aggregate.log",
    benchmark:
        "results/{grid}/benchmarks/aggregate.tsv"
    shell:
        "python -m experiments.report.aggregate --grid {wildcards.grid} --out results/{wildcards.grid}"
        " --page {output.page} --experiments {input.experiments} --yardstick {input.yardstick}"
        " -- {params.tables} > {log} 2>&1"


# The jobs' MLflow runs as soon as the identify batches are done, beside the yardstick, the paper experiments and
# the aggregate (the logging is ~0.14 s of CPU per run, 560 runs in the paper grid); the runlog step then only
# logs the grid's run and makes the jobs its children.
rule runlog_jobs:
    message:
        "runlog_jobs: MLflow runs of grid {wildcards.grid}'s jobs -> {output}"
    input:
        results=lambda wc: identify_dirs(wc.grid),
    output:
        "results/{grid}/runlog/jobs.json",
    priority: runlog_priority
    conda:
        CONDA_ENV
    params:
        tables=lambda wc: result_files(wc.grid),
    log:
        "results/{grid}/logs/runlog_jobs.log",
    benchmark:
        "results/{grid}/benchmarks/runlog_jobs.tsv"
    shell:
        "python -m experiments.runlog.identify_runs --grid {wildcards.grid} --jobs-only --out {output}"
        " -- {params.tables} > {log} 2>&1"


rule runlog:
    message:
        "runlog: MLflow runs and page of grid {wildcards.grid} -> {output.page}"
    input:
        results=lambda wc: identify_dirs(wc.grid),
        jobs="results/{grid}/runlog/jobs.json",
        summary="results/{grid}/summary.md",
        tables="results/{grid}/tables",
        figures="results/{grid}/figures",
    output:
        record="results/{grid}/mlflow_runs.json",
        page="results/{grid}/README.md",
    conda:
        CONDA_ENV
    params:
        tables=lambda wc: result_files(wc.grid),
    log:
        "results/{grid}/logs/runlog.log",
    benchmark:
        "results/{grid}/benchmarks/runlog.tsv"
    shell:
        "python -m experiments.runlog.identify_runs --grid {wildcards.grid} --out {output.record}"
        " --summary {input.summary} --page {output.page} --aggregate {input.tables} {input.figures}"
        " -- {params.tables} > {log} 2>&1"


rule reproduce:
    message:
        "reproduce: paper experiment {wildcards.experiment} -> {output}"
    output:
        report(
            directory("results/{grid}/paper/{experiment}"),
            patterns=["{name}.png"],
            caption="../../report/captions/_paper_experiment.rst",
            category="paper reproductions",
            subcategory="{experiment}",
        ),
    threads: 1
    priority: experiment_priority
    resources:
        mem_mb=MEM_MB_JOB,
        runtime=30,
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/paper/{experiment}.log",
    benchmark:
        "results/{grid}/benchmarks/paper/{experiment}.tsv"
    shell:
        "python -m experiments.jobs.reproduce experiment={wildcards.experiment} out_dir={output}"
        " runlog.enabled=false > {log} 2>&1"
