# aggregate and track are light and serial (track is the one writer of the MLflow store): they run on the
# machine that runs Snakemake, never as cluster jobs.
localrules:
    aggregate,
    track,


rule aggregate:
    input:
        results=lambda wc: result_files(wc.grid),
        experiments=lambda wc: experiment_dirs(wc.grid),
    output:
        "results/{grid}/README.md",
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/aggregate.log",
    shell:
        "python -m experiments.report.aggregate --grid {wildcards.grid} --out results/{wildcards.grid}"
        " --experiments {input.experiments} -- {input.results} > {log} 2>&1"


rule track:
    input:
        results=lambda wc: result_files(wc.grid),
        summary="results/{grid}/README.md",
    output:
        "results/{grid}/mlflow_runs.json",
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/track.log",
    shell:
        "python -m experiments.tracking.track --grid {wildcards.grid} --out {output} {input.results} > {log} 2>&1"


rule reproduce:
    output:
        directory("results/{grid}/paper/{experiment}"),
    threads: 1
    resources:
        mem_mb=MEM_MB_JOB,
        runtime=30,
    conda:
        CONDA_ENV
    log:
        "results/{grid}/logs/paper/{experiment}.log",
    shell:
        "python -m experiments.jobs.reproduce experiment={wildcards.experiment} out_dir={output}"
        " tracking.enabled=false > {log} 2>&1"
