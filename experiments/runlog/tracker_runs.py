"""Log a tracking grid to MLflow in one serial step, then write its page.

    python -m experiments.runlog.tracker_runs --grid tracking --out results/tracking/mlflow_runs.json \
        --summary results/tracking/summary.md --page results/tracking/README.md \
        --aggregate results/tracking/tables results/tracking/figures -- results/tracking/track/*

One MLflow experiment per grid (``grid-<name>``), as for the identification grids
(``experiments.runlog.identify_runs``): the grid is a parent run carrying the tables, figures and page; each
(tracker, cell) is a child run with the tracker's options and the cell's settings as parameters, the cell's
summary (``tracking_metrics.summarize_cell``) as metrics, its scores table as an artifact and the records as
its dataset input. A run's key covers the records' content, the options and the code version, so running
this again logs nothing twice. With ``--jobs-only`` (and no ``--summary``/``--page``) it logs the (tracker, cell)
runs alone, as the workflow does beside the report (rule ``tracking_runlog_jobs``); the grid's step then finds
them logged and only makes them its children (``experiments.runlog.identify_runs.log_children``).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pandas as pd

from experiments.cli import ArgumentParser, cpu_line
from experiments.io import atomic_write_text, write_json
from experiments.provenance import canonical_json, digest, git_state
from experiments.report.tracking_metrics import summarize_cell
from experiments.runlog.identify_runs import aggregate_files, log_children
from experiments.runlog.store import dataset_entity, log_run, source_tags

__all__ = ["SOURCE", "log_cell", "main", "run_key"]

SOURCE = "experiments/jobs/track_job.py"


def run_key(record: dict) -> str:
    return f"{record['grid']}/{record['tracker']}/{record['cell']['cell']}/{record['run_key_digest']}"


def log_cell(experiment: str, record: dict, table_path: Path, parent_run_id: str | None) -> tuple[str, str, bool]:
    table = pd.read_csv(table_path)
    has_step = table["t_reconverge_s"].notna().any()
    metrics = {k: float(v) for k, v in summarize_cell(table, has_step=has_step).items()
               if isinstance(v, (int, float, bool))}
    params = {"tracker": record["tracker"], **{f"cell.{k}": v for k, v in record["cell"].items()},
              **{f"option.{k}": v for k, v in record["options"].items()},
              "dataset_digest": record["dataset"]["digest"], "git_commit": record["code"]["commit"]}
    key = run_key(record)
    ds = record["dataset"]
    rid, created = log_run(experiment, key, params=params, metrics=metrics, artifacts=[table_path],
                           dataset=dataset_entity(ds["name"], ds["digest"], ds["name"], kind="tracking cell"),
                           tags={**source_tags(SOURCE, record["code"]), "grid": record["grid"], "kind": "job",
                                 "tracker": record["tracker"]},
                           parent_run_id=parent_run_id)
    return key, rid, created


def main(argv=None) -> int:
    ap = ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", required=True)
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--summary", type=Path, help="the report's page (required unless --jobs-only)")
    ap.add_argument("--page", type=Path, help="the grid's page to write (required unless --jobs-only)")
    ap.add_argument("--aggregate", nargs="*", type=Path, default=[])
    ap.add_argument("--jobs-only", action="store_true",
                    help="log the (tracker, cell) runs alone, no grid run and no page")
    ap.add_argument("results", nargs="+", type=Path, help="the trackers' folders")
    args = ap.parse_args(argv)
    if not args.jobs_only and (args.summary is None or args.page is None):
        ap.error("--summary and --page are required (unless --jobs-only)")
    experiment = f"grid-{args.grid}"
    jobs = []
    for folder in args.results:
        for rec_path in sorted(folder.glob("*.json")):
            jobs.append((rec_path.with_suffix(".csv"), json.loads(rec_path.read_text())))
    keys = [run_key(rec) for _, rec in jobs]

    def log_one(job, parent):
        table_path, rec = job
        return log_cell(experiment, rec, table_path, parent)

    if args.jobs_only:
        runs, created = log_children(experiment, list(zip(keys, jobs, strict=True)), log_one, None)
        write_json(args.out, {"experiment": experiment, "runs": runs})
        print(f"{len(runs)} (tracker, cell) runs in MLflow experiment {experiment} ({created} newly logged)")
        print(cpu_line())
        return 0
    code = git_state()
    parent_key = f"{args.grid}/grid/{digest(canonical_json({'jobs': sorted(keys), 'commit': code['commit']}))}"
    files = aggregate_files(args.aggregate) + [args.summary]
    parent_id, created = log_run(experiment, parent_key, params={"grid": args.grid, "jobs": len(jobs)},
                                 artifacts=files, tags={**source_tags("Snakefile", code), "grid": args.grid,
                                                        "kind": "grid"})
    children, new = log_children(experiment, list(zip(keys, jobs, strict=True)), log_one, parent_id)
    runs = {parent_key: parent_id, **children}
    created += new
    write_json(args.out, {"experiment": experiment, "parent_run": parent_id, "runs": runs})
    atomic_write_text(args.page, args.summary.read_text().rstrip("\n") + "\n\n## Tracking\n\n"
                      f"MLflow experiment `{experiment}`: one parent run for the grid (tables, figures, this page) "
                      f"with its {len(jobs)} (tracker, cell) runs as children; run ids in "
                      f"[{args.out.name}]({args.out.name}).\n")
    print(f"{len(runs)} runs in MLflow experiment {experiment} ({created} newly logged)")
    print(cpu_line())
    return 0


if __name__ == "__main__":
    sys.exit(main())
