"""The smoke grid through a real SLURM (snakemake-executor-plugin-slurm, profiles/slurm/) gives the local tables.

A single-node SLURM with accounting (munge, MariaDB, slurmdbd, slurmctld, slurmd) is brought up by
.ci/slurm-single-node.sh, which installs Debian's packages with apt-get: that needs root. Checks: the run
completes with the venv's ``bin`` absent from PATH (jobs name their interpreter), every result CSV and summary
table equals the local run's as text (bit for bit, runtime columns aside: the grid is seeded, the methods
deterministic), the datasets batch and one identify batch per method ran as SLURM jobs that sacct lists as
COMPLETED, and aggregate/track ran on the submitting side (localrules).
"""

import os
import re
import shutil
import subprocess

import pytest
import yaml
from _apt import apt_lock
from _smoke import ROOT, result_tables, snakemake

pytestmark = pytest.mark.slow


def _skip_reason() -> str | None:
    if shutil.which("sbatch") and shutil.which("sacct") and os.geteuid() == 0:
        return None
    if os.geteuid() != 0:
        return "SLURM test needs root (it starts munge, MariaDB, slurmdbd, slurmctld and slurmd)"
    if not shutil.which("apt-get"):
        return "SLURM test needs apt-get to install Debian's slurm-wlm, slurmdbd, munge and mariadb-server"
    return None


@pytest.fixture(scope="module")
def slurm():
    reason = _skip_reason()
    if reason:
        pytest.skip(reason)
    with apt_lock():
        proc = subprocess.run(["bash", str(ROOT / ".ci" / "slurm-single-node.sh")], capture_output=True,
                              text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    # the partition and account as a user's environment gives them to sbatch (read by profiles/slurm)
    return {"SBATCH_PARTITION": "main", "SBATCH_ACCOUNT": "research"}


@pytest.fixture(scope="module")
def runs(slurm, local_smoke, tmp_path_factory):
    remote = tmp_path_factory.mktemp("slurm")
    # --cores: the node of this test has nproc CPUs
    cores = str(len(os.sched_getaffinity(0)))
    proc = snakemake(remote, "--workflow-profile", str(ROOT / "profiles" / "slurm"), "smoke", "--cores", cores,
                     "--slurm-init-seconds-before-status-checks", "1", env=slurm)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return local_smoke, remote, proc.stdout + proc.stderr


def test_slurm_tables_equal_the_local_run_bit_for_bit(runs):
    local, remote, _ = runs
    expected, got = result_tables(local), result_tables(remote)
    grid = yaml.safe_load((ROOT / "configs" / "grid" / "smoke.yaml").read_text())
    n_tables = len(grid["methods"]) * len(grid["noise_ug"]) * len(grid["n_samples"])   # one per (method, cell)
    assert sum(name.startswith("identify/") for name in expected) == n_tables
    assert "tables/comparison.csv" in expected
    assert got.keys() == expected.keys()
    for name, table in expected.items():
        assert got[name] == table, name


def test_sacct_lists_the_batch_jobs_as_completed(runs):
    _, remote, log = runs
    job_ids = re.findall(r"submitted with SLURM jobid (\d+)", log)
    # the datasets batch and one identify batch per method; nothing else is sent
    grid = yaml.safe_load((ROOT / "configs" / "grid" / "smoke.yaml").read_text())
    assert len(job_ids) == 1 + len(grid["methods"]), log[-3000:]
    assert "aggregate: tables" in log and "runlog: MLflow runs" in log   # run here, not submitted (localrules)
    proc = subprocess.run(["sacct", "-X", "-n", "-P", "-j", ",".join(job_ids), "--format=JobID,State,Account"],
                          capture_output=True, text=True, check=True)
    rows = [line.split("|") for line in proc.stdout.split()]
    assert sorted(r[0] for r in rows) == sorted(job_ids)
    assert all(r[1] == "COMPLETED" and r[2] == "research" for r in rows), rows
    assert (remote / "results" / "smoke" / "mlflow_runs.json").exists()
