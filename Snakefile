# The workflow's table of contents: datasets -> identify -> aggregate -> track.
# Every step is a command a user can type by hand (python -m experiments.<step> ...).
#
#   snakemake --cores 2            # the default target: the paper grid (configs/grid/paper.yaml)
#   snakemake --cores 2 smoke      # the CI grid;  `full` for R = 100 and records up to 2048 samples
#   snakemake --cores 2 results/<name>/README.md   # any grid in configs/grid/<name>.yaml
#   snakemake --cores 2 tracking   # the tracking grid (configs/grid/tracking.yaml, docs/tracking.md)

include: "experiments/workflow/rules/common.smk"
include: "experiments/workflow/rules/datasets.smk"
include: "experiments/workflow/rules/identify.smk"
include: "experiments/workflow/rules/report.smk"
include: "experiments/workflow/rules/tracking.smk"


localrules:
    paper,
    smoke,
    full,


rule paper:
    input:
        grid_targets("paper"),
    default_target: True


rule smoke:
    input:
        grid_targets("smoke"),


rule full:
    input:
        grid_targets("full"),


# Last, once every rule is defined: a target that names no rule is one line; the data folders are made.
finish_reading(workflow.rules)
