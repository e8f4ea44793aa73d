# Grid configs (configs/grid/*.yaml), validated against configs/grid/schema.yaml on load, and the
# helpers that turn a grid into file names. A grid's cells (noise x length x scenario axes) and their names
# come from experiments/simulate/scenarios.py.
import functools
import glob
import json
import math
import os
import shlex
import sys

import jsonschema
import yaml
from snakemake.exceptions import WorkflowError
from snakemake.settings.types import DeploymentMethod
from snakemake.utils import validate

import methods
from experiments.jobs.config import method_of_config
from experiments.simulate import scenarios as _scenarios
from experiments.simulate.plant import PlantConfig
from experiments.tracking import provenance

# Jobs run side by side on the cores Snakemake is given; multithreaded BLAS on the small matrices of the
# filters only makes them fight (wkf measured 4x slower per replicate on 2 busy cores).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

CONDA_ENV = "../../configs/conda/pipeline.yaml"

# Each job's `python` is the interpreter running Snakemake, whose environment has the project installed. Its
# directory goes first on the jobs' PATH, so a job never depends on the PATH of the shell that submitted it
# (a SLURM job starts in whatever shell the node gives, and the plugin re-runs this file there with the same
# interpreter). Under --use-conda the job's conda environment provides `python` instead. "set -euo pipefail"
# is Snakemake's default prefix, kept.
if DeploymentMethod.CONDA not in workflow.deployment_settings.deployment_method:
    shell.prefix(f"set -euo pipefail; export PATH={shlex.quote(os.path.dirname(sys.executable))}:\"$PATH\"; ")
with open(os.path.join(workflow.basedir, "configs", "grid", "schema.yaml")) as _f:
    SCHEMA = yaml.safe_load(_f)

METHOD_CONFIGS = os.path.join(workflow.basedir, "configs", "method")


def method_config(entry):
    """The Hydra method config of a grid's methods entry: `pem` -> pem, `pem:paper` -> pem_paper."""
    return entry.replace(":", "_")


def _check_methods(path, grid):
    """Each method a grid names must have a config (or be an installed plugin) and its library."""
    for entry in grid["methods"]:
        config = method_config(entry)
        method = method_of_config(config)
        has_config = os.path.exists(os.path.join(METHOD_CONFIGS, f"{config}.yaml"))
        if method is None or not (has_config or (config in methods.plugins())):
            raise WorkflowError(f"error: {path}: unknown method '{entry}' (no configs/method/{config}.yaml "
                                f"and no installed plugin of that name)")
        try:
            methods.require(method)
        except ValueError as exc:
            raise WorkflowError(f"error: {path}: {exc}") from None


def _plant_config():
    """The grids' base plant (configs/plant/paper.yaml), to check scenario cells against it."""
    with open(os.path.join(workflow.basedir, "configs", "plant", "paper.yaml")) as f:
        values = {k: v for k, v in yaml.safe_load(f).items() if k != "defaults"}
    return PlantConfig(**values)


def _method_options(config_name):
    """The option names a method config sets (following its `defaults:` chain), without importing it."""
    path = os.path.join(METHOD_CONFIGS, f"{config_name}.yaml")
    if not os.path.exists(path):
        return set()                      # an installed plugin without a config: its defaults
    with open(path) as f:
        cfg = yaml.safe_load(f) or {}
    keys = set((cfg.get("options") or {}).keys())
    for parent in cfg.get("defaults") or []:
        if isinstance(parent, str) and parent != "_self_" and not parent.endswith("_schema"):
            keys |= _method_options(parent)
    return keys


def _refuse(path, message):
    """A bad grid: one line `error: ...` naming the file and the value, exit status 2, nothing run."""
    raise WorkflowError(f"error: {os.path.relpath(path)}: {message}")


GRID_DIR = os.path.join(workflow.basedir, "configs", "grid")
# Grid names are the file names; a grid is read and validated only when a target asks for it, so one
# malformed file never breaks the other grids. The tracking grids (tracking*.yaml) have their own schema and
# rules (experiments/rules/tracking.smk).
GRID_NAMES = sorted(
    os.path.splitext(os.path.basename(p))[0]
    for p in glob.glob(os.path.join(GRID_DIR, "*.yaml"))
    if not os.path.basename(p).startswith(("schema", "tracking"))
)


@functools.cache
def load_grid(name):
    """The grid ``configs/grid/<name>.yaml``, validated against the schema; a bad file stops the workflow
    with one line naming the file and the key."""
    path = os.path.relpath(os.path.join(GRID_DIR, f"{name}.yaml"))
    try:
        with open(path) as f:
            grid = yaml.safe_load(f)
        if not isinstance(grid, dict):
            raise ValueError("the file must be a mapping of keys (name, noise_ug, n_samples, ...)")
        jsonschema.validate(grid, SCHEMA)
    except jsonschema.ValidationError as exc:
        key = ".".join(map(str, exc.absolute_path)) or "(top level)"
        raise WorkflowError(f"error: {path}: {key}: {exc.message}") from None
    except (OSError, ValueError, yaml.YAMLError) as exc:
        raise WorkflowError(f"error: {path}: {' '.join(str(exc).split())}") from None
    validate(grid, os.path.join(GRID_DIR, "schema.yaml"), set_default=True)    # fills the schema's defaults
    if grid["name"] != name:
        raise WorkflowError(f"error: {path}: name: '{grid['name']}' must match the file name '{name}'")
    _check_methods(path, grid)
    try:
        grid["cells"] = _scenarios.check_grid(grid, _plant_config())
    except ValueError as exc:
        _refuse(path, str(exc))
    return grid


def _requested_grids():
    """The grids the command line asks for (a named rule or a results/<grid>/... file). Snakemake has not
    parsed its targets yet while it reads this file, so the command line's words are looked at."""
    names = set()
    for target in sys.argv[1:]:
        parts = os.path.normpath(str(target)).split(os.sep)
        if target in GRID_NAMES:
            names.add(target)
        elif len(parts) > 1 and parts[0] == "results" and parts[1] in GRID_NAMES:
            names.add(parts[1])
    return sorted(names)


# A requested grid is checked before the DAG is built, so a bad file is reported as one line (an error
# inside an input function would come wrapped in Snakemake's context); other grids' files are not read.
for _grid in _requested_grids():
    try:
        load_grid(_grid)
    except WorkflowError as _exc:
        print(str(_exc).strip(), file=sys.stderr)
        sys.exit(2)


wildcard_constraints:
    grid="|".join(GRID_NAMES),
    method="[a-z0-9_]+",
    cell=r"noise[A-Za-z0-9_.+-]+",


def cells(grid):
    return list(load_grid(grid)["cells"])


def runs_cell(grid, config_name, cell):
    """Whether a method runs on a cell: a `measurement` cell only for methods with that option."""
    measurement = load_grid(grid)["cells"][cell]["axes"].get("measurement")
    return measurement is None or "measurement" in _method_options(config_name)


def result_files(grid):
    g = load_grid(grid)
    return [f"results/{grid}/identify/{method_config(m)}/{c}.csv" for m in g["methods"] for c in cells(grid)
            if runs_cell(grid, method_config(m), c)]


def provenance_files(grid):
    return [f[: -len(".csv")] + ".json" for f in result_files(grid)]


def identify_dirs(grid):
    """The identify batches' folders of a grid (each holds the tables and records of its method)."""
    return [f"results/{grid}/identify/{method_config(m)}" for m in load_grid(grid)["methods"]]


def experiment_dirs(grid):
    return [f"results/{grid}/paper/{e}" for e in load_grid(grid).get("experiments", [])]


def grid_targets(grid):
    return [f"results/{grid}/README.md", f"results/{grid}/mlflow_runs.json"]


def dataset_args(grid, cell_name):
    """make_dataset's command-line overrides of one cell (the plain cells: exactly those of before)."""
    g = load_grid(grid)
    cell = g["cells"][cell_name]
    axes = cell["axes"]
    args = [f"noise_ug={cell['noise_ug']}", f"n_samples={cell['n_samples']}", f"replicates={g['replicates']}",
            f"seed={g['seed']}", f"dt_s={axes.get('dt_s', g['dt_s'])}",
            f"bias_m_s2={axes.get('bias_m_s2', g['bias_m_s2'])}"]
    for axis, value in axes.items():
        if axis not in ("dt_s", "bias_m_s2"):
            text = "[" + ",".join(str(v) for v in value) + "]" if isinstance(value, list) else str(value)
            args.append(f"scenario.{axis}={text}")
    named = [a for a in ("dt_s", "bias_m_s2") if a in axes]
    if named:
        args.append(f"scenario.axes=[{','.join(named)}]")
    return args


def dataset_jobs(wildcards):
    """The datasets batch: one make_dataset command line per cell (experiments/jobs/batch.py), as JSON."""
    jobs = [dataset_args(wildcards.grid, c) + [f"out=results/{wildcards.grid}/data/{c}.npz"]
            for c in cells(wildcards.grid)]
    return shlex.quote(json.dumps(jobs))


def grid_method_overrides(grid, method):
    """The grid's extra overrides of a method (keyed by its grid entry or config name)."""
    g = load_grid(grid)
    extra = g.get("method_overrides", {})
    entries = [e for e in g["methods"] if method_config(e) == method]
    out = list(extra.get(method, []))
    for e in entries:
        if e != method:
            out += extra.get(e, [])
    return out


def cell_overrides(grid, method, cell):
    """The method's overrides on one cell: the grid's, and the cell's measurement axis."""
    out = grid_method_overrides(grid, method)
    measurement = load_grid(grid)["cells"][cell]["axes"].get("measurement")
    if measurement is not None:
        out.append(f"method.options.measurement={measurement}")
    return out


def method_cells(grid, method):
    """The cells a method runs on (a `measurement` cell only for methods with that option)."""
    return [c for c in cells(grid) if runs_cell(grid, method, c)]


def identify_jobs(wildcards):
    """The identify batch of a (grid, method): one identify command line per cell, as JSON."""
    grid, method = wildcards.grid, wildcards.method
    jobs = [[f"method={method}", f"data.dataset=results/{grid}/data/{c}.npz",
             f"out=results/{grid}/identify/{method}/{c}.csv", f"grid_name={grid}", "tracking.enabled=false",
             *cell_overrides(grid, method, c)] for c in method_cells(grid, method)]
    if not jobs:
        raise WorkflowError(f"error: grid {grid}: method {method} runs on none of its cells")
    return shlex.quote(json.dumps(jobs))


# What an identify job's result depends on, for Snakemake's rerun triggers: the method's code files are
# inputs (mtime/input triggers), its resolved config and the versions of the packages it imports are
# params (params trigger). An edit of configs/method/fft.yaml or methods/fft.py reruns the fft jobs and
# everything downstream; an edit elsewhere reruns nothing.
def method_code(wildcards):
    return [os.path.join(workflow.basedir, f)
            for f in provenance.method_code_files(wildcards.method, workflow.basedir)]


def resolved_config(wildcards):
    overrides = tuple(grid_method_overrides(wildcards.grid, wildcards.method))
    if not os.path.exists(os.path.join(METHOD_CONFIGS, f"{wildcards.method}.yaml")):
        return provenance.canonical_json({"plugin": wildcards.method, "overrides": overrides})
    return provenance.resolved_method_config(wildcards.method, overrides, workflow.basedir)


def method_versions(wildcards):
    return provenance.package_versions(wildcards.method, workflow.basedir)


# Resources (threads, mem_mb, runtime in minutes) that a cluster executor requests per job; a local run only
# uses threads. Measured with Snakemake's benchmark files (smoke grid) and /usr/bin/time on one N = 2048, R = 4
# cell (2026-11-22): every job is one process on one core; peak RSS 92-122 MB in the smoke grid, 95 MB
# (dataset) to 145 MB (pem) at N = 2048; CPU time = ~1.5 s of imports + a cost per replicate x sample,
# largest for pem: 29 s for 8192 samples, 0.0035 s each (fft/akf/pll <= 0.0002, wkf 0.0002, dataset 0.0001).
# Requests: 1000 MB (~7x the peak); identify 4x the pem cost of its cell, at least 2 minutes (a smoke job takes
# ~2 s of CPU, ~17 s wall on a machine loaded 8x); dataset 5 minutes (20 s of CPU at N = 2048, R = 100).
MEM_MB_JOB = 1000
# Worker processes of one identify batch (its cells handed out as workers free up; Snakemake caps it at
# --cores, and `snakemake ... --set-threads identify=N` sets it per run). One by default: on the 2-core
# machine the full_paper_methods grid took 162 s with one (9.5 % of job time not numerics) and 148 s with
# two, where each batch's serial start (imports, composing and checking its cells: ~2 s) holds the second
# core idle (15 %). More workers pay on a machine with more cores than a grid has methods, and on a
# cluster, where a batch's workers are the CPUs its job asks for.
IDENTIFY_THREADS = 1
CPU_S_PER_SAMPLE = 0.0035


DATASET_CPU_S_PER_SAMPLE = 0.0001


def _grid_samples(grid, cell_names):
    g = load_grid(grid)
    return sum(g["replicates"] * int(g["cells"][c]["n_samples"]) for c in cell_names)


def identify_runtime(wildcards, attempt):
    """Minutes for one identify batch: 4x the measured cost of its cells, at least 2 min, doubled per retry."""
    work = _grid_samples(wildcards.grid, method_cells(wildcards.grid, wildcards.method))
    return attempt * max(2, math.ceil(4 * CPU_S_PER_SAMPLE * work / 60))


def dataset_runtime(wildcards, attempt):
    """Minutes for the datasets batch: 4x its measured cost, at least 5 min, doubled per retry."""
    work = _grid_samples(wildcards.grid, cells(wildcards.grid))
    return attempt * max(5, math.ceil(4 * DATASET_CPU_S_PER_SAMPLE * work / 60))
