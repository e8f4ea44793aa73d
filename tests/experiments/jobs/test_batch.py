"""The workflow's batch jobs (experiments/jobs/batch.py): one process, the same files as one job per cell."""

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from experiments.io import read_npz

DATASET = ["noise_ug=1000", "n_samples=64", "replicates=2", "seed=5"]


def batch(cwd, app, jobs):
    return subprocess.run([sys.executable, "-m", "experiments.jobs.batch", app, json.dumps(jobs)], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def single(cwd, module, overrides):
    return subprocess.run([sys.executable, "-m", f"experiments.jobs.{module}", *overrides], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def cells(tmp_path_factory):
    cwd = tmp_path_factory.mktemp("batch")
    jobs = [DATASET + [f"out={cwd}/a.npz"], [*DATASET[:1], "n_samples=128", *DATASET[2:], f"out={cwd}/b.npz"]]
    proc = batch(cwd, "dataset", jobs)
    assert proc.returncode == 0, proc.stderr
    return cwd


def test_a_batch_writes_what_single_jobs_write(cells):
    cwd = cells
    assert single(cwd, "make_dataset", DATASET + [f"out={cwd}/a1.npz"]).returncode == 0
    a, a1 = read_npz(cwd / "a.npz"), read_npz(cwd / "a1.npz")
    np.testing.assert_array_equal(a["accel_m_s2"], a1["accel_m_s2"])
    assert read_npz(cwd / "b.npz")["accel_m_s2"].shape == (2, 128)
    common = ["method=era", "grid_name=t", "runlog.enabled=false"]
    jobs = [common + [f"data.dataset={cwd}/{c}.npz", f"out={cwd}/era_{c}.csv"] for c in ("a", "b")]
    proc = batch(cwd, "identify", jobs)
    assert proc.returncode == 0, proc.stderr
    assert "2 identify jobs" in proc.stdout
    ref = single(cwd, "identify", common + [f"data.dataset={cwd}/a.npz", f"out={cwd}/era_ref.csv",
                                            f"hydra.run.dir={cwd}/run"])
    assert ref.returncode == 0, ref.stderr

    def table(path):    # the runtime column aside, the same text
        lines = path.read_text().splitlines()
        col = lines[0].split(",").index("runtime_s")
        return [",".join(v for i, v in enumerate(line.split(",")) if i != col) for line in lines]

    assert table(cwd / "era_a.csv") == table(cwd / "era_ref.csv")
    rec, ref_rec = (json.loads((cwd / f).read_text()) for f in ("era_a.json", "era_ref.json"))
    assert rec["config"].pop("out").endswith("era_a.csv") and ref_rec["config"].pop("out").endswith("era_ref.csv")
    assert rec["config"] == ref_rec["config"] and rec["method_config"] == ref_rec["method_config"] == "era"


def test_bad_input_in_any_job_is_one_line_and_nothing_is_written(cells):
    cwd = cells
    jobs = [["method=fft", f"data.dataset={cwd}/a.npz", f"out={cwd}/x1.csv"],
            ["method=fft", f"data.dataset={cwd}/a.npz", f"out={cwd}/x2.csv", "method.options.no_such=1"]]
    proc = batch(cwd, "identify", jobs)
    errors = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2 and len(errors) == 1, proc.stderr
    assert errors[0].startswith("error: job 2 of 2") and "no_such" in errors[0]
    assert not (cwd / "x1.csv").exists()
    for jobs_text, word in [("[]", "non-empty"), ("{", "JSON")]:
        proc = subprocess.run([sys.executable, "-m", "experiments.jobs.batch", "identify", jobs_text], cwd=cwd,
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2 and word in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_composing_once_per_method_gives_each_job_hydras_own_config():
    from hydra import initialize_config_module
    from omegaconf import OmegaConf

    from experiments.hydra_app.command_line import CONFIG_MODULE
    from experiments.hydra_app.config_store import register
    from experiments.jobs import batch as batch_app

    register(with_methods=["akf", "fft"])
    jobs = [[f"method={m}", f"data.dataset=results/g/data/{c}.npz", f"out=results/g/identify/{m}/{c}.csv",
             "grid_name=g", "runlog.enabled=false", *extra]
            for m, extra in (("fft", []), ("akf", ["method.options.measurement=acceleration"]))
            for c in ("noise10ug_n20", "noise1000ug_n2048")]
    jobs.append(jobs[0] + ["out=twice.csv"])           # a key given twice: composed by Hydra from scratch
    with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
        composer = batch_app.Composer("identify")
        for job in jobs:
            got, choice = composer(job)
            ref, ref_choice = batch_app._compose("identify", job)
            assert OmegaConf.to_container(got) == OmegaConf.to_container(ref)
            assert choice == ref_choice
        assert len(composer.cache) == 2                 # one composition per method
        assert got.out == "twice.csv"


def test_worker_processes_write_what_one_process_writes(cells):
    cwd = cells
    common = ["method=akf", "grid_name=t", "runlog.enabled=false"]

    def jobs(tag):
        return [common + [f"data.dataset={cwd}/{c}.npz", f"out={cwd}/w{tag}_{c}.csv"] for c in ("a", "b")]

    one = batch(cwd, "identify", jobs(1))
    two = subprocess.run([sys.executable, "-m", "experiments.jobs.batch", "identify", json.dumps(jobs(2)),
                          "--workers", "2"], cwd=cwd, capture_output=True, text=True, timeout=300)
    assert one.returncode == 0 and two.returncode == 0, one.stderr + two.stderr
    assert "(2 workers)" in two.stdout and "(1 worker)" in one.stdout
    for c in ("a", "b"):
        t1, t2 = (pd.read_csv(cwd / f"w{k}_{c}.csv").drop(columns="runtime_s") for k in (1, 2))
        pd.testing.assert_frame_equal(t1, t2)
    bad = subprocess.run([sys.executable, "-m", "experiments.jobs.batch", "identify", json.dumps(jobs(3)),
                          "--workers", "0"], cwd=cwd, capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "--workers 0" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    assert not (cwd / "w3_a.csv").exists()
