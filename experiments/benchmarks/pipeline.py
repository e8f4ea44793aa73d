"""How much of a finished grid's time went to numerical work, and how much to the pipeline around it.

    python -m experiments.benchmarks.pipeline results/full [--wall-s 1234]

Reads Snakemake's ``benchmark:`` files (the wall time of each job as a whole process: the datasets batch of
the grid and one identify batch per method, experiments/workflow/rules/; a batch run by W worker processes counts
W × its wall time, the cores it held) and the jobs' result tables (the time spent
inside ``identify`` for each replicate). The difference is the pipeline's overhead: interpreter start-up,
imports, Hydra composition, file I/O. With ``--wall-s`` (the workflow's measured wall time) it also reports
the share of the wall time, including Snakemake's own scheduling and the serial aggregate and track steps.

Part of every job's start-up is not the pipeline's but the method's own: importing its numerical libraries
(``scipy.signal`` alone takes ~0.7 s here). That cost is measured per method (median of 5 fresh
interpreters) and reported separately, so the pipeline's own share (Snakemake, Hydra, file I/O) is explicit.
Grids made before the batches (one process per method and cell: ``benchmarks/identify/<method>/<cell>.tsv``)
are read too, so a before/after comparison uses this one command.
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

import methods

__all__ = ["measure", "batch_workers", "dataset_job_s", "import_cost_s", "main"]


def _numeric_s(table: Path) -> float:
    res = pd.read_csv(table)
    return float(res.drop_duplicates("replicate")["runtime_s"].sum())


def measure(grid_dir: Path) -> pd.DataFrame:
    """One row per identify job: its method, wall time as a process, and the time inside ``identify``."""
    rows = []
    bench = grid_dir / "benchmarks" / "identify"
    for tsv in sorted(bench.glob("*.tsv")):                     # a batch: one method, every cell
        method = tsv.stem
        workers = batch_workers(grid_dir / "logs" / "identify" / f"{method}.log")
        job_s = workers * float(pd.read_csv(tsv, sep="\t")["s"].iloc[0])
        tables = sorted((grid_dir / "identify" / method).glob("*.csv"))
        rows.append({"method": method, "cells": len(tables), "workers": workers, "job_s": job_s,
                     "numeric_s": sum(_numeric_s(t) for t in tables)})
    for tsv in sorted(bench.glob("*/*.tsv")):                   # one process per (method, cell)
        method, cell = tsv.parent.name, tsv.stem
        job_s = float(pd.read_csv(tsv, sep="\t")["s"].iloc[0])
        rows.append({"method": method, "cells": 1, "workers": 1, "job_s": job_s,
                     "numeric_s": _numeric_s(grid_dir / "identify" / method / f"{cell}.csv")})
    return pd.DataFrame(rows)


def batch_workers(log: Path) -> int:
    """The worker processes of an identify batch, from the last line of its log ("... (2 workers)"); 1 for
    batches without workers. A batch's job time is its wall time x its workers: the cores it held."""
    match = re.search(r"\((\d+) workers?\)\s*$", log.read_text()) if log.exists() else None
    return int(match.group(1)) if match else 1


def dataset_job_s(grid_dir: Path) -> float:
    """Wall time of the dataset jobs (the batch, or one process per cell in grids made before it)."""
    files = [grid_dir / "benchmarks" / "datasets.tsv"] + sorted((grid_dir / "benchmarks" / "dataset").glob("*.tsv"))
    return sum(float(pd.read_csv(f, sep="\t")["s"].iloc[0]) for f in files if f.exists())


def import_cost_s(method: str, runs: int = 5) -> float:
    """Median wall time of a fresh interpreter importing the method's module, minus a bare interpreter."""
    def median(code):
        times = []
        for _ in range(runs):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", code], check=True)
            times.append(time.perf_counter() - t0)
        return statistics.median(times)
    return median(f"import {methods.module_name(method)}") - median("pass")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("grid_dir", type=Path)
    ap.add_argument("--wall-s", type=float, default=None, help="measured wall time of the whole workflow")
    ap.add_argument("--cores", type=int, default=2)
    args = ap.parse_args(argv)
    df = measure(args.grid_dir)
    if df.empty:
        print(f"error: no benchmark files under {args.grid_dir}/benchmarks/identify", file=sys.stderr)
        return 2
    per = df.groupby("method")[["cells", "job_s", "numeric_s"]].sum()
    per["jobs"] = df.groupby("method").size()
    per["workers"] = df.groupby("method")["workers"].max()
    per["import_s_per_job"] = [import_cost_s(m) for m in per.index]
    per["import_s"] = per["import_s_per_job"] * per["jobs"]
    per["pipeline_s"] = per["job_s"] - per["numeric_s"] - per["import_s"]
    per["median_job_s"] = df.groupby("method")["job_s"].median()
    print(per.to_string(float_format=lambda v: f"{v:.3g}"))
    job, num, imp = df["job_s"].sum(), df["numeric_s"].sum(), per["import_s"].sum()
    pipe = job - num - imp
    print(f"\nidentify jobs: {len(df)}; job time {job:.0f} s = numerical {num:.0f} s + library imports {imp:.0f} s "
          f"+ pipeline (Snakemake, Hydra, I/O) {pipe:.0f} s")
    print(f"everything but the numerical work: {100 * (1 - num / job):.1f} % of job time; "
          f"the pipeline's own part: {100 * pipe / job:.1f} %")
    data_s = dataset_job_s(args.grid_dir)
    print(f"dataset jobs: {data_s:.0f} s (simulation and start-up; not counted above)")
    if args.wall_s:
        busy = args.wall_s * args.cores
        idle = busy - job - data_s
        print(f"workflow wall {args.wall_s:.0f} s x {args.cores} cores = {busy:.0f} core-s: "
              f"numerical {100 * num / busy:.1f} %, imports {100 * imp / busy:.1f} %, "
              f"pipeline in jobs {100 * pipe / busy:.1f} %, dataset jobs {100 * data_s / busy:.1f} %, "
              f"scheduling and idle cores {100 * idle / busy:.1f} %")
    return 0


if __name__ == "__main__":
    from experiments.benchmarks import run_with_page

    raise SystemExit(run_with_page(main, "pipeline"))   # prints, and writes results/bench/pipeline.md
