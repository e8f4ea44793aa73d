"""End to end: the smoke grid through Snakemake (datasets -> identify -> aggregate -> MLflow), then again.

Runs in a scratch working directory with its own MLflow store, so it neither needs nor touches results/.
"""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import mlflow
import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.slow


def snakemake_in(workdir, *args, snakefile=ROOT / "Snakefile"):
    """Snakemake with any Snakefile (a scratch copy of the repository) in a scratch working directory."""
    bindir = Path(sys.executable).parent          # the rules call `python -m ...` of this environment
    env = os.environ | {"PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}"}
    env.pop("MLFLOW_TRACKING_URI", None)
    return subprocess.run([str(bindir / "snakemake"), "-s", str(snakefile), "--directory", str(workdir),
                           "--cores", "2", *args], capture_output=True, text=True, timeout=900, env=env)


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


# ---- Reruns after a change: a scratch copy of the repository with a two-method grid -----------------------

TINY = """name: tiny
noise_ug: [1000]
n_samples: [64]
replicates: 2
seed: 7
methods: [fft, akf]
"""
IGNORE = shutil.ignore_patterns(".venv", ".git", "results", ".snakemake", "__pycache__", ".pytest_cache",
                                ".ruff_cache", "*.egg-info")


def planned(workdir, target="results/tiny/README.md"):
    """The jobs ``snakemake -n`` would run: {rule: [outputs]}."""
    proc = snakemake_in(workdir, "-n", target, snakefile=workdir / "Snakefile")
    assert proc.returncode == 0, proc.stderr[-3000:]
    jobs = {}
    for line in (proc.stdout + proc.stderr).splitlines():
        # each rule's message (experiments/workflow/rules/*.smk): "Job <i>: <rule>: <what> -> <first output>"
        match = re.match(r"\s*Job \d+: (\w+): .* -> (\S+)$", line)
        if match:
            jobs.setdefault(match[1], []).append(match[2])
    return jobs


@pytest.fixture(scope="module")
def repo_copy(tmp_path_factory):
    copy = tmp_path_factory.mktemp("repo") / "repo"
    shutil.copytree(ROOT, copy, ignore=IGNORE)
    (copy / "configs" / "grid" / "tiny.yaml").write_text(TINY)
    (copy / "configs" / "grid" / "broken.yaml").write_text(TINY.replace("tiny", "broken").replace("[1000]", "[-1]"))
    proc = snakemake_in(copy, "results/tiny/README.md", snakefile=copy / "Snakefile")
    assert proc.returncode == 0, proc.stderr[-3000:]
    return copy


def test_one_target_gives_a_grids_tables_figures_and_tracking(repo_copy):
    out = repo_copy / "results" / "tiny"
    assert (out / "tables" / "comparison.csv").exists() and (out / "figures" / "winner_map.png").exists()
    record = json.loads((out / "mlflow_runs.json").read_text())
    client = mlflow.MlflowClient(f"sqlite:///{repo_copy / 'results' / 'mlflow.db'}")
    exp = client.get_experiment_by_name("grid-tiny")
    assert len(client.search_runs([exp.experiment_id])) == len(record["runs"]) == 1 + 2
    assert "grid-tiny" in (out / "README.md").read_text()


def test_a_malformed_grid_file_breaks_only_itself_in_one_line(repo_copy):
    assert planned(repo_copy) == {}                       # the tiny grid still plans (nothing to do)
    proc = snakemake_in(repo_copy, "-n", "results/broken/README.md", snakefile=repo_copy / "Snakefile")
    assert proc.returncode != 0
    errors = [line for line in (proc.stdout + proc.stderr).splitlines() if "broken.yaml" in line]
    assert errors and "noise_ug" in errors[0] and "-1" in errors[0], proc.stderr[-2000:]


def test_runlog_reads_only_what_the_workflow_declares(repo_copy):
    # the runlog step reads the declared tables and records; logs, benchmarks and run folders are not inputs
    for undeclared in ("logs", "benchmarks", "runs"):
        shutil.rmtree(repo_copy / "results" / "tiny" / undeclared, ignore_errors=True)
    (repo_copy / "results" / "tiny" / "README.md").unlink()
    proc = snakemake_in(repo_copy, "results/tiny/README.md", snakefile=repo_copy / "Snakefile")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "runlog: MLflow runs and page of grid tiny" in proc.stdout + proc.stderr
    assert "0 newly logged" in (repo_copy / "results" / "tiny" / "logs" / "runlog.log").read_text()


def test_a_deleted_dataset_is_regenerated_bit_for_bit_and_the_tables_stay(repo_copy):
    out = repo_copy / "results" / "tiny"
    (dataset,) = (out / "data").glob("*.npz")
    original = dataset.read_bytes()
    table = pd.read_csv(out / "tables" / "comparison.csv").drop(columns="median_runtime_s")
    dataset.unlink()
    jobs = planned(repo_copy)
    assert jobs.pop("datasets") == ["results/tiny/data"] and set(jobs) == {"identify", "aggregate", "runlog"}
    proc = snakemake_in(repo_copy, "results/tiny/README.md", snakefile=repo_copy / "Snakefile")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert dataset.read_bytes() == original
    pd.testing.assert_frame_equal(pd.read_csv(out / "tables" / "comparison.csv").drop(columns="median_runtime_s"),
                                  table)
    assert planned(repo_copy) == {}


def _edit(path, old, new):
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    return text


def test_an_edit_reruns_exactly_the_affected_jobs_and_what_follows(repo_copy):
    downstream = {"aggregate", "runlog"}
    fft_jobs = ["results/tiny/identify/fft"]           # the fft batch: every cell of the grid
    # unrelated edits: a README, another method's code and config
    for path, old, new in [(repo_copy / "README.md", "# Identifying", "# Identifying (edited)"),
                           (repo_copy / "methods" / "pll" / "_loop.py", '"""', '"""Edited. '),
                           (repo_copy / "configs" / "method" / "pem.yaml", "name: pem", "name: pem  # edited")]:
        _edit(path, old, new)
        assert planned(repo_copy) == {}, path
    # the fft method's config, then its code: the fft job and everything downstream, nothing else
    cfg = repo_copy / "configs" / "method" / "fft.yaml"
    original = _edit(cfg, "name: fft\n", "name: fft\noptions:\n  zero_pad_factor: 8\n")
    jobs = planned(repo_copy)
    assert jobs.pop("identify") == fft_jobs and set(jobs) == downstream
    cfg.write_text(original)
    assert planned(repo_copy) == {}                       # back to the config the results were made with
    _edit(repo_copy / "methods" / "fft.py", '"""', '"""Edited. ')
    jobs = planned(repo_copy)
    assert jobs.pop("identify") == fft_jobs and set(jobs) == downstream
    # a module shared by several methods reruns all of theirs
    _edit(repo_copy / "methods" / "estimate.py", '"""', '"""Edited. ')
    assert sorted(planned(repo_copy)["identify"]) == sorted(
        fft_jobs + ["results/tiny/identify/akf"])


def test_run_sh_clears_a_stale_lock_unless_a_snakemake_works_in_this_folder(repo_copy, tmp_path):
    # run.sh's environment: this one, seen through a .venv that run.sh takes as installed (a symlink to the
    # real .venv would let run.sh reinstall the package from the copy)
    venv_bin = repo_copy / ".venv" / "bin"
    venv_bin.mkdir(parents=True)
    for exe in ("python", "snakemake"):
        (venv_bin / exe).symlink_to(Path(sys.executable).parent / exe)
    (repo_copy / ".venv" / ".installed").touch()
    locks = repo_copy / ".snakemake" / "locks"
    fake = tmp_path / "bin" / "snakemake"                       # stands for a running Snakemake
    fake.parent.mkdir()
    shutil.copy("/bin/sleep", fake)

    def stale_lock_cleared_with(cwd):
        locks.mkdir(parents=True, exist_ok=True)
        (locks / "0.input.lock").write_text(f"{repo_copy / 'results' / 'x'}\n")
        other = subprocess.Popen([str(fake), "120"], cwd=cwd)
        try:
            proc = subprocess.run(["./run.sh", "smoke", "--version"], cwd=repo_copy, capture_output=True,
                                  text=True, timeout=300)
            assert proc.returncode == 0, proc.stderr
        finally:
            other.kill()
            other.wait()
        return not locks.exists() or not any(locks.iterdir())

    assert stale_lock_cleared_with(tmp_path)          # another workflow elsewhere on the machine: cleared
    assert not stale_lock_cleared_with(repo_copy)     # a Snakemake working here: left alone


def test_a_grid_with_a_yardstick_prior_gets_the_bayesian_columns_and_a_rerun_does_nothing(repo_copy):
    # a one-cell grid where the CRLB is loose (20 samples at 1 mg): the yardstick rule runs once, its columns
    # reach the comparison table, and a second dry run is empty until the prior's config changes
    grid = TINY.replace("tiny", "bayes").replace("[64]", "[20]").replace("[fft, akf]", "[fft]")
    (repo_copy / "configs" / "grid" / "bayes.yaml").write_text(grid + "yardstick_prior: pem_map\n")
    target = "results/bayes/README.md"
    assert set(planned(repo_copy, target)) == {"datasets", "identify", "yardstick", "aggregate", "runlog"}
    proc = snakemake_in(repo_copy, target, snakefile=repo_copy / "Snakefile")
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = repo_copy / "results" / "bayes"
    ys = pd.read_csv(out / "yardstick.csv")
    assert len(ys) == 4 and ys["loose"].any() and ys.loc[ys["loose"], "posterior_mean_rmse_rad_s"].notna().all()
    table = pd.read_csv(out / "tables" / "comparison.csv")
    merged = table.merge(ys, on=["noise_ug", "n_samples", "mode"], suffixes=("", "_y"))
    np.testing.assert_allclose(merged["rmse_over_posterior_mean"],       # every mode of the loose cell
                               merged["rmse_rad_s"] / merged["posterior_mean_rmse_rad_s_y"])
    np.testing.assert_allclose(merged["van_trees_std_rad_s"], merged["van_trees_std_rad_s_y"])
    assert planned(repo_copy, target) == {}                              # cached: a rerun does nothing
    cfg = repo_copy / "configs" / "method" / "pem_map.yaml"
    original = _edit(cfg, "[0.795, 5.019, 5.196, 15.873]", "[0.8, 5.0, 5.2, 15.9]")
    assert set(planned(repo_copy, target)) == {"yardstick", "aggregate", "runlog"}
    cfg.write_text(original)
    assert planned(repo_copy, target) == {}
