"""What a loaded grid runs: its cells per method, the command lines of its dataset and identify batches, and
the files its rules read and write (the targets of ``experiments/workflow/rules/*.smk``)."""

from __future__ import annotations

import dataclasses
import functools

import methods
from experiments.config_schema import method_of_config
from experiments.workflow.grids import GridError, Grids, method_config

__all__ = ["has_option", "runs_cell", "method_cells", "result_files", "identify_dirs", "experiment_dirs",
           "grid_targets", "dataset_args", "dataset_jobs", "cell_overrides", "identify_jobs", "yardstick_files",
           "yardstick_cells", "yardstick_args"]


@functools.cache
def has_option(config: str, option: str) -> bool:
    """Whether the method of a config has the keyword option (asked of the registry's ``Options``)."""
    fields = dataclasses.fields(methods.options_class(method_of_config(config)))
    return option in {f.name for f in fields}


def runs_cell(grids: Grids, grid: str, config: str, cell: str) -> bool:
    """Whether a method runs on a cell: a ``measurement`` cell only for methods with that option."""
    measurement = grids.load_grid(grid)["cells"][cell]["axes"].get("measurement")
    return measurement is None or has_option(config, "measurement")


def method_cells(grids: Grids, grid: str, config: str) -> list[str]:
    return [c for c in grids.cells(grid) if runs_cell(grids, grid, config, c)]


def result_files(grids: Grids, grid: str) -> list[str]:
    g = grids.load_grid(grid)
    return [f"results/{grid}/identify/{method_config(m)}/{c}.csv" for m in g["methods"]
            for c in method_cells(grids, grid, method_config(m))]


def identify_dirs(grids: Grids, grid: str) -> list[str]:
    """The identify batches' folders of a grid (each holds the tables and records of its method)."""
    return [f"results/{grid}/identify/{method_config(m)}" for m in grids.load_grid(grid)["methods"]]


def experiment_dirs(grids: Grids, grid: str) -> list[str]:
    return [f"results/{grid}/paper/{e}" for e in grids.load_grid(grid).get("experiments", [])]


def grid_targets(grid: str) -> list[str]:
    return [f"results/{grid}/README.md", f"results/{grid}/mlflow_runs.json"]


def dataset_args(grids: Grids, grid: str, cell_name: str) -> list[str]:
    """make_dataset's command-line overrides of one cell (the plain cells: exactly those of before)."""
    g = grids.load_grid(grid)
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


def dataset_jobs(grids: Grids, grid: str) -> list[list[str]]:
    """The datasets batch: one make_dataset command line per cell (experiments/jobs/batch.py)."""
    return [dataset_args(grids, grid, c) + [f"out=results/{grid}/data/{c}.npz"] for c in grids.cells(grid)]


def cell_overrides(grids: Grids, grid: str, config: str, cell: str) -> list[str]:
    """The method's overrides on one cell: the grid's, and the cell's measurement axis."""
    out = grids.grid_method_overrides(grid, config)
    measurement = grids.load_grid(grid)["cells"][cell]["axes"].get("measurement")
    if measurement is not None:
        out.append(f"method.options.measurement={measurement}")
    return out


def identify_jobs(grids: Grids, grid: str, config: str) -> list[list[str]]:
    """The identify batch of a (grid, method): one identify command line per cell."""
    jobs = [[f"method={config}", f"data.dataset=results/{grid}/data/{c}.npz",
             f"out=results/{grid}/identify/{config}/{c}.csv", f"grid_name={grid}", "runlog.enabled=false",
             *cell_overrides(grids, grid, config, c)] for c in method_cells(grids, grid, config)]
    if not jobs:
        raise GridError(f"error: grid {grid}: method {config} runs on none of its cells")
    return jobs


def yardstick_files(grids: Grids, grid: str) -> list[str]:
    """The grid's yardstick table, or none when the grid names no ``yardstick_prior``."""
    return [f"results/{grid}/yardstick.csv"] if "yardstick_prior" in grids.load_grid(grid) else []


def yardstick_cells(grids: Grids, grid: str) -> list[str]:
    """The dataset files the yardstick reads: the grid's plain cells (no scenario axis)."""
    g = grids.load_grid(grid)
    return [f"results/{grid}/data/{c}.npz" for c, cell in g["cells"].items() if not cell["axes"]]


def yardstick_args(grids: Grids, grid: str) -> str:
    """The yardstick job's prior options."""
    mu, std = grids.yardstick_prior(grids.load_grid(grid)["yardstick_prior"])
    return (f"--prior-rad-s {' '.join(f'{v:g}' for v in mu)} "
            f"--prior-std-rad-s {' '.join(f'{v:g}' for v in std)}")
