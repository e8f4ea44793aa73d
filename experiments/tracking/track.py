"""Log a grid's finished jobs to MLflow in one serial step (safe under parallel workflows).

    python -m experiments.tracking.track --grid smoke --out results/smoke/mlflow_runs.json \
        results/smoke/identify/*/*.csv

One MLflow experiment per grid; one run per (method, cell) job — parameters from the job's own Hydra
config (``results/<grid>/runs/<method>/<cell>/.hydra/config.yaml``), metrics from its result table, the
table as an artifact — and one aggregate run carrying the tables and figures. Run keys make it idempotent:
running it again (or after a kill) logs each run exactly once.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

import pandas as pd
from omegaconf import OmegaConf

from experiments.io import read_npz, write_json
from experiments.jobs.identify import job_params, run_key, scenario_of
from experiments.report.summary import job_metrics, summarize
from experiments.tracking.store import git_commit, log_run


def job_run(grid: str, results_path: Path, commit: str) -> tuple[str, str, bool]:
    method, cell = results_path.parent.name, results_path.stem
    grid_dir = results_path.parent.parent.parent
    cfg = OmegaConf.load(grid_dir / "runs" / method / cell / ".hydra" / "config.yaml")
    method_cfg = OmegaConf.to_container(cfg.method, resolve=True)
    if cfg.get("prior") is not None:
        method_cfg["prior_rad_s"] = list(cfg.prior)
    data = read_npz(cfg.data.dataset)
    table = pd.read_csv(results_path)
    params = job_params(method_cfg, float(data["noise_ug"]), int(data["t_s"].size),
                        int(table["replicate"].nunique()), int(data["seed"]), scenario_of(data))
    key = run_key(grid, method, params["noise_ug"], params["n_samples"], params)
    params["git_commit"] = commit          # logged, but not part of the key: a new commit is not a new result
    rid, created = log_run(f"grid-{grid}", key, params=params, metrics=job_metrics(summarize(table)),
                           artifacts=[results_path], tags={"git_commit": commit, "grid": grid,
                                                           "kind": "job"})
    return key, rid, created


def aggregate_run(grid: str, grid_dir: Path, commit: str) -> tuple[str, str, bool]:
    files = sorted(p for sub in ("tables", "figures") for p in (grid_dir / sub).glob("*") if p.is_file())
    files.append(grid_dir / "README.md")
    digest = hashlib.sha256(b"".join(p.name.encode() + (p.read_bytes() if p.suffix in (".csv", ".md")
                                                         else b"") for p in files)).hexdigest()[:12]
    key = f"{grid}/aggregate/{digest}"
    rid, created = log_run(f"grid-{grid}", key, params={"grid": grid}, artifacts=files,
                           tags={"git_commit": commit, "grid": grid, "kind": "aggregate"})
    return key, rid, created


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", required=True)
    ap.add_argument("--out", required=True, type=Path, help="JSON record of the logged runs")
    ap.add_argument("results", nargs="+", type=Path)
    args = ap.parse_args(argv)
    commit = git_commit()
    runs, created = {}, 0
    for path in sorted(args.results):
        key, rid, new = job_run(args.grid, path, commit)
        runs[key] = rid
        created += new
    grid_dir = args.results[0].parent.parent.parent
    key, rid, new = aggregate_run(args.grid, grid_dir, commit)
    runs[key] = rid
    created += new
    write_json(args.out, {"experiment": f"grid-{args.grid}", "runs": runs})
    print(f"{len(runs)} runs in MLflow experiment grid-{args.grid} ({created} newly logged)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
