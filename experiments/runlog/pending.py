"""MLflow runs logged after the job: a run folder holds everything its run needs, until it is logged.

    python -m experiments.runlog.pending                 # log every run waiting for this store
    python -m experiments.runlog.pending results/runs    # ...and any waiting in run folders under a folder

Importing MLflow and opening its store cost a measurement job more than its answer (2–4 s against 2 s,
``results/bench/measurement.md``). So the job writes its run's description into its run folder —
``mlflow_pending.json``: experiment, run key, parameters, metrics, tags, the dataset, texts and the
artifacts (files of that folder) — adds the folder to the store's queue (a folder ``<store>.pending`` beside
the SQLite file, or beside its lock file for other stores: :func:`queue_dir`), prints its answer and starts
this module as a detached process that it does not wait for. That process logs every run in the queue,
the job's own and any left over, each with :func:`experiments.runlog.store.log_run` (idempotent by run
key, under the store's lock), then renames the folder's ``mlflow_pending.json`` to ``mlflow_run.json``
(with the run's id) and takes the folder off the queue, in that order.

Nothing is lost. Until a run is logged the marker ``mlflow_pending.json`` stays in its folder and the
folder in the queue: a logger killed (even ``kill -9``) before or while logging leaves both, and a run it
left RUNNING is replaced by the next logger (``log_run``'s cut-off rule). The next job's logger, this
command, and the workflow's runlog step (``experiments.runlog.identify_runs``) log what is left. Two loggers at
once (two jobs sharing a store) take turns on the store's lock, and a run key is logged once.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from experiments.io import atomic_write_text
from experiments.provenance import digest
from experiments.runlog.store import check_store, dataset_entity, lock_path, log_run, tracking_uri

__all__ = ["PENDING", "LOGGED", "LOG", "queue_dir", "enqueue", "start_logger", "waiting", "log_folder", "log_all",
           "main"]

PENDING = "mlflow_pending.json"     # in a run folder: its run, not yet logged
LOGGED = "mlflow_run.json"          # ...renamed to this once logged (with the run's id)
LOG = "mlflow_log.txt"              # what the detached logger started by a job printed


def queue_dir(uri: str | None = None) -> Path:
    """The queue of run folders waiting for the store ``uri`` (default :func:`tracking_uri`)."""
    return lock_path(uri or tracking_uri()).with_suffix(".pending")


def enqueue(run_dir: Path, experiment: str, run_key: str, *, params: dict, metrics: dict, tags: dict,
            texts: dict, dataset: dict, artifacts: list[Path]) -> Path:
    """Write ``run_dir/mlflow_pending.json`` (the run, ready to log; ``dataset``: the keyword arguments of
    :func:`experiments.runlog.store.dataset_entity`; ``artifacts``: files in ``run_dir``) and queue the
    folder for the store. Returns the marker's path."""
    run_dir = Path(run_dir).resolve()
    uri = tracking_uri()
    names = []
    for path in artifacts:
        path = Path(path).resolve()
        if path.parent != run_dir:
            raise ValueError(f"artifact {path} is not in the run folder {run_dir}")
        names.append(path.name)
    spec = {"status": "not yet logged to MLflow", "store": uri, "experiment": experiment, "run_key": run_key,
            "params": {k: str(v) for k, v in params.items()},
            "metrics": {k: float(v) for k, v in metrics.items()}, "tags": tags, "texts": texts,
            "dataset": dataset, "artifacts": names}
    marker = atomic_write_text(run_dir / PENDING, json.dumps(spec, indent=2, sort_keys=True) + "\n")
    queue = queue_dir(uri)
    queue.mkdir(parents=True, exist_ok=True)
    atomic_write_text(queue / f"{digest(str(run_dir), 16)}.path", str(run_dir) + "\n")
    return marker


def start_logger(run_dir: Path) -> subprocess.Popen:
    """Start this module as a detached process (own session, output to ``run_dir/mlflow_log.txt``) that logs
    every queued run; the caller does not wait for it."""
    with open(Path(run_dir) / LOG, "ab") as out:
        return subprocess.Popen([sys.executable, "-m", "experiments.runlog.pending"], cwd=os.getcwd(),
                                stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True, close_fds=True)


def waiting(folders: list[Path] = (), uri: str | None = None) -> list[Path]:
    """Run folders with a run waiting: those queued for the store, and any under ``folders``."""
    found = set()
    queue = queue_dir(uri)
    if queue.is_dir():
        for entry in sorted(queue.glob("*.path")):
            try:
                run_dir = Path(entry.read_text().strip())
            except FileNotFoundError:          # taken off the queue by another logger meanwhile
                continue
            if (run_dir / PENDING).is_file():
                found.add(run_dir)
            else:                              # logged (marker renamed) or the folder deleted: off the queue
                if not run_dir.is_dir():
                    print(f"warning: {run_dir}: queued for MLflow but the folder is gone; taken off the queue",
                          file=sys.stderr)
                entry.unlink(missing_ok=True)
    for folder in folders:
        folder = Path(folder).resolve()
        found.update(p.parent for p in ([folder / PENDING] if (folder / PENDING).is_file() else [])
                     + sorted(folder.rglob(PENDING)))
    return sorted(found)


def log_folder(run_dir: Path) -> tuple[str, str, bool] | None:
    """Log the run waiting in ``run_dir``: (run key, run id, newly created), or None when another logger
    logged it meanwhile. Raises ``ValueError`` for a marker written for another store."""

    run_dir = Path(run_dir)
    try:
        spec = json.loads((run_dir / PENDING).read_text())
    except FileNotFoundError:
        return None
    uri = tracking_uri()
    if spec["store"] != uri:
        raise ValueError(f"{run_dir / PENDING}: its run is for the MLflow store {spec['store']}, not {uri}; "
                         f"run this command where that store is the default, or with MLFLOW_TRACKING_URI set")
    missing = [n for n in spec["artifacts"] if not (run_dir / n).is_file()]
    if missing:
        raise ValueError(f"{run_dir}: the run's files {', '.join(missing)} are missing; nothing logged")
    rid, created = log_run(spec["experiment"], spec["run_key"], params=spec["params"], metrics=spec["metrics"],
                           artifacts=[run_dir / n for n in spec["artifacts"]], texts=spec["texts"],
                           dataset=dataset_entity(**spec["dataset"]), tags=spec["tags"])
    # marker renamed first, queue entry removed second: a kill between them leaves an entry that points to
    # a logged folder, which the next logger drops (the other order could lose a run from the queue)
    done = {**spec, "status": "logged to MLflow", "run_id": rid}
    atomic_write_text(run_dir / LOGGED, json.dumps(done, indent=2, sort_keys=True) + "\n")
    (run_dir / PENDING).unlink(missing_ok=True)
    (queue_dir(uri) / f"{digest(str(run_dir.resolve()), 16)}.path").unlink(missing_ok=True)
    return spec["run_key"], rid, created


def log_all(folders: list[Path] = ()) -> tuple[int, int]:
    """Log every waiting run (:func:`waiting`); print a line for each. Returns (logged, failed)."""
    logged = failed = 0
    for run_dir in waiting(folders):
        try:
            out = log_folder(run_dir)
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            failed += 1
            continue
        if out is None:
            continue
        key, rid, created = out
        spec = json.loads((run_dir / LOGGED).read_text())
        print(f"MLflow experiment {spec['experiment']}: run {key} ({'logged' if created else 'already there'}; "
              f"from {run_dir})", flush=True)
        logged += 1
    return logged, failed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="*", type=Path,
                    help="also log runs waiting in run folders under these (mlflow_pending.json)")
    args = ap.parse_args(argv)
    for folder in args.folders:
        if not folder.is_dir():
            print(f"error: {folder}: no such folder", file=sys.stderr)
            return 2

    try:
        check_store()
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    logged, failed = log_all(args.folders)
    if not logged and not failed:
        print(f"no MLflow run waiting for {tracking_uri()}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
