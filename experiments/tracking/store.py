"""MLflow tracking with an embedded default and idempotent runs.

Default store: SQLite at ``results/mlflow.db`` (no server); ``MLFLOW_TRACKING_URI`` in the environment wins.
A run is identified by a *run key* (tag ``run_key``): logging the same key again is a no-op when a finished
run holds it, and replaces a run that was cut off part-way (killed job). SQLite refuses concurrent writers
("database is locked") and experiment creation races between processes: both are retried, and in the
Snakemake workflow all logging happens in one serial step, so parallel jobs never write at the same time.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_DB = Path("results") / "mlflow.db"   # relative to the working directory, like all outputs


def tracking_uri() -> str:
    uri = os.environ.get("MLFLOW_TRACKING_URI")
    if uri:
        return uri
    DEFAULT_DB.parent.mkdir(parents=True, exist_ok=True)
    return f"sqlite:///{DEFAULT_DB.resolve()}"


def _client():
    import mlflow  # imported here: ~2 s, and only the tracking steps need it

    mlflow.set_tracking_uri(tracking_uri())
    return mlflow.MlflowClient()


def _retry(fn, attempts: int = 8):
    delay = 0.2
    for i in range(attempts):
        try:
            return fn()
        except Exception as exc:  # noqa: BLE001 - MLflow wraps SQLite errors in several types
            transient = any(s in str(exc).lower() for s in ("locked", "already exists", "unique constraint",
                                                             "busy"))
            if not transient or i == attempts - 1:
                raise
            time.sleep(delay)
            delay *= 2


def experiment_id(client, name: str) -> str:
    def get_or_create():
        exp = client.get_experiment_by_name(name)
        if exp is not None:
            if exp.lifecycle_stage == "deleted":
                client.restore_experiment(exp.experiment_id)
            return exp.experiment_id
        artifact_root = None
        if tracking_uri().startswith("sqlite:///") and "MLFLOW_TRACKING_URI" not in os.environ:
            artifact_root = (DEFAULT_DB.parent.resolve() / "mlartifacts" / name).as_uri()
        return client.create_experiment(name, artifact_location=artifact_root)
    return _retry(get_or_create)


def log_run(experiment: str, run_key: str, *, params: dict | None = None, metrics: dict | None = None,
            artifacts: list | None = None, tags: dict | None = None) -> tuple[str, bool]:
    """Log one run unless a finished run with ``run_key`` exists. Returns (run_id, created)."""
    from mlflow.entities import Metric, Param, RunTag

    client = _client()
    exp_id = experiment_id(client, experiment)
    existing = _retry(lambda: client.search_runs([exp_id], filter_string=f"tags.run_key = '{run_key}'"))
    for run in existing:
        if run.info.status == "FINISHED":
            return run.info.run_id, False
        _retry(lambda r=run: client.delete_run(r.info.run_id))      # a run cut off part-way
    all_tags = {"run_key": run_key, **(tags or {})}
    run = _retry(lambda: client.create_run(exp_id, tags=all_tags, run_name=run_key.replace("/", "_")))
    rid = run.info.run_id
    now = int(time.time() * 1000)
    _retry(lambda: client.log_batch(
        rid,
        metrics=[Metric(k, float(v), now, 0) for k, v in (metrics or {}).items() if v == v],
        params=[Param(k, str(v)[:6000]) for k, v in (params or {}).items()],
        tags=[RunTag(k, str(v)) for k, v in all_tags.items()]))
    for path in artifacts or []:
        _retry(lambda p=path: client.log_artifact(rid, str(p)))
    _retry(lambda: client.set_terminated(rid, "FINISHED"))
    return rid, True


def git_commit() -> str:
    """The commit of the working tree (``unknown`` outside a git checkout), '+dirty' if modified."""
    import subprocess

    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                             check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                               capture_output=True, text=True, check=True).stdout.strip()
        return sha + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
