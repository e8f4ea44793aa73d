"""MLflow under concurrency: real processes racing on a fresh store, then on a used one.

Without the store lock, processes opening a fresh SQLite store at once leave it half-migrated for good
(``table _alembic_tmp_tags already exists``), and a search-then-create of one run key from two processes
gives two runs. Each process here waits at a barrier after its imports, so they hit the store together.
"""

import json
import subprocess
import sys
import time

import mlflow
import pytest
from _procs import grid_jobs, run

pytestmark = pytest.mark.slow
N_PROC = 4

BARRIER = """
import pathlib, sys, time
pathlib.Path(sys.argv[1] + ".ready").touch()
while not pathlib.Path(sys.argv[2]).exists():
    time.sleep(0.01)
"""
LOG_KEYS = BARRIER + """
from experiments.runlog.store import log_run
for k in range(int(sys.argv[3])):
    log_run("race", f"key/{k}", params={"k": k}, metrics={"x": float(k)})
"""
TRACK = BARRIER + """
from experiments.runlog.identify_runs import main
sys.exit(main(sys.argv[3:]))
"""


def race(cwd, script, args_of):
    """Start N_PROC processes, release them at once, and return their (returncode, stderr)."""
    import os

    env = os.environ | {"OPENBLAS_NUM_THREADS": "1"}
    env.pop("MLFLOW_TRACKING_URI", None)
    go = cwd / "go"
    go.unlink(missing_ok=True)
    procs = []
    for i in range(N_PROC):
        tag = cwd / f"proc{i}"
        (cwd / f"proc{i}.ready").unlink(missing_ok=True)
        procs.append(subprocess.Popen([sys.executable, "-c", script, str(tag), str(go), *args_of(i)], cwd=cwd,
                                      env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
    deadline = time.time() + 300
    while not all((cwd / f"proc{i}.ready").exists() for i in range(N_PROC)):
        assert time.time() < deadline and all(p.poll() is None for p in procs), "a racer died before the start"
        time.sleep(0.05)
    go.touch()
    return [(p.wait(timeout=600), p.communicate()[1]) for p in procs]


def _runs(cwd, experiment):
    client = mlflow.MlflowClient(f"sqlite:///{cwd / 'results' / 'mlflow.db'}")
    exp = client.get_experiment_by_name(experiment)
    return client, client.search_runs([exp.experiment_id], max_results=1000)


def test_racing_processes_log_every_run_exactly_once_on_a_fresh_then_a_used_store(cells, tmp_path):
    # fresh store: 4 processes create it and log the same 6 keys
    for code, err in race(tmp_path, LOG_KEYS, lambda i: ["6"]):
        assert code == 0, err[-2000:]
    client, runs = _runs(tmp_path, "race")
    assert sorted(r.data.tags["run_key"] for r in runs) == [f"key/{k}" for k in range(6)]
    assert all(r.info.status == "FINISHED" for r in runs)

    # used store: the workflow's runlog step, 4 at once over the same two jobs
    a, _ = cells
    tables = grid_jobs(tmp_path, a, "race")
    results = race(tmp_path, TRACK, lambda i: ["--grid", "race", "--out", f"record{i}.json", "--", *tables])
    for code, err in results:
        assert code == 0, err[-2000:]
    client, runs = _runs(tmp_path, "grid-race")
    keys = [r.data.tags["run_key"] for r in runs]
    assert len(keys) == len(set(keys)) == 1 + 2                 # the grid's run and its two jobs, once each
    records = [json.loads((tmp_path / f"record{i}.json").read_text()) for i in range(N_PROC)]
    assert all(r["runs"] == records[0]["runs"] for r in records)
    parent = records[0]["parent_run"]
    assert sorted(r.data.tags.get("mlflow.parentRunId", "") for r in runs) == ["", parent, parent]

    # the store is usable afterwards, by MLflow directly and by another (serial) logging run
    exp = client.create_experiment("after")
    client.set_terminated(client.create_run(exp).info.run_id)
    assert len(client.search_runs([exp])) == 1
    proc = run("-c", LOG_KEYS.replace(BARRIER, "import sys\n"), "x", "y", "8", cwd=tmp_path)
    assert proc.returncode == 0
    assert len(_runs(tmp_path, "race")[1]) == 8
