# aggregate -> track: the grid's page results/<grid>/README.md is written last, by the tracking step, so
# one target gives the tables, the figures and the MLflow runs (results/<grid>/summary.md is the same page
# before tracking).
rule aggregate:
    input:
        results=lambda wc: result_files(wc.grid),
        experiments=lambda wc: experiment_dirs(wc.grid),
    output:
        page="results/{grid}/summary.md",
        tables=directory("results/{grid}/tables"),
        figures=directory("results/{grid}/figures"),
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/aggregate.log",
    shell:
        "python -m experiments.report.aggregate --grid {wildcards.grid} --out results/{wildcards.grid}"
        " --page {output.page} --experiments {input.experiments} -- {input.results} > {log} 2>&1"


rule track:
    input:
        results=lambda wc: result_files(wc.grid),
        provenance=lambda wc: provenance_files(wc.grid),
        summary="results/{grid}/summary.md",
        tables="results/{grid}/tables",
        figures="results/{grid}/figures",
    output:
        record="results/{grid}/mlflow_runs.json",
        page="results/{grid}/README.md",
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/track.log",
    shell:
        "python -m experiments.tracking.track --grid {wildcards.grid} --out {output.record}"
        " --summary {input.summary} --page {output.page} --aggregate {input.tables} {input.figures}"
        " -- {input.results} > {log} 2>&1"


rule reproduce:
    output:
        directory("results/{grid}/paper/{experiment}"),
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/paper/{experiment}.log",
    shell:
        "python -m experiments.jobs.reproduce experiment={wildcards.experiment} out_dir={output}"
        " tracking.enabled=false > {log} 2>&1"
