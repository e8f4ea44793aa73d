# Grid configs (configs/grid/*.yaml), validated against configs/grid/schema.yaml on load, and the
# helpers that turn a grid into file names.
import glob
import os

import yaml
from snakemake.utils import validate

# Jobs run side by side on the cores Snakemake is given; multithreaded BLAS on the small matrices of the
# filters only makes them fight (wkf measured 4x slower per replicate on 2 busy cores).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

CONDA_ENV = "../../configs/conda/pipeline.yaml"
GRID_SCHEMA = os.path.join(workflow.basedir, "configs", "grid", "schema.yaml")



def _load_grid(path):
    with open(path) as f:
        grid = yaml.safe_load(f)
    validate(grid, GRID_SCHEMA, set_default=True)
    expected = os.path.splitext(os.path.basename(path))[0]
    if grid["name"] != expected:
        raise ValueError(f"{path}: name '{grid['name']}' must match the file name '{expected}'")
    return grid


GRIDS = {
    os.path.splitext(os.path.basename(p))[0]: _load_grid(p)
    for p in sorted(glob.glob(os.path.join(workflow.basedir, "configs", "grid", "*.yaml")))
    if os.path.basename(p) != "schema.yaml"
}


wildcard_constraints:
    grid="|".join(GRIDS),
    method="[a-z_]+",
    noise=r"[0-9.e+-]+",
    n=r"[0-9]+",


def cell_name(noise, n):
    return f"noise{noise:g}ug_n{n}"


def cells(grid):
    g = GRIDS[grid]
    return [cell_name(noise, n) for noise in g["noise_ug"] for n in g["n_samples"]]


def result_files(grid):
    g = GRIDS[grid]
    return [f"results/{grid}/identify/{m}/{c}.csv" for m in g["methods"] for c in cells(grid)]


def experiment_dirs(grid):
    return [f"results/{grid}/paper/{e}" for e in GRIDS[grid].get("experiments", [])]


def grid_targets(grid):
    return [f"results/{grid}/README.md", f"results/{grid}/mlflow_runs.json"]


def method_overrides(wildcards):
    return " ".join(GRIDS[wildcards.grid].get("method_overrides", {}).get(wildcards.method, []))
