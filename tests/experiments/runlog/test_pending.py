"""Runs logged after the job (experiments/runlog/pending.py): never lost, each logged once."""

import json
import os
import signal
import subprocess
import sys
import time

import mlflow
import pytest
from _procs import identify, run
from filelock import FileLock

from experiments.runlog import pending
from experiments.runlog.store import lock_path


def _run_folder(root, name, value=1.0):
    d = root / name
    d.mkdir(parents=True)
    (d / "estimate.json").write_text(json.dumps({"value": value}))
    (d / "figure.png").write_bytes(b"\x89PNG fake")
    return d


def _enqueue(d, key, value=1.0):
    return pending.enqueue(d, "measurements", key, params={"method": "pem", "prior": [1.0, 2.0]},
                           metrics={"freq": value, "nan_metric": float("nan")}, tags={"kind": "measurement"},
                           texts={"config.yaml": "a: 1\n"},
                           dataset={"name": "beam.csv", "digest_": "abc", "source": "beam.csv", "kind": "measurement"},
                           artifacts=[d / "estimate.json", d / "figure.png"])


def _finished(uri, key):
    client = mlflow.MlflowClient(uri)
    exp = client.get_experiment_by_name("measurements")
    if exp is None:
        return []
    runs = client.search_runs([exp.experiment_id], filter_string=f"tags.run_key = '{key}'")
    return [r for r in runs if r.info.status == "FINISHED"]


def test_a_queued_run_is_logged_once_with_its_files_then_leaves_the_queue(mlflow_uri, tmp_path, capsys):
    d = _run_folder(tmp_path, "run1")
    marker = _enqueue(d, "measurement/pem/beam.csv/k1", 3.5)
    assert json.loads(marker.read_text())["status"] == "not yet logged to MLflow"
    assert pending.waiting() == [d.resolve()]
    assert pending.log_all() == (1, 0)
    (run,) = _finished(mlflow_uri, "measurement/pem/beam.csv/k1")
    assert run.data.metrics == {"freq": 3.5}                            # the NaN metric is not logged
    assert run.data.params["prior"] == "[1.0, 2.0]" and run.data.tags["kind"] == "measurement"
    client = mlflow.MlflowClient(mlflow_uri)
    assert {a.path for a in client.list_artifacts(run.info.run_id)} == {"estimate.json", "figure.png",
                                                                        "config.yaml"}
    assert run.inputs.dataset_inputs[0].dataset.name == "beam.csv"
    assert not marker.exists()
    assert json.loads((d / pending.LOGGED).read_text())["run_id"] == run.info.run_id
    assert pending.waiting() == [] and list(pending.queue_dir().iterdir()) == []
    assert pending.log_all() == (0, 0)                                  # nothing twice
    assert len(_finished(mlflow_uri, "measurement/pem/beam.csv/k1")) == 1


def test_a_run_folder_outside_the_queue_is_found_under_a_folder(mlflow_uri, tmp_path):
    d = _run_folder(tmp_path / "runs", "a")
    _enqueue(d, "k/outside")
    for entry in pending.queue_dir().iterdir():          # the queue lost (deleted by hand): the marker remains
        entry.unlink()
    assert pending.waiting() == []
    assert pending.waiting([tmp_path / "runs"]) == [d.resolve()]
    assert pending.log_all([tmp_path / "runs"]) == (1, 0)
    assert len(_finished(mlflow_uri, "k/outside")) == 1


def test_a_run_with_a_missing_file_is_refused_and_stays_waiting(mlflow_uri, tmp_path, capsys):
    d = _run_folder(tmp_path, "run2")
    _enqueue(d, "k/missing")
    (d / "figure.png").unlink()
    assert pending.log_all() == (0, 1)
    assert "figure.png are missing" in capsys.readouterr().err
    assert (d / pending.PENDING).exists() and _finished(mlflow_uri, "k/missing") == []


def _logger(cwd, uri):
    env = os.environ | {"MLFLOW_TRACKING_URI": uri, "OPENBLAS_NUM_THREADS": "1"}
    return subprocess.Popen([sys.executable, "-m", "experiments.runlog.pending"], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.slow
def test_kill_9_of_the_logger_loses_nothing(mlflow_uri, tmp_path):
    """Killed while it waits for the store (another writer holds the lock), and killed at whatever point it
    has reached after a second of work: the run stays waiting or is logged, never lost nor logged twice,
    and the next logger finishes it."""
    d = _run_folder(tmp_path, "run3")
    key = "measurement/pem/beam.csv/k3"
    _enqueue(d, key)
    with FileLock(str(lock_path(mlflow_uri))):
        proc = _logger(tmp_path, mlflow_uri)
        time.sleep(4.0)                                  # imported, now blocked on the store's lock
        assert proc.poll() is None
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert (d / pending.PENDING).exists() and pending.waiting() == [d.resolve()]
    proc = _logger(tmp_path, mlflow_uri)
    time.sleep(1.0)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert (d / pending.PENDING).exists() or len(_finished(mlflow_uri, key)) == 1
    out = run("-m", "experiments.runlog.pending", cwd=tmp_path, env_extra={"MLFLOW_TRACKING_URI": mlflow_uri})
    assert key in out.stdout or "no MLflow run waiting" in out.stdout
    assert len(_finished(mlflow_uri, key)) == 1
    assert not (d / pending.PENDING).exists() and pending.waiting() == []


@pytest.mark.slow
def test_two_loggers_at_once_log_each_run_once(mlflow_uri, tmp_path):
    keys = [f"measurement/pem/beam.csv/race{i}" for i in range(3)]
    for i, key in enumerate(keys):
        _enqueue(_run_folder(tmp_path, f"r{i}"), key, float(i))
    procs = [_logger(tmp_path, mlflow_uri) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    for key in keys:
        assert len(_finished(mlflow_uri, key)) == 1
    client = mlflow.MlflowClient(mlflow_uri)
    assert len(client.search_runs([client.get_experiment_by_name("measurements").experiment_id])) == 3
    assert pending.waiting() == []


@pytest.mark.slow
def test_the_job_answers_first_and_its_run_is_logged_in_the_background(measurement, tmp_path):
    """The identify job on a CSV with MLflow logging on (the default): the answer and the run folder are there
    when it exits, the MLflow run follows; the command logs (or finds logged) the run."""
    out = identify(tmp_path, "method=fft", f"data.path={measurement}", "prior=[3.8,16,26,46]",
                   "hydra.run.dir=run")
    assert "being logged by a background process" in out.stdout
    assert (tmp_path / "run" / "estimate.json").exists()
    db = tmp_path / "results" / "mlflow.db"
    done = run("-m", "experiments.runlog.pending", cwd=tmp_path)     # waits for the job's logger's lock
    assert done.returncode == 0
    deadline = time.time() + 120
    while (tmp_path / "run" / pending.PENDING).exists() and time.time() < deadline:
        time.sleep(0.5)
    client = mlflow.MlflowClient(f"sqlite:///{db}")
    (r,) = client.search_runs([client.get_experiment_by_name("measurements").experiment_id])
    assert r.info.status == "FINISHED" and "freq_rad_s.mode1" in r.data.metrics
    assert json.loads((tmp_path / "run" / pending.LOGGED).read_text())["run_id"] == r.info.run_id
    sync = identify(tmp_path, "method=fft", f"data.path={measurement}", "prior=[3.8,16,26,46]",
                    "hydra.run.dir=run2", "runlog.background=false")
    assert "(already there)" in sync.stdout


def test_the_command_refuses_a_missing_folder(tmp_path):
    out = run("-m", "experiments.runlog.pending", str(tmp_path / "nope"), cwd=tmp_path, check=False)
    assert out.returncode == 2 and out.stderr.startswith("error: ") and len(out.stderr.splitlines()) == 1
