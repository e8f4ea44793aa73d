"""How much of a finished grid's time went to numerical work, and how much to the pipeline around it.

    python -m experiments.benchmarks.pipeline results/full [--wall-s 1234]

Reads Snakemake's per-job ``benchmark:`` files (the wall time of each identify job as a whole process) and
the jobs' result tables (the time spent inside ``identify`` for each replicate). The difference is the
pipeline's overhead: interpreter start-up, imports, Hydra composition, file I/O and Snakemake scheduling.
With ``--wall-s`` (the workflow's measured wall time) it also reports the share of the wall time.

Part of every job's start-up is not the pipeline's but the method's own: importing its numerical libraries
(``scipy.signal`` alone takes ~0.7 s here). That cost is measured per method (median of 5 fresh
interpreters) and reported separately, so the pipeline's own share (Snakemake, Hydra, file I/O) is explicit.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd


def measure(grid_dir: Path) -> pd.DataFrame:
    rows = []
    for tsv in sorted((grid_dir / "benchmarks" / "identify").glob("*/*.tsv")):
        method, cell = tsv.parent.name, tsv.stem
        job_s = float(pd.read_csv(tsv, sep="\t")["s"].iloc[0])
        res = pd.read_csv(grid_dir / "identify" / method / f"{cell}.csv")
        numeric_s = float(res.drop_duplicates("replicate")["runtime_s"].sum())
        rows.append({"method": method, "cell": cell, "job_s": job_s, "numeric_s": numeric_s})
    return pd.DataFrame(rows)


def import_cost_s(method: str, runs: int = 5) -> float:
    """Median wall time of a fresh interpreter importing the method's module, minus a bare interpreter."""
    def median(code):
        times = []
        for _ in range(runs):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", code], check=True)
            times.append(time.perf_counter() - t0)
        return statistics.median(times)
    return median(f"import methods.{method}") - median("pass")


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
    per = df.groupby("method")[["job_s", "numeric_s"]].sum()
    per["jobs"] = df.groupby("method").size()
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
    if args.wall_s:
        busy = args.wall_s * args.cores
        idle = busy - job
        print(f"workflow wall {args.wall_s:.0f} s x {args.cores} cores = {busy:.0f} core-s: "
              f"numerical {100 * num / busy:.1f} %, imports {100 * imp / busy:.1f} %, "
              f"pipeline in jobs {100 * pipe / busy:.1f} %, "
              f"scheduling and idle cores {100 * idle / busy:.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
