"""MLflow run logging with an embedded default, safe under concurrent processes, with idempotent runs.

Default store: SQLite at ``results/mlflow.db`` with artifacts under ``results/mlartifacts/<experiment>``
(no server); ``MLFLOW_TRACKING_URI`` in the environment wins (a server, PostgreSQL, ...). A run is
identified by a *run key* (tag ``run_key``): logging the same key again is a no-op when a finished run holds
it, and replaces a run that was cut off part-way (killed job).

Concurrency. MLflow creates and migrates its database schema on the first connection; two processes doing
that at once on a fresh SQLite file leave it half-migrated for good (``table _alembic_tmp_tags already
exists``), and a search-then-create of a run key is not atomic. MLflow's answer for concurrent writers is a
tracking server; without one, every process here takes an inter-process file lock (``filelock``) around the
first connection and around each run's search-create-log, so the store is initialised once and each key
is logged once. The lock file sits beside the SQLite file, or under ``results/`` for other stores (shared
by the processes of one project folder, e.g. the jobs of a workflow). Writers in other folders or on other
machines (a shared server) share no lock: there each run, once finished, looks for others with its key and
the earliest-started one stays (a run that finds an earlier one deletes itself), and a run left RUNNING is
taken for cut off only when its owner process (tag ``owner``, host:pid) is known to be gone.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import socket
import sqlite3
import tempfile
import time
from pathlib import Path
from urllib.parse import unquote, urlparse

from filelock import FileLock

from experiments.provenance import digest, git_state

__all__ = ["DEFAULT_DB", "LOCK_TIMEOUT_S", "tracking_uri", "is_default_store", "lock_path", "store_lock", "client",
           "experiment_id", "log_run", "finished_runs", "set_parents", "dataset_entity", "source_tags",
           "git_commit"]

DEFAULT_DB = Path("results") / "mlflow.db"   # relative to the working directory, like all outputs
LOCK_TIMEOUT_S = 600


def tracking_uri() -> str:
    uri = os.environ.get("MLFLOW_TRACKING_URI")
    if uri:
        return uri
    DEFAULT_DB.parent.mkdir(parents=True, exist_ok=True)
    return f"sqlite:///{DEFAULT_DB.resolve()}"


_SQLITE_MAGIC = b"SQLite format 3\x00"


def sqlite_path(uri: str) -> Path | None:
    """The file of a ``sqlite:///`` store (None for other stores and in-memory SQLite)."""
    if uri.startswith("sqlite:///") and ":memory:" not in uri:
        return Path(unquote(urlparse(uri).path[1:]))
    return None


def check_store(uri: str | None = None) -> None:
    """Refuse, before any work, a SQLite store that exists but is empty, truncated or corrupt.

    MLflow would rebuild an empty file silently (every run it held gone without a word) and fail on a
    truncated one with a long traceback after the job's outputs are written. Neither is repaired here:
    the file is left as it is, and the message says how to go on. Raises ``ValueError`` (one line).
    Checks: the SQLite header, the database size the header records against the file's size (what a
    truncation breaks), and SQLite's own ``PRAGMA quick_check``.
    """
    uri = uri or tracking_uri()
    path = sqlite_path(uri)
    if path is None or not path.exists():
        return                                     # a server, or a store to be created: nothing to check
    with store_lock(uri):        # another process may be creating the store this instant (0 bytes for now)
        _check_sqlite(path)


# (path, size, mtime) of store files this process found sound: a job checks before any work and again when
# it opens the client, and PRAGMA quick_check reads the whole file; an unchanged file is not read twice.
_SOUND: set[tuple[str, int, int]] = set()


def _check_sqlite(path: Path) -> None:
    stat = path.stat()
    state = (str(path.resolve()), stat.st_size, stat.st_mtime_ns)
    if state in _SOUND:
        return
    _check_sqlite_file(path)
    _SOUND.add(state)


def _check_sqlite_file(path: Path) -> None:
    way_out = (f"move it aside (mv {path} {path}.broken) to start a fresh store, point MLFLOW_TRACKING_URI to "
               f"another store, or run with runlog.enabled=false")
    size = path.stat().st_size
    if size == 0:
        raise ValueError(f"the MLflow store {path} is empty (0 bytes): it is not rebuilt silently, since the "
                         f"runs it held would be lost without a word; {way_out}")
    with open(path, "rb") as f:
        header = f.read(100)
    if len(header) < 100 or not header.startswith(_SQLITE_MAGIC):
        raise ValueError(f"the MLflow store {path} is not an SQLite database ({size} bytes, no SQLite header); "
                         f"{way_out}")
    page_size = int.from_bytes(header[16:18], "big")
    page_size = 65536 if page_size == 1 else page_size
    pages = int.from_bytes(header[28:32], "big")
    if pages and pages * page_size > size:
        raise ValueError(f"the MLflow store {path} is truncated ({size} bytes; its header records "
                         f"{pages * page_size}); {way_out}")

    try:
        with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=30)) as db:
            verdict = db.execute("PRAGMA quick_check(1)").fetchone()[0]
    except sqlite3.DatabaseError as exc:
        raise ValueError(f"the MLflow store {path} cannot be read ({exc}); {way_out}") from None
    if verdict != "ok":
        raise ValueError(f"the MLflow store {path} is corrupt (SQLite: {verdict}); {way_out}")


def is_default_store(uri: str) -> bool:
    return not os.environ.get("MLFLOW_TRACKING_URI") and uri == tracking_uri()


def lock_path(uri: str) -> Path:
    """The lock file that serialises this project's writers to the store ``uri``."""
    db = sqlite_path(uri)            # sqlite:///relative.db or sqlite:////absolute.db (SQLAlchemy's forms)
    if db is not None:
        path = Path(f"{db}.lock")
    else:
        path = DEFAULT_DB.parent / f".mlflow-{digest(uri, 12)}.lock"
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


@contextlib.contextmanager
def store_lock(uri: str):
    with FileLock(str(lock_path(uri)), timeout=LOCK_TIMEOUT_S):
        yield


_CLIENTS: dict[str, object] = {}


def client(uri: str | None = None):
    """An ``MlflowClient`` on ``uri`` (default :func:`tracking_uri`), its store created under the lock.

    ``mlflow.set_tracking_uri`` is not used: it sets ``MLFLOW_TRACKING_URI`` in the environment, which would
    then hide whether the default store is in use.
    """
    uri = uri or tracking_uri()
    if uri not in _CLIENTS:
        import mlflow  # imported here: ~2 s, and only the runlog steps need it

        with store_lock(uri):            # the client may open the store on construction (tracing)
            path = sqlite_path(uri)
            if path is not None and path.exists():
                _check_sqlite(path)      # never let MLflow rebuild an emptied store or trip on a broken one
            c = mlflow.MlflowClient(tracking_uri=uri)
            _retry(lambda: c.search_experiments(max_results=1))   # creates/migrates the schema, once
        _CLIENTS[uri] = c
    return _CLIENTS[uri]


def _retry(fn, attempts: int = 8):
    """Retry a store call that failed on a transient condition (SQLite busy under a foreign writer)."""
    delay = 0.2
    for i in range(attempts):
        try:
            return fn()
        except Exception as exc:  # noqa: BLE001 - MLflow wraps SQLite errors in several types
            transient = any(s in str(exc).lower() for s in ("locked", "busy"))
            if not transient or i == attempts - 1:
                raise
            time.sleep(delay)
            delay *= 2


def experiment_id(c, name: str, uri: str) -> str:
    """The id of experiment ``name``, created if needed (called under the store lock)."""
    exp = _retry(lambda: c.get_experiment_by_name(name))
    if exp is not None:
        if exp.lifecycle_stage == "deleted":
            _retry(lambda: c.restore_experiment(exp.experiment_id))
        return exp.experiment_id
    artifact_root = None
    if is_default_store(uri):
        artifact_root = (DEFAULT_DB.parent.resolve() / "mlartifacts" / name).as_uri()
    return _retry(lambda: c.create_experiment(name, artifact_location=artifact_root))


def log_run(experiment: str, run_key: str, *, params: dict | None = None, metrics: dict | None = None,
            artifacts: list | None = None, tags: dict | None = None, texts: dict | None = None,
            dataset=None, parent_run_id: str | None = None) -> tuple[str, bool]:
    """Log one run unless a finished run with ``run_key`` exists. Returns (run_id, created).

    ``texts`` maps artifact file names to text (e.g. the resolved config); ``dataset`` is an
    ``mlflow.entities.Dataset`` logged as the run's input; ``parent_run_id`` makes it a child run (an
    existing run with the key is moved under that parent).
    """
    from mlflow.entities import DatasetInput, InputTag, Metric, Param  # mlflow: ~2 s, runlog steps only

    uri = tracking_uri()
    c = client(uri)
    all_tags = {"run_key": run_key, "owner": _OWNER, **(tags or {})}
    if parent_run_id:
        all_tags["mlflow.parentRunId"] = parent_run_id
    with store_lock(uri):
        exp_id = experiment_id(c, experiment, uri)
        existing = _retry(lambda: c.search_runs([exp_id], filter_string=f"tags.run_key = '{run_key}'"))
        foreign = False          # a live writer that does not share the lock is logging this key
        for run in existing:
            if run.info.status == "FINISHED":
                if parent_run_id and run.data.tags.get("mlflow.parentRunId") != parent_run_id:
                    _retry(lambda r=run: c.set_tag(r.info.run_id, "mlflow.parentRunId", parent_run_id))
                return run.info.run_id, False
            if _owner_gone(run):
                _retry(lambda r=run: c.delete_run(r.info.run_id))  # cut off part-way
            else:
                foreign = True
        run = _retry(lambda: c.create_run(exp_id, tags=all_tags, run_name=run_key.replace("/", "_")[-250:]))
        rid = run.info.run_id
        now = int(time.time() * 1000)
        _retry(lambda: c.log_batch(
            rid,
            metrics=[Metric(k, float(v), now, 0) for k, v in (metrics or {}).items() if v == v],
            params=[Param(k, str(v)[:6000]) for k, v in (params or {}).items()]))
        if dataset is not None:
            _retry(lambda: c.log_inputs(rid, datasets=[DatasetInput(
                dataset, tags=[InputTag("mlflow.data.context", "evaluation")])]))
        if texts or artifacts:
            # one log_artifacts of a folder holding them all: each log_text / log_artifact call looks the
            # run up in the store again (a third of a grid's logging time went to those look-ups); the same
            # files at the run's artifact root, a later one of the same name replacing an earlier one
            with tempfile.TemporaryDirectory() as folder:
                for name, text in (texts or {}).items():
                    Path(folder, name).write_text(text, encoding="utf-8")
                for path in artifacts or []:
                    shutil.copyfile(path, Path(folder, Path(path).name))
                _retry(lambda: c.log_artifacts(rid, folder))
        _retry(lambda: c.set_terminated(rid, "FINISHED"))
        _retry(lambda: c.delete_tag(rid, "owner"))        # only a RUNNING run needs it
        # a writer from another folder (no shared lock) may have logged the same key meanwhile; a SQLite store's
        # lock sits beside its file, so every writer of this module shares it, and only a writer seen logging
        # this key without the lock (a RUNNING run of a live owner, above) can have (one search less per run)
        if foreign or sqlite_path(uri) is None:
            same = _retry(lambda: c.search_runs([exp_id], filter_string=f"tags.run_key = '{run_key}'"))
            live = [r for r in same if r.info.status in ("RUNNING", "FINISHED")]
            first = min(live, key=lambda r: (r.info.start_time, r.info.run_id))
            if first.info.run_id != rid:
                _retry(lambda: c.delete_run(rid))
                return first.info.run_id, False
    return rid, True


def finished_runs(experiment: str) -> dict[str, tuple[str, str | None]]:
    """Run key -> (run id, parent run id or None) of every finished run of ``experiment`` ({} if there is no
    such experiment), the earliest-started run of a key, as :func:`log_run` keeps it. One paged search, where
    a step that logs a grid's runs would otherwise search the store once per run: the runs it finds here are
    logged already, and :func:`log_run` decides for the others."""
    uri = tracking_uri()
    c = client(uri)
    exp = _retry(lambda: c.get_experiment_by_name(experiment))
    if exp is None:
        return {}
    found: dict[str, tuple[str, str | None]] = {}
    token = None
    while True:
        page = _retry(lambda t=token: c.search_runs(
            [exp.experiment_id], filter_string="attributes.status = 'FINISHED'", max_results=SEARCH_PAGE,
            order_by=["attributes.start_time ASC"], page_token=t))
        for run in page:
            key = run.data.tags.get("run_key")
            if key and key not in found:
                found[key] = (run.info.run_id, run.data.tags.get("mlflow.parentRunId"))
        token = page.token
        if not token:
            return found


SEARCH_PAGE = 1000      # runs per page of finished_runs' search (MLflow's default page)


def set_parents(run_ids: list[str], parent_run_id: str) -> None:
    """Make each logged run of ``run_ids`` a child of ``parent_run_id`` (MLflow's tag ``mlflow.parentRunId``, the
    tag :func:`log_run` gives a child run): a grid's jobs are logged as they finish, its parent run after its
    tables and figures. One hold of the store lock for all (a grid's step adopts its 560 jobs at once)."""
    uri = tracking_uri()
    c = client(uri)
    with store_lock(uri):
        for run_id in run_ids:
            _retry(lambda r=run_id: c.set_tag(r, "mlflow.parentRunId", parent_run_id))


_OWNER = f"{socket.gethostname()}:{os.getpid()}"


def _owner_gone(run) -> bool:
    """Whether the process that created a RUNNING run is known to have ended (on this host; an owner on
    another host is taken for alive, and a run without an owner tag for cut off)."""
    owner = run.data.tags.get("owner")
    if not owner:
        return True
    host, _, pid = owner.rpartition(":")
    if host != socket.gethostname():
        return False
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return True
    except (PermissionError, ValueError):
        return False
    return int(pid) == os.getpid()    # our own leftover (an earlier attempt in this process)


def dataset_entity(name: str, digest_: str, source: str, *, kind: str, profile: dict | None = None):
    """An MLflow dataset (name, digest, source) for ``log_run(dataset=...)``."""
    from mlflow.entities import Dataset  # mlflow: ~2 s, runlog steps only

    return Dataset(name=name, digest=digest_[:36], source_type="local",
                   source=json.dumps({"uri": str(source)}),
                   schema=json.dumps({"kind": kind}), profile=json.dumps(profile or {}))


def source_tags(entry_point: str, code: dict) -> dict:
    """MLflow's standard source tags (and the tree's dirty flag) for a run produced by ``entry_point``."""
    tags = {"mlflow.source.name": entry_point, "mlflow.source.type": "LOCAL",
            "git_dirty": str(bool(code.get("dirty"))).lower()}
    if code.get("commit", "unknown") != "unknown":
        tags["mlflow.source.git.commit"] = code["commit"]
    return tags


def git_commit() -> str:
    """The commit of the code (``unknown`` outside a git checkout), ``+dirty`` if tracked files changed."""
    state = git_state()
    return state["commit"] + ("+dirty" if state["dirty"] else "")
