"""The cluster requests of the workflow's jobs (runtime in minutes), from the measured costs: see
``experiments/workflow/rules/common.smk`` for the measurement. A local run ignores them."""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path

from experiments.workflow.grids import Grids
from experiments.workflow.targets import method_cells

__all__ = ["CPU_S_PER_SAMPLE", "DATASET_CPU_S_PER_SAMPLE", "DEFAULT_COSTS", "identify_runtime", "dataset_runtime",
           "batch_cpu_s", "job_cpu_s", "downstream_cpu_s", "identify_priority", "job_priority", "write_defaults"]

# CPU seconds per replicate × sample of the costliest method (pem) and of the dataset job.
CPU_S_PER_SAMPLE = 0.0035
DATASET_CPU_S_PER_SAMPLE = 0.0001
# What each job of the shipped grids cost on its last measured run (CPU s), committed so that a fresh clone,
# which has no benchmark file and no cost model, still starts the longest jobs first (the priorities below).
# Regenerated from the cost model and a run's benchmark files: python -m experiments.workflow.resources paper full
# (and tracking, from a tracking grid run's benchmark files)
DEFAULT_COSTS = Path("experiments", "workflow", "job_cpu_s.csv")


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


def _benchmark_cpu_s(path: Path) -> float | None:
    """CPU seconds of a Snakemake benchmark file (``cpu_time``, else wall ``s``), None if absent or unreadable."""
    try:
        with path.open(newline="") as fh:
            row = next(csv.DictReader(fh, delimiter="\t"))
        value = float(row.get("cpu_time") or row["s"])
    except (OSError, StopIteration, KeyError, ValueError):
        return None
    return value if math.isfinite(value) and value > 0 else None


def default_cpu_s(root: Path, grid: str, job: str) -> float | None:
    """The committed cost of a job (:data:`DEFAULT_COSTS`: ``grid,job,cpu_s``), None where it has none."""
    try:
        with Path(root, DEFAULT_COSTS).open(newline="") as fh:
            for row in csv.DictReader(fh):
                if row["grid"] == grid and row["job"] == job:
                    value = float(row["cpu_s"])
                    return value if math.isfinite(value) and value > 0 else None
    except (OSError, KeyError, ValueError):
        return None
    return None


def _model_cpu_s(root: Path, grid: str) -> dict[str, float]:
    """The cost model's CPU s per identify batch (``results/bench/sweep_cost/<grid>.csv`` of
    ``python -m experiments.benchmarks.sweep_cost``), by method folder: Σ over the grid's cells of R × CPU
    per fit, a noise level the model did not time (``--noise-ug``) charged as the nearest timed one in log
    scale, as the model itself charges it (every timed cell once where the grid file is not readable)."""
    model = Path(root, "results", "bench", "sweep_cost", f"{grid}.csv")
    fits: dict[str, dict[int, dict[float, float]]] = {}
    try:
        with model.open(newline="") as fh:
            for r in csv.DictReader(fh):
                per_n = fits.setdefault(r["entry"].replace(":", "_"), {}).setdefault(int(r["n_samples"]), {})
                per_n[float(r["noise_ug"])] = int(r["replicates"]) * float(r["cpu_s_per_fit"])
    except (OSError, KeyError, ValueError):
        return {}
    try:
        levels = [float(x) for x in Grids(root).load_grid(grid)["noise_ug"]]
    except Exception:  # noqa: BLE001 - no such grid, or one that does not load: its timed cells as they are
        levels = None
    totals = {}
    for method, per_n in fits.items():
        total = 0.0
        for timed in per_n.values():
            for x in levels or timed:
                total += timed[min(timed, key=lambda t: abs(math.log(t / x)))]
        if math.isfinite(total):
            totals[method] = total
    return totals


def batch_cpu_s(root: Path, grid: str, method: str) -> float | None:
    """What an identify batch of (grid, method config) is known to cost, CPU s: its last run's Snakemake
    benchmark (``results/<grid>/benchmarks/identify/<method>.tsv``, ``cpu_time``, else wall ``s``), else the
    cost model's (:func:`_model_cpu_s`), else the committed default (:data:`DEFAULT_COSTS`, what a fresh
    clone has), else None."""
    measured = _benchmark_cpu_s(Path(root, "results", grid, "benchmarks", "identify", f"{method}.tsv"))
    if measured is not None:
        return measured
    model = _model_cpu_s(root, grid).get(method)
    return model if model is not None else default_cpu_s(root, grid, f"identify/{method}")


def job_cpu_s(root: Path, grid: str, job: str) -> float | None:
    """A grid's job other than an identify batch (``yardstick``, ``paper/<experiment>``): its last run's
    Snakemake benchmark (``results/<grid>/benchmarks/<job>.tsv``), else the committed default, else None."""
    measured = _benchmark_cpu_s(Path(root, "results", grid, "benchmarks", f"{job}.tsv"))
    return measured if measured is not None else default_cpu_s(root, grid, job)


def _priority(cost: float | None) -> int:
    return 0 if cost is None else int(math.ceil(cost))


# The serial steps after a grid's jobs, to its page (report.smk): the identify batches feed runlog_jobs (MLflow
# runs of the jobs) and the aggregate, the yardstick and the paper experiments feed the aggregate; runlog waits
# for both.
AFTER = {"identify": (("runlog_jobs", "aggregate"), "runlog"), "runlog_jobs": ((), "runlog"),
         "other": (("aggregate",), "runlog")}


def downstream_cpu_s(root: Path, grid: str, kind: str) -> float:
    """CPU s of the longest chain of steps that must follow a job of ``kind`` (``identify``, ``runlog_jobs``,
    else ``other``: the yardstick, a paper experiment) before the grid's page is written, from those steps'
    known costs (:func:`job_cpu_s`; 0 where unknown)."""
    parallel, last = AFTER.get(kind, AFTER["other"])
    return max([job_cpu_s(root, grid, j) or 0.0 for j in parallel], default=0.0) + (job_cpu_s(root, grid, last) or 0.0)


def identify_priority(root: Path, grid: str, method: str) -> int:
    """Snakemake priority of an identify batch: its known CPU seconds (:func:`batch_cpu_s`) plus the longest
    chain of steps that must follow it (:func:`downstream_cpu_s`), 0 when its own cost is unknown. Among the
    jobs ready at once the scheduler starts the highest first: the jobs with the longest path to the end
    first (list scheduling by "bottom level", Graham's LPT order where no step follows), so that the MLflow
    runs of the jobs, which wait for the last identify batch, run beside the yardstick and the paper
    experiments rather than after them. A fresh clone, with no benchmark and no cost model, takes the
    committed defaults (:data:`DEFAULT_COSTS`)."""
    cost = batch_cpu_s(root, grid, method)
    return _priority(None if cost is None else cost + downstream_cpu_s(root, grid, "identify"))


def job_priority(root: Path, grid: str, job: str) -> int:
    """Snakemake priority of the yardstick, a paper experiment or ``runlog_jobs``: its known CPU seconds
    (:func:`job_cpu_s`) plus the steps that must follow it (:func:`downstream_cpu_s`), on the identify
    batches' scale, so that all of them start longest path first."""
    cost = job_cpu_s(root, grid, job)
    kind = "runlog_jobs" if job == "runlog_jobs" else "other"
    return _priority(None if cost is None else cost + downstream_cpu_s(root, grid, kind))


def measured_costs(root: Path, grid: str) -> dict[str, float]:
    """CPU s per job of a grid, as :data:`DEFAULT_COSTS` keeps them: the identify batches from the cost model
    (:func:`_model_cpu_s`; Snakemake samples a job's CPU time every few seconds, and a batch of a few seconds
    is charged one sample), the yardstick and the paper experiments from the last run's Snakemake benchmark
    files (``results/<grid>/benchmarks``), the serial steps after them (``runlog_jobs``, ``aggregate``, ``runlog``:
    :func:`downstream_cpu_s`), and a tracking grid's tracker jobs (``track/<tracker>``) too."""
    costs = {f"identify/{m}": t for m, t in _model_cpu_s(root, grid).items()}
    folder = Path(root, "results", grid, "benchmarks")
    serial = [folder / f"{job}.tsv" for job in ("runlog_jobs", "aggregate", "runlog")]
    for path in [folder / "yardstick.tsv", *sorted(folder.glob("paper/*.tsv")),
                 *sorted(folder.glob("track/*.tsv")), *serial]:
        cost = _benchmark_cpu_s(path)
        if cost is not None:
            costs[path.relative_to(folder).with_suffix("").as_posix()] = cost
    return costs


def write_defaults(root: Path, grid: str, costs: dict[str, float]) -> Path:
    """Enter ``costs`` (job -> CPU s) of ``grid`` into :data:`DEFAULT_COSTS`, replacing those jobs' rows."""
    path = Path(root, DEFAULT_COSTS)
    try:
        with path.open(newline="") as fh:
            rows = [r for r in csv.DictReader(fh) if not (r["grid"] == grid and r["job"] in costs)]
    except OSError:
        rows = []
    rows += [{"grid": grid, "job": job, "cpu_s": f"{cost:.1f}"} for job, cost in costs.items()]
    rows.sort(key=lambda r: (r["grid"], -float(r["cpu_s"]), r["job"]))
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, ["grid", "job", "cpu_s"], lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    return path


def main(argv=None) -> int:
    """``python -m experiments.workflow.resources paper``: the committed default costs of a grid's jobs
    (:func:`measured_costs`: run ``python -m experiments.benchmarks.sweep_cost --grid paper`` and the grid
    first); the rows of jobs not measured are kept."""
    import argparse  # only for this command line, not for the workflow that imports the module

    ap = argparse.ArgumentParser(description="the committed default job costs of grids, from their measurements")
    ap.add_argument("grids", nargs="+")
    args = ap.parse_args(argv)
    for grid in args.grids:
        costs = measured_costs(Path.cwd(), grid)
        if not costs:
            print(f"error: grid '{grid}': no cost model (results/bench/sweep_cost/{grid}.csv) and no yardstick or "
                  f"paper-experiment or tracker benchmark (results/{grid}/benchmarks)", file=sys.stderr)
            return 2
        print(f"wrote {write_defaults(Path.cwd(), grid, costs)}: grid {grid}, {len(costs)} jobs")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
