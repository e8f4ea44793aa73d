"""End to end: the smoke grid through Snakemake (datasets -> identify -> aggregate -> MLflow), then again.

Runs in a scratch working directory with its own MLflow store, so it neither needs nor touches results/.
"""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import mlflow
import pandas as pd
import pytest
from _workflow import ROOT

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def smoke_run(smoke_workdir):
    return smoke_workdir


def test_smoke_workflow_writes_tables_figures_and_page(smoke_run):
    out = smoke_run / "results" / "smoke"
    summary = pd.read_csv(out / "tables" / "comparison.csv")
    grid = __import__("yaml").safe_load((ROOT / "configs" / "grid" / "smoke.yaml").read_text())
    n_cells = len(grid["noise_ug"]) * len(grid["n_samples"])
    assert set(summary["method"]) == set(grid["methods"])
    assert len(summary) == len(grid["methods"]) * n_cells * 4
    assert (summary["replicates"] == grid["replicates"]).all()
    for fig in ("rmse_vs_noise", "rmse_vs_length", "winner_map", "failure_map", "coverage", "pareto"):
        assert (out / "figures" / f"{fig}.png").stat().st_size > 10_000
        assert (out / "figures" / f"{fig}.svg").exists()
    page = (out / "README.md").read_text()
    assert "figures/winner_map.png" in page and "tables/comparison.csv" in page
    assert "Is each method's reported std honest?" in page
    assert {"coverage_1std", "coverage_2std", "median_abs_err_over_std"} <= set(summary.columns)
    # one benchmark file per batch job: the datasets of the grid, and each method over every cell
    assert len(list((out / "benchmarks" / "identify").glob("*.tsv"))) == len(grid["methods"])
    assert (out / "benchmarks" / "datasets.tsv").exists()


def test_mlflow_holds_each_job_once_and_a_rerun_adds_nothing(smoke_run, snakemake):
    out = smoke_run / "results" / "smoke"
    record = json.loads((out / "mlflow_runs.json").read_text())
    client = mlflow.MlflowClient(f"sqlite:///{smoke_run / 'results' / 'mlflow.db'}")
    exp = client.get_experiment_by_name(record["experiment"])
    runs = client.search_runs([exp.experiment_id], max_results=1000)
    assert len(runs) == len(record["runs"])
    assert len({r.data.tags["run_key"] for r in runs}) == len(runs)
    # the grid is a parent run (tables, figures, page) with every job as its child
    parent = client.get_run(record["parent_run"])
    assert parent.data.tags["kind"] == "grid"
    assert {"comparison.csv", "winner_map.png", "summary.md"} <= {
        Path(a.path).name for d in ("", "tables", "figures") for a in client.list_artifacts(parent.info.run_id, d)}
    jobs = [r for r in runs if r.data.tags.get("kind") == "job"]
    assert len(jobs) == len(runs) - 1 == len(list((out / "identify").glob("*/*.csv")))
    for r in jobs:
        assert r.data.tags["mlflow.parentRunId"] == parent.info.run_id
        assert r.data.tags["mlflow.source.name"] == "experiments/jobs/identify.py"
        (ds,) = r.inputs.dataset_inputs
        cell = r.data.params["dataset"]
        assert ds.dataset.name == cell and len(ds.dataset.digest) > 8
        assert "config.yaml" in {a.path for a in client.list_artifacts(r.info.run_id)}
    assert "## Tracking" in (out / "README.md").read_text()
    assert (out / "README.md").read_text().startswith((out / "summary.md").read_text().rstrip("\n"))
    table = (out / "tables" / "comparison.csv").read_bytes()
    proc = snakemake(smoke_run, "smoke")
    assert proc.returncode == 0
    assert "Nothing to be done" in proc.stdout + proc.stderr
    # forcing the logging step again is idempotent too
    (out / "mlflow_runs.json").unlink()
    assert snakemake(smoke_run, "smoke").returncode == 0
    assert len(client.search_runs([exp.experiment_id], max_results=1000)) == len(runs)
    assert (out / "tables" / "comparison.csv").read_bytes() == table


def test_a_killed_job_leaves_no_file_snakemake_takes_for_done(smoke_run, tmp_path):
    # Re-running identify into a fresh path with the process killed mid-way leaves no output file.
    cell = next((smoke_run / "results" / "smoke" / "data").glob("*.npz"))
    target = tmp_path / "res.csv"
    proc = subprocess.Popen([sys.executable, "-m", "experiments.jobs.identify", "method=fft",
                             f"data.dataset={cell}", f"out={target}", "runlog.enabled=false",
                             f"hydra.run.dir={tmp_path / 'run'}"], cwd=tmp_path)
    proc.kill()
    proc.wait()
    assert not target.exists()
    shutil.rmtree(tmp_path / "run", ignore_errors=True)
