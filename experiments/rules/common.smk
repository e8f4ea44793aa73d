# Grid configs (configs/grid/*.yaml), validated against configs/grid/schema.yaml on load, and the
# helpers that turn a grid into file names.
import glob
import os

import yaml
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

import methods
from experiments.jobs.config import method_of_config

# Jobs run side by side on the cores Snakemake is given; multithreaded BLAS on the small matrices of the
# filters only makes them fight (wkf measured 4x slower per replicate on 2 busy cores).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

CONDA_ENV = "../../configs/conda/pipeline.yaml"
GRID_SCHEMA = os.path.join(workflow.basedir, "configs", "grid", "schema.yaml")
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



def _load_grid(path):
    with open(path) as f:
        grid = yaml.safe_load(f)
    validate(grid, GRID_SCHEMA, set_default=True)
    expected = os.path.splitext(os.path.basename(path))[0]
    if grid["name"] != expected:
        raise ValueError(f"{path}: name '{grid['name']}' must match the file name '{expected}'")
    _check_methods(path, grid)
    return grid


GRIDS = {
    os.path.splitext(os.path.basename(p))[0]: _load_grid(p)
    for p in sorted(glob.glob(os.path.join(workflow.basedir, "configs", "grid", "*.yaml")))
    if os.path.basename(p) != "schema.yaml"
}


wildcard_constraints:
    grid="|".join(GRIDS),
    method="[a-z0-9_]+",
    noise=r"[0-9.e+-]+",
    n=r"[0-9]+",


def cell_name(noise, n):
    return f"noise{noise:g}ug_n{n}"


def cells(grid):
    g = GRIDS[grid]
    return [cell_name(noise, n) for noise in g["noise_ug"] for n in g["n_samples"]]


def result_files(grid):
    g = GRIDS[grid]
    return [f"results/{grid}/identify/{method_config(m)}/{c}.csv" for m in g["methods"] for c in cells(grid)]


def experiment_dirs(grid):
    return [f"results/{grid}/paper/{e}" for e in GRIDS[grid].get("experiments", [])]


def grid_targets(grid):
    return [f"results/{grid}/README.md", f"results/{grid}/mlflow_runs.json"]


def method_overrides(wildcards):
    overrides = GRIDS[wildcards.grid].get("method_overrides", {})
    named = {method_config(k): v for k, v in overrides.items()}
    return " ".join(named.get(wildcards.method, []))
