import copy
import json

import mlflow
import pytest
from _procs import grid_jobs, identify

from experiments.runlog.identify_runs import run_key
from experiments.runlog.store import log_run, tracking_uri


def test_tracking_uri_defaults_to_sqlite_and_environment_wins(monkeypatch, tmp_path):
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    monkeypatch.chdir(tmp_path)
    assert tracking_uri() == f"sqlite:///{tmp_path / 'results' / 'mlflow.db'}"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", "http://127.0.0.1:5000")
    assert tracking_uri() == "http://127.0.0.1:5000"


def test_the_default_store_keeps_artifacts_under_results_not_the_working_directory(monkeypatch, tmp_path):
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    monkeypatch.chdir(tmp_path)
    art = tmp_path / "table.csv"
    art.write_text("a\n1\n")
    rid, _ = log_run("exp-artifacts", "k/1", artifacts=[art])
    assert not (tmp_path / "mlruns").exists()
    assert list((tmp_path / "results" / "mlartifacts").rglob("table.csv"))
    assert "MLFLOW_TRACKING_URI" not in __import__("os").environ


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


RECORD = {"grid": "g", "method": "fft", "method_config": "fft",
          "config": {"method": {"name": "fft", "options": {"zero_pad_factor": 16}}, "prior": None,
                     "data": {"dataset": "a/cell.npz", "replicates": None}, "out": "a/cell.csv"},
          "dataset": {"name": "cell", "path": "a/cell.npz", "digest": "d1"},
          "code": {"commit": "c1", "dirty": False, "diff": "", "method_files": "f1"},
          "versions": {"numpy": "2.4.0"}}


def _changed(path, value):
    rec = copy.deepcopy(RECORD)
    *head, last = path
    node = rec
    for k in head:
        node = node[k]
    node[last] = value
    return rec


@pytest.mark.parametrize("path, value", [
    (("dataset", "digest"), "d2"),                                  # another dataset content (e.g. a bias)
    (("config", "method", "options", "zero_pad_factor"), 8),        # another option
    (("config", "prior"), [3.5, 19.0, 23.0, 55.0]),                 # another prior
    (("config", "data", "replicates"), 1),
    (("code", "commit"), "c2"), (("code", "dirty"), True), (("code", "diff"), "x"),
    (("code", "method_files"), "f2"),                               # the method's code changed
    (("versions", "numpy"), "2.4.1"),
])
def test_the_run_key_changes_with_what_determines_the_result(path, value):
    assert run_key(_changed(path, value)) != run_key(RECORD)


@pytest.mark.parametrize("path, value", [(("config", "out"), "b/x.csv"), (("dataset", "path"), "b/cell.npz"),
                                         (("config", "data", "dataset"), "b/cell.npz")])
def test_the_run_key_ignores_where_files_are(path, value):
    assert run_key(_changed(path, value)) == run_key(RECORD)


@pytest.mark.slow
def test_identify_logs_each_distinct_result_once_and_user_measurements_too(cells, measurement, tmp_path):
    """Real jobs on a fresh default store: a cell with another bias (same noise, N, seed) is a new run, an
    identical rerun is not, another option is; a user's CSV goes to the experiment 'measurements'."""
    a, b = cells
    for overrides in ([f"data.dataset={a}"], [f"data.dataset={a}"], [f"data.dataset={b}"],
                      [f"data.dataset={a}", "method.options.zero_pad_factor=8"]):
        identify(tmp_path, "method=fft", *overrides)
    identify(tmp_path, "method=fft", f"data.path={measurement}", "prior=[3.8,16,26,46]", "runlog.background=false")
    client = mlflow.MlflowClient(f"sqlite:///{tmp_path / 'results' / 'mlflow.db'}")
    runs = client.search_runs([client.get_experiment_by_name("identify").experiment_id])
    assert len(runs) == 3
    assert len({r.data.tags["run_key"] for r in runs}) == 3
    assert {r.data.params["option.zero_pad_factor"] for r in runs} == {"16", "8"}
    for r in runs:
        assert r.data.tags["mlflow.source.name"] == "experiments/jobs/identify.py"
        assert r.info.artifact_uri.startswith((tmp_path / "results" / "mlartifacts").as_uri())
        assert "config.yaml" in {f.path for f in client.list_artifacts(r.info.run_id)}
        (ds,) = r.inputs.dataset_inputs
        assert ds.dataset.digest and ds.dataset.name in ("a", "b")
    meas = client.search_runs([client.get_experiment_by_name("measurements").experiment_id])
    assert len(meas) == 1
    assert meas[0].inputs.dataset_inputs[0].dataset.name == "my.csv"
    assert "freq_rad_s.mode1" in meas[0].data.metrics
    assert not (tmp_path / "mlruns").exists()


def test_a_run_of_the_same_key_from_a_writer_elsewhere_is_not_duplicated(mlflow_uri):
    """Writers in another folder share no lock: the earlier-started run with a key stays, a later one
    deletes itself; a RUNNING run of a live owner elsewhere is not taken for cut off."""
    client = mlflow.MlflowClient(mlflow_uri)
    exp_id = client.create_experiment("exp3")
    other = client.create_run(exp_id, tags={"run_key": "k", "owner": "another-host:1"})   # still running
    rid, created = log_run("exp3", "k", metrics={"x": 1.0})
    assert not created and rid == other.info.run_id
    assert [r.info.run_id for r in client.search_runs([exp_id])] == [other.info.run_id]
    client.set_terminated(other.info.run_id)
    assert log_run("exp3", "k", metrics={"x": 1.0}) == (other.info.run_id, False)


def test_jobs_logged_first_become_the_grid_runs_children_without_being_logged_again(cells, mlflow_uri, tmp_path,
                                                                                    capsys):
    """The workflow's runlog_jobs step logs the jobs alone (no parent); the runlog step then logs the grid's run
    and only makes the same runs its children: the store ends as if one step had logged everything."""
    from experiments.runlog.identify_runs import main

    a, _ = cells
    tables = grid_jobs(tmp_path, a, "g")
    assert main(["--grid", "g", "--jobs-only", "--out", str(tmp_path / "jobs.json"), "--", *tables]) == 0
    assert "2 job runs in MLflow experiment grid-g (2 newly logged)" in capsys.readouterr().out
    first = json.loads((tmp_path / "jobs.json").read_text())["runs"]
    client = mlflow.MlflowClient(mlflow_uri)
    exp_id = client.get_experiment_by_name("grid-g").experiment_id
    assert all("mlflow.parentRunId" not in r.data.tags for r in client.search_runs([exp_id]))
    summary = tmp_path / "summary.md"
    summary.write_text("# g\n")
    assert main(["--grid", "g", "--out", str(tmp_path / "runs.json"), "--summary", str(summary), "--page",
                 str(tmp_path / "README.md"), "--", *tables]) == 0
    assert "3 runs in MLflow experiment grid-g (1 newly logged)" in capsys.readouterr().out
    record = json.loads((tmp_path / "runs.json").read_text())
    assert {k: v for k, v in record["runs"].items() if v != record["parent_run"]} == first
    runs = client.search_runs([exp_id])
    assert len(runs) == 3 and all(r.info.status == "FINISHED" for r in runs)
    children = [r for r in runs if r.data.tags.get("kind") == "job"]
    assert sorted(r.info.run_id for r in children) == sorted(first.values())
    assert all(r.data.tags["mlflow.parentRunId"] == record["parent_run"] for r in children)
    assert "owner" not in {k for r in runs for k in r.data.tags}
