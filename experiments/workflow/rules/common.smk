# The workflow's helpers: thin wrappers of the Python beside the rules (experiments/workflow/: grids.py loads
# and checks a grid, targets.py says what it runs, command_line.py what a command line asks for, with unit
# tests), and the resources each job asks of a cluster. Grids are configs/grid/<name>.yaml, validated against
# experiments/workflow/schemas/grid.yaml when a target asks for them.
import json
import os
import shlex
import sys
from pathlib import Path

from snakemake.exceptions import WorkflowError
from snakemake.settings.types import DeploymentMethod

from experiments.runlog.store import check_store
from experiments.workflow import resources, targets, triggers
from experiments.workflow.command_line import (RENAMED_RULES, check_target, command_line_targets, renamed_rules,
                                               requested_grids, unknown_rule_targets)
from experiments.workflow.grids import GridError, Grids
from experiments.workflow.tracking import TRACKING_GRIDS

# Jobs run side by side on the cores Snakemake is given; multithreaded BLAS on the small matrices of the
# filters only makes them fight (wkf measured 4x slower per replicate on 2 busy cores).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

CONDA_ENV = "../../../configs/conda/pipeline.yaml"

# Each job's `python` is the interpreter running Snakemake, whose environment has the project installed. Its
# directory goes first on the jobs' PATH, so a job never depends on the PATH of the shell that submitted it
# (a SLURM job starts in whatever shell the node gives, and the plugin re-runs this file there with the same
# interpreter). Under --use-conda the job's conda environment provides `python` instead. "set -euo pipefail"
# is Snakemake's default prefix, kept.
if DeploymentMethod.CONDA not in workflow.deployment_settings.deployment_method:
    shell.prefix(f"set -euo pipefail; export PATH={shlex.quote(os.path.dirname(sys.executable))}:\"$PATH\"; ")

WF = Grids(workflow.basedir)
GRID_NAMES = WF.grid_names()

# A requested grid is checked before the DAG is built, so a bad file or target is reported as one line (an
# error inside an input function would come wrapped in Snakemake's context); other grids' files are not read.
try:
    _REQUESTED = requested_grids(sys.argv[1:], GRID_NAMES + TRACKING_GRIDS)
    for _name in _REQUESTED:
        if _name in GRID_NAMES:       # the tracking grids are checked by experiments/workflow/rules/tracking.smk
            WF.load_grid(_name)
    for _target in sys.argv[1:]:
        check_target(WF, _target)
except GridError as _exc:
    print(str(_exc), file=sys.stderr)
    sys.exit(2)

# The MLflow store a grid's last step writes, checked as the grid is: an empty, truncated or corrupt store is
# one line now, not "Error in rule track" after every other job (experiments/runlog/store.py).
if _REQUESTED:
    try:
        check_store()
    except ValueError as _exc:
        print(f"error: {_exc}", file=sys.stderr)
        sys.exit(2)

def finish_reading(rules):
    """Called at the end of the Snakefile, once every rule is defined. A bare word that names no rule
    (`snakemake --cores 2 papr`) is one line naming the rules, where Snakemake would print several lines.
    The targets are read by Snakemake's own parser, since they are not yet in `workflow` here. Then
    the data folders the identify batches read (dataset_folder below) are made, before Snakemake lists what
    exists: one made while it builds the jobs is not seen ("Missing input files"). Those of the grids asked
    for, or of the default target (the paper grid) when none is.

    A renamed rule's old name on the command line (``--forcerun track``) names the new rule, with a note:
    Snakemake has no alias of a rule (``use rule ... as`` makes a second rule with the same outputs, which
    the DAG would not use), so the old name is entered in the workflow's table of rules, where the options
    taking rule names (--forcerun, --until, --omit-from, --prioritize) look names up."""
    for old in renamed_rules(sys.argv[1:]):
        workflow._rules.setdefault(old, workflow._rules[RENAMED_RULES[old]])
    unknown = unknown_rule_targets(command_line_targets(sys.argv[1:]), {r.name for r in rules}, workflow.basedir)
    if unknown:
        print(f"error: no rule '{unknown[0]}'; the targets are the rules "
              + ", ".join(sorted(r.name for r in rules if not r.has_wildcards()))
              + " or a file results/<grid>/...", file=sys.stderr)
        sys.exit(2)
    for name in _REQUESTED or ([] if {"--lint", "--unlock"} & set(sys.argv) else ["paper"]):
        if name in GRID_NAMES:
            Path("results", name, "data").mkdir(parents=True, exist_ok=True)


wildcard_constraints:
    grid="|".join(GRID_NAMES),
    method="[a-z0-9_]+",
    cell=r"noise[A-Za-z0-9_.+-]+",


def _grid(call):
    """A workflow call that may refuse a grid: a GridError becomes Snakemake's WorkflowError."""
    try:
        return call()
    except GridError as exc:
        raise WorkflowError(str(exc)) from None


def grid_targets(grid):
    return targets.grid_targets(grid)


def identify_dirs(grid):
    return _grid(lambda: targets.identify_dirs(WF, grid))


def experiment_dirs(grid):
    return _grid(lambda: targets.experiment_dirs(WF, grid))


def result_files(grid):
    return _grid(lambda: targets.result_files(WF, grid))


def yardstick_files(grid):
    return _grid(lambda: targets.yardstick_files(WF, grid))


def yardstick_cells(wildcards):
    return _grid(lambda: targets.yardstick_cells(WF, wildcards.grid))


def yardstick_args(wildcards):
    return _grid(lambda: targets.yardstick_args(WF, wildcards.grid))


def dataset_files(wildcards):
    """The datasets an identify batch reads: the files of the cells its method runs on."""
    cells = _grid(lambda: targets.method_cells(WF, wildcards.grid, wildcards.method))
    return [f"results/{wildcards.grid}/data/{c}.npz" for c in cells]


def dataset_folder(wildcards):
    """The folder of a grid's datasets, an input of its identify batches for its modification time: deleting a
    dataset changes it, so the batches rerun, and Snakemake remakes the missing file they need first (a
    missing file that no job to be run needs is not remade: Snakemake takes the results as up to date). The
    datasets batch writes its files before any identify batch starts, so a run leaves the folder older than
    the batches' outputs. The input must exist: made when the workflow is read (above), and here for a grid
    no target named; a .snakemake_timestamp left by the folder output of earlier versions would stand in for
    its mtime, and is removed."""
    folder = Path("results", wildcards.grid, "data")
    folder.mkdir(parents=True, exist_ok=True)
    (folder / ".snakemake_timestamp").unlink(missing_ok=True)
    return str(folder)


def identify_jobs(wildcards):
    """The identify batch of a (grid, method): one identify command line per cell, as JSON."""
    jobs = _grid(lambda: targets.identify_jobs(WF, wildcards.grid, wildcards.method))
    return shlex.quote(json.dumps(jobs))


# What an identify job's result depends on, for Snakemake's rerun triggers: the method's code files are
# inputs (mtime/input triggers), its resolved config and the versions of the packages it imports are
# params (params trigger). An edit of configs/method/fft.yaml or methods/fft.py reruns the fft jobs and
# everything downstream; an edit elsewhere reruns nothing.
def method_code(wildcards):
    return triggers.method_code(WF.root, wildcards.method)


def resolved_config(wildcards):
    overrides = _grid(lambda: WF.grid_method_overrides(wildcards.grid, wildcards.method))
    return triggers.resolved_config(WF.root, wildcards.method, tuple(overrides))


def method_versions(wildcards):
    return triggers.method_versions(WF.root, wildcards.method)


# Resources (threads, mem_mb, runtime in minutes) that a cluster executor requests per job; a local run only
# uses threads. Measured with Snakemake's benchmark files (smoke grid) and /usr/bin/time on one N = 2048, R = 4
# cell (2026-11-22): every job is one process on one core; peak RSS 92-122 MB in the smoke grid, 95 MB
# (dataset) to 145 MB (pem) at N = 2048; CPU time = ~1.5 s of imports + a cost per replicate x sample,
# largest for pem: 29 s for 8192 samples, 0.0035 s each (fft/akf/pll <= 0.0002, wkf 0.0002, dataset 0.0001;
# experiments/workflow/resources.py). Requests: 1000 MB (~7x the peak); identify 4x the pem cost of its cell, at
# least 2 minutes (a smoke job takes ~2 s of CPU, ~17 s wall on a machine loaded 8x); dataset 5 minutes (20 s
# of CPU at N = 2048, R = 100).
MEM_MB_JOB = 1000
# Worker processes of one identify batch (its cells handed out as workers free up; Snakemake caps it at
# --cores, and `snakemake ... --set-threads identify=N` sets it per run). One by default: on the 2-core
# machine the full_paper_methods grid took 162 s with one (9.5 % of job time not numerics) and 148 s with
# two, where each batch's serial start (imports, composing and checking its cells: ~2 s) holds the second
# core idle (15 %). More workers pay on a machine with more cores than a grid has methods, and on a
# cluster, where a batch's workers are the CPUs its job asks for.
IDENTIFY_THREADS = 1


def identify_runtime(wildcards, attempt):
    return _grid(lambda: resources.identify_runtime(WF, wildcards.grid, wildcards.method, attempt))


def identify_priority(wildcards):
    return resources.identify_priority(WF.root, wildcards.grid, wildcards.method)


def yardstick_priority(wildcards):
    return resources.job_priority(WF.root, wildcards.grid, "yardstick")


def runlog_priority(wildcards):
    return resources.job_priority(WF.root, wildcards.grid, "runlog_jobs")


def experiment_priority(wildcards):
    return resources.job_priority(WF.root, wildcards.grid, f"paper/{wildcards.experiment}")


# The datasets batch first: every identify batch and the yardstick wait for it (a few seconds), while the paper
# experiments, which need no dataset, would otherwise take both cores at the start.
DATASETS_PRIORITY = 1_000_000


def dataset_runtime(grid):
    """The runtime request of the datasets batch of a grid (datasets.smk)."""
    return lambda wildcards, attempt: resources.dataset_runtime(WF, grid, attempt)
