"""The cluster requests of the workflow's jobs (runtime in minutes), from the measured costs: see
``experiments/workflow/rules/common.smk`` for the measurement. A local run ignores them."""

from __future__ import annotations

import math

from experiments.workflow.grids import Grids
from experiments.workflow.targets import method_cells

__all__ = ["CPU_S_PER_SAMPLE", "DATASET_CPU_S_PER_SAMPLE", "identify_runtime", "dataset_runtime"]

# CPU seconds per replicate × sample of the costliest method (pem) and of the dataset job.
CPU_S_PER_SAMPLE = 0.0035
DATASET_CPU_S_PER_SAMPLE = 0.0001


def _samples(grids: Grids, grid: str, cell_names: list[str]) -> int:
    g = grids.load_grid(grid)
    return sum(g["replicates"] * int(g["cells"][c]["n_samples"]) for c in cell_names)


def identify_runtime(grids: Grids, grid: str, config: str, attempt: int) -> int:
    """Minutes for one identify batch: 4x the measured cost of its cells, at least 2 min, doubled per retry."""
    work = _samples(grids, grid, method_cells(grids, grid, config))
    return attempt * max(2, math.ceil(4 * CPU_S_PER_SAMPLE * work / 60))


def dataset_runtime(grids: Grids, grid: str, attempt: int) -> int:
    """Minutes for the datasets batch: 4x its measured cost, at least 5 min, doubled per retry."""
    work = _samples(grids, grid, grids.cells(grid))
    return attempt * max(5, math.ceil(4 * DATASET_CPU_S_PER_SAMPLE * work / 60))
