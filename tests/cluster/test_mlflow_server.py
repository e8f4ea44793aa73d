"""The workflow logs to a shared MLflow server on PostgreSQL (`./run.sh mlflow-server`) with no code change.

A private PostgreSQL (Debian's package; installed with apt-get when missing, as root) holds the server's
backend store; the server is started by the documented command. The smoke grid's results (the shared local
run) are logged by the workflow's own tracking step with MLFLOW_TRACKING_URI pointing at the server. Checks:
every run of the grid is on the server once; a rerun of the tracking step adds nothing; two copies of the grid
logging at the same time from two folders (no shared file lock: only the server sees both) lose nothing and
duplicate nothing; and the runs read back through MlflowClient equal those of the local SQLite store (run
keys, parameters, metrics, and the tags that are not about when or where a run was made).
"""

import json
import os
import shutil
import signal
import subprocess
import time
import urllib.request
from pathlib import Path

import mlflow
import pytest
from _postgres import Postgres, free_port, unavailable
from _smoke import ROOT, snakemake, start_snakemake

pytestmark = pytest.mark.slow
GRID = "smoke"
# tags that say when/where/by whom a run was made, or which file holds it: they differ between two stores
PLACE_TAGS = ("mlflow.user", "mlflow.source.name", "mlflow.runName", "mlflow.log-model.history",
              "mlflow.parentRunId")


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    reason = unavailable()
    if reason:
        pytest.skip(reason)
    pg = Postgres().start()
    port = free_port()
    artifacts = tmp_path_factory.mktemp("artifacts")
    log = open(tmp_path_factory.mktemp("server") / "server.log", "w+")
    proc = subprocess.Popen(["bash", str(ROOT / "run.sh"), "mlflow-server", pg.url, "--host", "127.0.0.1",
                             "--port", str(port), "--workers", "2", "--artifacts-destination", str(artifacts)],
                            stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    uri = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 600
        while True:
            try:
                if urllib.request.urlopen(f"{uri}/health", timeout=5).status == 200:
                    break
            except OSError:
                pass
            log.seek(0)
            assert proc.poll() is None and time.monotonic() < deadline, log.read()[-3000:]
            time.sleep(1)
        yield uri
    finally:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(timeout=60)
        pg.stop()


def copy_without_tracking(run: Path, workdir: Path) -> Path:
    """A finished smoke run without its tracking outputs and store: the workflow will log it again."""
    shutil.copytree(run, workdir, symlinks=True)
    for name in ("mlflow_runs.json", "README.md"):
        (workdir / "results" / GRID / name).unlink(missing_ok=True)
    (workdir / "results" / "mlflow.db").unlink(missing_ok=True)
    return workdir


def runs_by_key(uri):
    client = mlflow.MlflowClient(uri)
    exp = client.get_experiment_by_name(f"grid-{GRID}")
    runs = client.search_runs([exp.experiment_id], max_results=5000)
    by_key = {}
    for r in runs:
        by_key.setdefault(r.data.tags["run_key"], []).append(r)
    return runs, by_key


def content(run):
    tags = {k: v for k, v in run.data.tags.items() if k not in PLACE_TAGS}
    return run.data.params, run.data.metrics, tags, run.info.status


def log_from_copy(local_smoke, workdir, server):
    proc = snakemake(copy_without_tracking(local_smoke, workdir), "--cores", "1", GRID,
                     env={"MLFLOW_TRACKING_URI": server})
    assert proc.returncode == 0, proc.stderr[-2000:] + "\n".join(
        log.read_text()[-2000:] for log in (workdir / "results" / GRID / "logs").glob("track*.log"))


@pytest.fixture(scope="module")
def logged(server, local_smoke, tmp_path_factory):
    """The smoke grid's results logged by the workflow to the fresh server."""
    log_from_copy(local_smoke, tmp_path_factory.mktemp("first") / "w", server)
    return runs_by_key(server)


def sqlite_runs(local_smoke):
    return runs_by_key(f"sqlite:///{local_smoke / 'results' / 'mlflow.db'}")


def test_the_smoke_grid_logs_each_run_once_to_the_server(logged, local_smoke):
    runs, by_key = logged
    local_runs, local_by_key = sqlite_runs(local_smoke)
    record = json.loads((local_smoke / "results" / GRID / "mlflow_runs.json").read_text())
    assert len(local_runs) == len(record["runs"]) >= 5 * 4   # every (method, cell) job (and any grid run)
    assert by_key.keys() == local_by_key.keys()
    assert len(runs) == len(local_runs)


def test_runs_on_the_server_equal_the_sqlite_store(logged, local_smoke):
    _, by_key = logged
    _, local_by_key = sqlite_runs(local_smoke)
    for key, (run,) in by_key.items():
        assert content(run) == content(local_by_key[key][0]), key


def test_a_rerun_adds_nothing(logged, server, local_smoke, tmp_path):
    before, _ = logged
    log_from_copy(local_smoke, tmp_path / "w", server)
    runs, by_key = runs_by_key(server)
    assert len(runs) == len(before) and all(len(v) == 1 for v in by_key.values())


def test_two_grids_logging_at_once_lose_nothing_and_duplicate_nothing(logged, server, local_smoke, tmp_path):
    """Two folders (two users) log the same grid at the same time; they share no file lock, only the server."""
    before, before_by_key = logged
    client = mlflow.MlflowClient(server)
    for run in before:                                  # deleted runs are invisible: the keys are new again
        client.delete_run(run.info.run_id)
    env = {"MLFLOW_TRACKING_URI": server}
    procs = [start_snakemake(copy_without_tracking(local_smoke, tmp_path / name), "--cores", "1", GRID, env=env)
             for name in ("one", "two")]
    for p in procs:
        workdir = Path(p.args[p.args.index("--directory") + 1])
        assert p.wait(timeout=900) == 0, (workdir / "snakemake.out").read_text()[-2000:] + "\n".join(
            log.read_text()[-2000:] for log in (workdir / "results" / GRID / "logs").glob("track*.log"))
    runs, by_key = runs_by_key(server)
    assert by_key.keys() == before_by_key.keys()
    assert [k for k, v in by_key.items() if len(v) > 1] == []
