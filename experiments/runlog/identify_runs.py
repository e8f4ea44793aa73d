"""Log a grid's finished jobs to MLflow in one serial step, then write the grid's page.

    python -m experiments.runlog.identify_runs --grid smoke --out results/smoke/mlflow_runs.json \
        --summary results/smoke/summary.md --page results/smoke/README.md \
        --aggregate results/smoke/tables results/smoke/figures -- results/smoke/identify/*/*.csv

(the workflow's ``runlog`` rule; installed, the command ``modal-id-runlog``).

    python -m experiments.runlog.identify_runs --grid smoke --jobs-only --out results/smoke/runlog/jobs.json \
        -- results/smoke/identify/*/*.csv

logs the jobs alone, without their grid (the workflow's ``runlog_jobs`` rule, beside the aggregate, which the
grid's run waits for); the step above then finds them logged (one search of the store for all of them) and
only makes them the grid run's children.

One MLflow experiment per grid (``grid-<name>``). The grid is a parent run carrying the tables, figures and
page; each (method, cell) job is a child run: parameters and provenance from the job's own record
``<cell>.json`` written beside its table (resolved config, dataset digest, code version, package
versions), metrics from its table, the dataset as an MLflow dataset input, the resolved config and the table
as artifacts. Run keys cover the dataset's content, the resolved options and the code version, so a changed
result is a new run and running this again (or after a kill, or from another process at the same time)
logs nothing twice. Only the files named on the command line are read, and first any measurement run a
job left waiting for the store (:mod:`experiments.runlog.pending`) is logged.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import pandas as pd

from experiments.cli import ArgumentParser
from experiments.io import atomic_write_text, write_json
from experiments.provenance import canonical_json, digest, git_state
from experiments.runlog.pending import log_all
from experiments.runlog.records import IDENTIFY_SOURCE, config_yaml, job_params, run_key
from experiments.runlog.store import check_store, dataset_entity, finished_runs, log_run, set_parents, source_tags

__all__ = ["IDENTIFY_SOURCE", "run_key", "job_params", "config_yaml", "log_job", "grid_run", "aggregate_files",
           "log_children", "main", "main_as_track"]

def log_job(experiment: str, record: dict, table_path: Path, record_path: Path | None = None,
            parent_run_id: str | None = None) -> tuple[str, str, bool]:
    """Log one identify job on a dataset cell (from its table and its record). Returns (key, id, created)."""
    # imported here: the summary imports scipy.stats (~0.8 s of CPU), and the grid's step, last in the
    # workflow and alone on the machine, finds its jobs logged already and summarises none
    from experiments.report.summary import job_metrics, summarize

    table = pd.read_csv(table_path)
    key = run_key(record)
    ds = record["dataset"]
    artifacts = [table_path] + ([record_path] if record_path else [])
    rid, created = log_run(
        experiment, key, params=job_params(record, table), metrics=job_metrics(summarize(table)),
        artifacts=artifacts, texts={"config.yaml": config_yaml(record)},
        dataset=dataset_entity(ds["name"], ds["digest"], ds["path"], kind="cell", profile=ds.get("settings")),
        tags={**source_tags(IDENTIFY_SOURCE, record["code"]), "grid": record["grid"], "kind": "job",
              "method": record["method"]},
        parent_run_id=parent_run_id)
    return key, rid, created


def grid_run(grid: str, child_keys: list[str], files: list[Path]) -> tuple[str, str, bool]:
    """The grid's parent run, carrying tables and figures: keyed by its jobs' keys (which cover their data,
    options and code) and the commit (the report's code); uncommitted edits make no new grid run unless
    they change a job."""
    code = git_state()
    key = f"{grid}/grid/{digest(canonical_json({'jobs': sorted(child_keys), 'commit': code['commit']}))}"
    rid, created = log_run(f"grid-{grid}", key, params={"grid": grid, "jobs": len(child_keys)}, artifacts=files,
                           tags={**source_tags("Snakefile", code), "grid": grid, "kind": "grid"})
    return key, rid, created


def log_children(experiment: str, jobs: list, log_one, parent_run_id: str | None) -> tuple[dict, int]:
    """Log each of ``jobs`` with ``log_one(job, parent_run_id) -> (key, run id, created)``, except those a
    finished run of the experiment holds already (:func:`experiments.runlog.store.finished_runs`, one search
    for all): those are only made children of ``parent_run_id`` where they are not yet. ``jobs`` are
    (run key, job) pairs. Returns ({key: run id}, how many were newly logged)."""
    known = finished_runs(experiment)
    runs, created, adopt = {}, 0, []
    for key, job in jobs:
        if key in known:
            rid, parent = known[key]
            if parent_run_id and parent != parent_run_id:
                adopt.append(rid)
        else:
            key, rid, new = log_one(job, parent_run_id)
            created += new
        runs[key] = rid
    if adopt:
        set_parents(adopt, parent_run_id)
    return runs, created


def aggregate_files(paths: list[Path]) -> list[Path]:
    out = []
    for p in paths:
        out += sorted(f for f in p.rglob("*") if f.is_file()) if p.is_dir() else [p]
    return out


# What the track step needs of a job: its table's columns and its record's keys.
TABLE_COLUMNS = ("method", "noise_ug", "n_samples", "replicate", "mode", "estimate_rad_s", "error_rad_s")
RECORD_KEYS = ("grid", "method", "config", "dataset", "code", "versions")


def read_job(path: Path) -> tuple[Path, Path, dict]:
    """(table, record path, record) of one identify job; ``ValueError`` (one line) when ``path`` is not a
    job's result table with its record ``<table>.json`` beside it."""
    record_path = path.with_suffix(".json")
    if not path.is_file():
        raise ValueError(f"{path}: no such result table")
    # the header line alone, by the csv module: pandas' reader costs ~4 ms a file to read one line, and the
    # grid's steps check every job's table (560 in the paper grid) before they log anything
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            columns = next(csv.reader(fh), None)
    except (csv.Error, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not a CSV result table ({exc})") from None
    if not columns:
        raise ValueError(f"{path}: not a CSV result table (no header line)")
    missing = [c for c in TABLE_COLUMNS if c not in columns]
    if missing:
        raise ValueError(f"{path}: not an identify job's result table (no column {', '.join(missing)})")
    if not record_path.is_file():
        raise ValueError(f"{path}: the job's record {record_path.name} is missing beside it")
    try:
        record = json.loads(record_path.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise ValueError(f"{record_path}: not a JSON job record ({exc})") from None
    if not isinstance(record, dict) or any(k not in record for k in RECORD_KEYS):
        absent = [k for k in RECORD_KEYS if not isinstance(record, dict) or k not in record]
        raise ValueError(f"{record_path}: not an identify job's record (no {', '.join(absent)})")
    return path, record_path, record


def main(argv=None) -> int:
    ap = ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", required=True)
    ap.add_argument("--out", required=True, type=Path, help="JSON record of the logged runs")
    ap.add_argument("--summary", type=Path, help="the aggregate's page; with --page: copied there, plus "
                                                  "where the runs are in MLflow")
    ap.add_argument("--page", type=Path)
    ap.add_argument("--aggregate", nargs="*", type=Path, default=[],
                    help="tables/figures (files or folders) to log with the grid's parent run")
    ap.add_argument("--jobs-only", action="store_true",
                    help="log the jobs alone, no grid run and no page (the grid's step makes them its children)")
    ap.add_argument("results", nargs="+", type=Path, help="the jobs' tables; <table>.json beside each")
    args = ap.parse_args(argv)
    try:
        check_store()
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    experiment = f"grid-{args.grid}"
    try:
        jobs = [read_job(path) for path in sorted(args.results)]
    except ValueError as exc:              # checked before anything is logged: one line, nothing written
        print(f"error: {exc}", file=sys.stderr)
        return 2

    log_all()       # measurement runs a job left waiting (experiments/runlog/pending.py), if any
    child_keys = [run_key(rec) for _, _, rec in jobs]

    def log_one(job, parent):
        path, record_path, rec = job
        return log_job(experiment, rec, path, record_path, parent_run_id=parent)

    if args.jobs_only:
        runs, created = log_children(experiment, list(zip(child_keys, jobs, strict=True)), log_one, None)
        write_json(args.out, {"experiment": experiment, "runs": runs})
        print(f"{len(runs)} job runs in MLflow experiment {experiment} ({created} newly logged)")
        return 0
    files = aggregate_files(args.aggregate) + ([args.summary] if args.summary else [])
    parent_key, parent_id, created = grid_run(args.grid, child_keys, files)
    children, new = log_children(experiment, list(zip(child_keys, jobs, strict=True)), log_one, parent_id)
    runs = {parent_key: parent_id, **children}
    created += new
    write_json(args.out, {"experiment": experiment, "parent_run": parent_id, "runs": runs})
    message = f"{len(runs)} runs in MLflow experiment {experiment} ({created} newly logged)"
    if args.page:
        summary = args.summary.read_text() if args.summary else ""
        atomic_write_text(args.page, summary.rstrip("\n") + "\n\n## Tracking\n\n"
                          f"MLflow experiment `{experiment}`: one parent run for the grid (tables, figures, "
                          f"this page) with its {len(jobs)} jobs as child runs; run ids in "
                          f"[{args.out.name}]({args.out.name}).\n")
    print(message)
    return 0


def main_as_track() -> int:
    """The console script's old name ``modal-id-track``, until the next release: a note, then :func:`main`."""
    print("note: modal-id-track is now modal-id-runlog; the old name works until the next release", file=sys.stderr)
    return main()


if __name__ == "__main__":
    sys.exit(main())
