import mlflow
import pytest

from experiments.tracking.store import log_run, tracking_uri


def test_tracking_uri_defaults_to_sqlite_and_environment_wins(monkeypatch, tmp_path):
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    monkeypatch.chdir(tmp_path)
    assert tracking_uri() == f"sqlite:///{tmp_path / 'results' / 'mlflow.db'}"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", "http://127.0.0.1:5000")
    assert tracking_uri() == "http://127.0.0.1:5000"


def test_logging_the_same_run_key_twice_creates_one_run(mlflow_uri, tmp_path):
    art = tmp_path / "r.csv"
    art.write_text("a,b\n1,2\n")
    rid1, created1 = log_run("exp", "grid/m/cell/abc", params={"p": 1}, metrics={"rmse": 0.5},
                             artifacts=[art])
    rid2, created2 = log_run("exp", "grid/m/cell/abc", params={"p": 1}, metrics={"rmse": 0.5},
                             artifacts=[art])
    assert created1 and not created2 and rid1 == rid2
    client = mlflow.MlflowClient(mlflow_uri)
    exp = client.get_experiment_by_name("exp")
    runs = client.search_runs([exp.experiment_id])
    assert len(runs) == 1
    assert runs[0].data.metrics["rmse"] == pytest.approx(0.5)
    assert [a.path for a in client.list_artifacts(rid1)] == ["r.csv"]


def test_a_run_cut_off_part_way_is_replaced(mlflow_uri):
    client = mlflow.MlflowClient(mlflow_uri)
    exp_id = client.create_experiment("exp2")
    stale = client.create_run(exp_id, tags={"run_key": "k"})          # a killed job: status RUNNING
    rid, created = log_run("exp2", "k", metrics={"x": 1.0})
    assert created and rid != stale.info.run_id
    runs = client.search_runs([exp_id])
    assert [r.info.run_id for r in runs] == [rid]
