"""How much of a finished grid's time went to numerical work, and how much to the pipeline around it.

    python -m experiments.benchmarks.pipeline results/full [--wall-s 1234]

Reads Snakemake's per-job ``benchmark:`` files (the wall time of each identify job as a whole process) and
the jobs' result tables (the time spent inside ``identify`` for each replicate). The difference is the
pipeline's overhead: interpreter start-up, imports, Hydra composition, file I/O and Snakemake scheduling.
With ``--wall-s`` (the workflow's measured wall time) it also reports the share of the wall time.
"""

from __future__ import annotations

import argparse
import sys
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
    per["overhead_share"] = 1 - per["numeric_s"] / per["job_s"]
    per["median_job_s"] = df.groupby("method")["job_s"].median()
    print(per.to_string(float_format=lambda v: f"{v:.3g}"))
    job, num = df["job_s"].sum(), df["numeric_s"].sum()
    print(f"\nidentify jobs: {len(df)}, job time {job:.0f} s, numerical {num:.0f} s, "
          f"overhead {job - num:.0f} s = {100 * (1 - num / job):.1f} % of job time")
    if args.wall_s:
        busy = args.wall_s * args.cores
        print(f"workflow wall {args.wall_s:.0f} s x {args.cores} cores = {busy:.0f} core-s; numerical work "
              f"{100 * num / busy:.1f} %, everything else (pipeline + idle cores) {100 * (1 - num / busy):.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
