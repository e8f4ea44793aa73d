"""End to end on a scratch copy of the repository: a tiny grid, then edits, deletions and a stale lock, each
rerunning exactly what it affects (the tests share the copy and run in order).

Split from tests/test_workflow.py so that the parallel suite (pytest-xdist, one file per worker) can run the
two halves on different workers.
"""

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import mlflow
import numpy as np
import pandas as pd
import pytest
from _workflow import ROOT, snakemake_in

pytestmark = pytest.mark.slow


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
    assert jobs.pop("datasets") == ["results/tiny/data"] and set(jobs) == {"identify", "aggregate", "runlog_jobs",
                                                                            "runlog"}
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
    downstream = {"aggregate", "runlog_jobs", "runlog"}
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
    assert set(planned(repo_copy, target)) == {"datasets", "identify", "yardstick", "aggregate", "runlog_jobs",
                                               "runlog"}
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
