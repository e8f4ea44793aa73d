"""The cluster requests of the workflow's jobs (runtime in minutes), from the measured costs: see
``experiments/workflow/rules/common.smk`` for the measurement. A local run ignores them."""

from __future__ import annotations

import csv
import math
from pathlib import Path

from experiments.workflow.grids import Grids
from experiments.workflow.targets import method_cells

__all__ = ["CPU_S_PER_SAMPLE", "DATASET_CPU_S_PER_SAMPLE", "identify_runtime", "dataset_runtime", "batch_cpu_s",
           "identify_priority"]

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


def batch_cpu_s(root: Path, grid: str, method: str) -> float | None:
    """What an identify batch of (grid, method config) is known to cost, CPU s: its last run's Snakemake
    benchmark (``results/<grid>/benchmarks/identify/<method>.tsv``, ``cpu_time``, else wall ``s``), else the
    cost model's per-cell fit times (``results/bench/sweep_cost/<grid>.csv`` of
    ``python -m experiments.benchmarks.sweep_cost``: Σ over its cells of R × CPU per fit), else None."""
    bench = Path(root, "results", grid, "benchmarks", "identify", f"{method}.tsv")
    try:
        with bench.open(newline="") as fh:
            row = next(csv.DictReader(fh, delimiter="\t"))
        value = float(row.get("cpu_time") or row["s"])
        if math.isfinite(value) and value > 0:
            return value
    except (OSError, StopIteration, KeyError, ValueError):
        pass
    model = Path(root, "results", "bench", "sweep_cost", f"{grid}.csv")
    try:
        with model.open(newline="") as fh:
            rows = [r for r in csv.DictReader(fh) if r["entry"].replace(":", "_") == method]
        total = sum(int(r["replicates"]) * float(r["cpu_s_per_fit"]) for r in rows)
    except (OSError, KeyError, ValueError):
        return None
    return total if rows and math.isfinite(total) else None


def identify_priority(root: Path, grid: str, method: str) -> int:
    """Snakemake priority of an identify batch: its known CPU seconds (:func:`batch_cpu_s`), 0 when unknown.
    Among the batches ready at once the scheduler starts the highest first, so the longest batches start
    first and the short ones fill the cores at the end (Graham's LPT order: the wall time the cost model
    predicts); without a measurement the order is Snakemake's own."""
    cost = batch_cpu_s(root, grid, method)
    return 0 if cost is None else int(math.ceil(cost))
