"""What a tracking grid will cost, from a few of its cells: a proxy for the whole run's CPU and wall time.

    python -m experiments.benchmarks.tracking_grid_cost --grid tracking \
        --cells drift_disturbance_noise1000ug_120s,drift_sparse_noise1000ug_120s [--replicates 1]

For each named cell: the CPU time (``time.process_time``) of simulating it with its bounds
(``tracking_data.make_cell``), and of every tracker of the grid (its options and variants as the grid's run
step gives them, ``experiments.jobs.track_job``) on ``--replicates`` of its records, each tracker warmed up
once untimed as the run step does. Every cell of a grid has records of the same kind and length, so the
grid's CPU is estimated as (mean measured CPU per record) × replicates × cells, plus the cells' simulation;
its wall time on 2 cores as that CPU over the parallel efficiency of the last whole-grid measurement
(docs/tracking.md §4: 1083 s of CPU in 12 min 30 s, 1.44 cores busy on average: the report and MLflow steps
and the Snakemake scheduling run on one core). Timings on a shared machine are noisy; the page says the load
average. Prints the tables and writes them to results/bench/tracking_grid_cost.md.

    python -m experiments.benchmarks.tracking_grid_cost --run results/tracking [--cores 2]

reads a finished run of a grid instead: each step's CPU seconds from the last line of its log (``total: <s> s
CPU``, the process from its start and its workers: Snakemake's benchmark files sample a job's CPU every few
seconds and miss up to an interval of it), and predicts the run's wall time on ``--cores`` quiet cores from the
workflow's order (experiments/workflow/rules/tracking.smk): the records on min(workers, cores) cores, the tracker
jobs placed longest first (LPT, as their priorities order them), the report beside the (tracker, cell) MLflow runs,
then the grid's MLflow run and page. Scheduling and file-system time are not counted.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from pathlib import Path

from experiments.benchmarks.sweep_cost import makespan
from experiments.cli import read_cpu_line
from experiments.jobs.track_job import check_tracker, grid_trackers, track_record, warm_up
from experiments.simulate.laboratory import LaboratoryCellConfig, make_lab_cell
from experiments.simulate.tracking_data import make_cell
from experiments.simulate.tracking_grid import load_grid

__all__ = ["CORES_BUSY", "main", "measure", "predict_run", "run_costs"]

CORES_BUSY = 1083.0 / 750.0      # the last whole-grid run: CPU s / wall s (docs/tracking.md §4)


def measure(grid: dict, cells: list[str], replicates: int) -> tuple[dict, dict]:
    """CPU seconds per (tracker, cell) for ``replicates`` records, and per cell for its simulation."""
    data, sim = {}, {}
    for name in cells:
        t0 = time.process_time()
        config = grid["cells"][name]["config"]
        data[name] = make_lab_cell(config) if isinstance(config, LaboratoryCellConfig) else make_cell(config)
        sim[name] = time.process_time() - t0
    cpu = {}
    for spec in grid_trackers(grid):
        options = check_tracker(grid, spec)
        warm_up(spec, options, data[cells[0]])
        for name in cells:
            d = data[name]
            t0 = time.process_time()
            for r in range(replicates):
                track_record(spec, d["accel_m_s2"][r], float(d["dt_s"]), d["prior_rad_s"][r], options)
            cpu[spec, name] = time.process_time() - t0
        print(f"{spec}: " + ", ".join(f"{cpu[spec, n]:.2f} s" for n in cells), flush=True)
    return cpu, sim


def run_costs(run: Path) -> dict[str, float]:
    """CPU s of each step of a finished run of a tracking grid (``results/<grid>``), from its logs' last
    :func:`experiments.cli.cpu_line`: ``data``, ``track/<tracker>``, ``report``, ``runlog_jobs``, ``runlog``; a
    step whose log has no such line is left out."""
    logs = Path(run) / "logs"
    found = {}
    for path in [logs / "data.log", *sorted((logs / "track").glob("*.log")), logs / "report.log",
                 logs / "runlog_jobs.log", logs / "runlog.log"]:
        try:
            cpu = read_cpu_line(path.read_text(errors="replace"))
        except OSError:
            continue
        if cpu is not None:
            found[path.relative_to(logs).with_suffix("").as_posix()] = cpu
    return found


def predict_run(costs: dict[str, float], cores: int, data_workers: int) -> dict[str, float]:
    """The wall time (s) of the run's steps on ``cores`` quiet cores, in the workflow's order: the records on
    min(``data_workers``, cores) processes (their cells cost about the same), the tracker jobs LPT-placed
    (:func:`experiments.benchmarks.sweep_cost.makespan`), the report beside the jobs' MLflow runs (on two cores
    or more), then the grid's run."""
    track = {k: v for k, v in costs.items() if k.startswith("track/")}
    data = costs.get("data", 0.0) / max(1, min(data_workers, cores))
    trackers = makespan(track, cores) if track else 0.0
    report, runs, grid_run = costs.get("report", 0.0), costs.get("runlog_jobs", 0.0), costs.get("runlog", 0.0)
    tail = max(report, runs) if cores >= 2 else report + runs
    return {"data": data, "trackers": trackers, "report and job runs": tail, "grid run": grid_run,
            "wall": data + trackers + tail + grid_run, "cpu": sum(costs.values()),
            "bound": data + max(sum(track.values()) / cores, max(track.values(), default=0.0)) + tail + grid_run}


def main_run(run: Path, cores: int) -> int:
    costs = run_costs(run)
    if not any(k.startswith("track/") for k in costs):
        print(f"error: --run {run}: no tracker log with a CPU line (logs/track/<tracker>.log ending 'total: <s> s "
              f"CPU'): not a finished run of a tracking grid by this version", file=sys.stderr)
        return 2
    data_log = run / "logs" / "data.log"
    workers = re.findall(r"cells on (\d+) process", data_log.read_text(errors="replace") if data_log.is_file() else "")
    wall = predict_run(costs, cores, int(workers[-1]) if workers else 1)
    load = os.getloadavg()[0]
    lines = [f"# The wall time of the tracking run {run} on {cores} quiet cores, from its steps' CPU", "",
             f"`python -m experiments.benchmarks.tracking_grid_cost --run {run} --cores {cores}` (each step's CPU "
             f"from its log's last line; load average now {load:.1f}).", "",
             "| step | CPU s |", "|---|---|"]
    lines += [f"| {k} | {v:.1f} |" for k, v in sorted(costs.items(), key=lambda kv: -kv[1])]
    lines += ["", "| part | wall s |", "|---|---|"]
    lines += [f"| {k} | {wall[k]:.0f} |" for k in ("data", "trackers", "report and job runs", "grid run")]
    lines += ["", f"All steps **{wall['cpu']:.0f} s CPU**; predicted wall time on {cores} cores **{wall['wall']:.0f} s "
              f"({wall['wall'] / 60:.1f} min)** (lower bound {wall['bound'] / 60:.1f} min: the tracker jobs' CPU "
              f"over {cores} cores, or the longest)."]
    print("\n".join(lines))
    return 0


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", default="tracking")
    parser.add_argument("--cells", help="comma-separated cell names of the grid")
    parser.add_argument("--replicates", type=int, default=1)
    parser.add_argument("--run", type=Path, help="a finished run's folder (results/<grid>): predict its wall time")
    parser.add_argument("--cores", type=int, default=2, help="with --run: the cores to predict for (default 2)")
    args = parser.parse_args(argv)
    if args.run is not None:
        if args.cores < 1:
            parser.exit(2, f"error: --cores = {args.cores} must be at least 1\n")
        return main_run(args.run, args.cores)
    if not args.cells:
        parser.exit(2, "error: give --cells (cells of the grid to time) or --run (a finished run to read)\n")
    try:
        grid = load_grid(args.grid)
    except ValueError as exc:
        parser.exit(2, f"error: {exc}\n")
    cells = [c for c in args.cells.split(",") if c]
    unknown = [c for c in cells if c not in grid["cells"]]
    r_grid = int(grid["replicates"])
    if not cells or unknown or not 1 <= args.replicates <= r_grid:
        parser.exit(2, f"error: --cells = {args.cells} must name cells of grid {grid['name']} (unknown: "
                       f"{', '.join(unknown) or 'none'}) and --replicates = {args.replicates} must be in 1…{r_grid}\n")
    load = os.getloadavg()[0]
    cpu, sim = measure(grid, cells, args.replicates)
    trackers = sorted({t for t, _ in cpu})
    per_record = {c: sum(cpu[t, c] for t in trackers) / args.replicates for c in cells}
    n_cells = len(grid["cells"])
    mean_record = sum(per_record.values()) / len(cells)
    total = mean_record * r_grid * n_cells + sum(sim.values()) / len(cells) * n_cells
    lines = [f"# The cost of the `{grid['name']}` grid, from {len(cells)} of its {n_cells} cells", "",
             f"`python -m experiments.benchmarks.tracking_grid_cost --grid {args.grid} --cells {args.cells} "
             f"--replicates {args.replicates}`; load average {load:.1f} at the start (2 cores, shared: noisy).", "",
             "| cell | simulate + bounds, s CPU | all trackers per record, s CPU |", "|---|---|---|"]
    lines += [f"| {c} | {sim[c]:.1f} | {per_record[c]:.1f} |" for c in cells]
    lines += ["", f"Grid estimate: {mean_record:.1f} s per record × {r_grid} replicates × {n_cells} cells + "
              f"simulation = **{total:.0f} s CPU**, about **{total / CORES_BUSY / 60:.1f} min** on 2 cores "
              f"({CORES_BUSY:.2f} cores busy on average, the last whole-grid run's ratio).", "",
              "| tracker | " + " | ".join(cells) + " |", "|---|" + "---|" * len(cells)]
    lines += [f"| {t} | " + " | ".join(f"{cpu[t, c] / args.replicates:.2f}" for c in cells) + " |"
              for t in trackers]
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    from experiments.benchmarks import one_blas_thread, run_with_page

    page = "tracking_grid_run" if "--run" in sys.argv else "tracking_grid_cost"
    with one_blas_thread():
        raise SystemExit(run_with_page(main, page))   # prints, writes results/bench/<page>.md
