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
"""

from __future__ import annotations

import argparse
import os
import time

from experiments.jobs.track_job import check_tracker, grid_trackers, track_record, warm_up
from experiments.simulate.laboratory import LaboratoryCellConfig, make_lab_cell
from experiments.simulate.tracking_data import make_cell
from experiments.simulate.tracking_grid import load_grid

__all__ = ["CORES_BUSY", "main", "measure"]

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


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", default="tracking")
    parser.add_argument("--cells", required=True, help="comma-separated cell names of the grid")
    parser.add_argument("--replicates", type=int, default=1)
    args = parser.parse_args(argv)
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

    with one_blas_thread():
        raise SystemExit(run_with_page(main, "tracking_grid_cost"))   # prints, writes results/bench/<name>.md
