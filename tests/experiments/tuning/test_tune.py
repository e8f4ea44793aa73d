"""The tuning command: its objective's arithmetic, its search-space arithmetic, a tiny study that writes a
method config Hydra composes, the scoring seed refused, and a Hydra sweep that survives a failing trial."""

import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hydra import compose, initialize_config_dir

from experiments.hydra_app.config_store import register
from experiments.report.objective import DEFAULT_PENALTY, FAILED_RATIO, objective
from experiments.simulate.datasets import DatasetConfig, write_cell
from experiments.tuning.space import base_params, resolve

ROOT = Path(__file__).resolve().parents[3]
SCORING_SEED = 20261121


def run(module, *args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", module, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def test_objective_on_a_known_table():
    """J = mean over cells of log10(median over delivered modes of RMSE/CRLB) + penalty × failure rate.
    Cell A: ratios 10, 100, 1000 and a mode that never converged -> median 100 (2 decades), failure rate
    1/4 -> 2 + 4/4 = 3. Cell B: nothing converged -> log10(FAILED_RATIO) + 4 = 16. Mean 9.5."""
    table = pd.DataFrame({
        "noise_ug": [10.0] * 4 + [1000.0] * 4, "n_samples": [256] * 8, "mode": [1, 2, 3, 4] * 2,
        "rmse_over_crlb": [10.0, 100.0, 1000.0, np.nan] + [np.nan] * 4,
        "failure_rate": [0.0, 0.0, 0.0, 1.0] + [1.0] * 4})
    j = objective(table, penalty=DEFAULT_PENALTY)
    assert DEFAULT_PENALTY == 4.0
    assert j["noise10ug_n256_median_rmse_over_crlb"] == pytest.approx(100.0)
    assert j["noise10ug_n256_failure_rate"] == pytest.approx(0.25)
    assert j["noise10ug_n256_value"] == pytest.approx(3.0)
    assert j["noise1000ug_n256_value"] == pytest.approx(math.log10(FAILED_RATIO) + 4.0)
    assert j["value"] == pytest.approx((3.0 + 16.0) / 2)


def test_relative_per_mode_space_scales_the_base_list():
    """A relative per-mode entry multiplies each loop's base value; trial 0 (factor 1) is the base."""
    spec = {"low": 0.25, "high": 4.0, "log": True, "per_mode": True, "relative": True}
    assert resolve("w", spec, [2.0, 0.5, 1.0, 1.0], [0.6, 4.0, 4.0, 11.3], 4) == pytest.approx([1.2, 2.0, 4.0, 11.3])
    common = {"low": 0.1, "high": 10.0, "log": True, "relative": True}
    assert resolve("p0", common, [3.0], [1.0, 20.0], 2) == pytest.approx([3.0, 60.0])
    space = {"w": spec, "rd": {"low": 1e-6, "high": 1.0, "log": True}, "m": {"choices": ["a", "b"]}}
    assert base_params(space, {"w": [0.6] * 4, "rd": 1e-2, "m": "b"}, 4) == {
        "w[0]": 1.0, "w[1]": 1.0, "w[2]": 1.0, "w[3]": 1.0, "rd": 1e-2, "m": "b"}
    assert "rd" not in base_params(space, {"w": [1.0] * 4, "rd": 10.0, "m": "b"}, 4)   # outside: not enqueued


def test_scoring_seed_is_refused(tmp_path):
    out = tmp_path / "akf_x.yaml"
    proc = run("experiments.tuning.tune", "tuning=akf", f"tuning.seed={SCORING_SEED}", f"tuning.out={out}",
               f"tuning.storage=sqlite:///{tmp_path / 'o.db'}", "runlog.enabled=false")
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and str(SCORING_SEED) in lines[0], proc.stderr
    assert not out.exists() and not (tmp_path / "o.db").exists()


@pytest.mark.slow
def test_tiny_study_writes_a_config_that_composes_and_never_simulates_the_scoring_seed(tmp_path, monkeypatch,
                                                                                        mlflow_uri):
    """2 trials on one tiny cell: configs/method/akf_tiny.yaml is written, composes with Hydra as the variant
    akf:tiny over akf, carries its provenance, every simulated cell used the tuning seed, and the trials are
    MLflow child runs of the study's run."""
    from experiments.tuning import tune

    seeds = []
    real = tune.make_cell          # the simulator the tuning command calls
    monkeypatch.setattr(tune, "make_cell", lambda cfg: seeds.append(cfg.seed) or real(cfg))
    configs = tmp_path / "configs"
    shutil.copytree(ROOT / "configs", configs)
    out = configs / "method" / "akf_tiny.yaml"
    monkeypatch.setattr(sys, "argv", [
        "tune", "tuning=akf", "tuning.variant=tiny", "tuning.trials=2", "tuning.replicates=2", "tuning.seed=11",
        "tuning.cells=[{noise_ug:1000,n_samples:32}]", f"tuning.out={out}",
        f"tuning.storage=sqlite:///{tmp_path / 'optuna.db'}"])
    tune.main()
    assert seeds and set(seeds) == {11}
    import mlflow

    client = mlflow.MlflowClient(mlflow_uri)
    runs = client.search_runs([client.get_experiment_by_name("tuning").experiment_id])
    kinds = {r.data.tags["kind"]: r for r in runs}
    study = kinds["tuning-study"].info.run_id
    trials = [r for r in runs if r.data.tags["kind"] == "tuning-trial"]
    assert len(trials) == 2 and all(r.data.tags["mlflow.parentRunId"] == study for r in trials)
    assert all("value" in r.data.metrics for r in trials)
    text = out.read_text()
    for fragment in ("tuning seed 11", "Trials: 2", "1000 µg/32", "best trial", "Command:"):
        assert fragment in text, text
    register(with_methods=["akf"])
    with initialize_config_dir(config_dir=str(configs), version_base="1.3"):
        cfg = compose(config_name="identify", overrides=["method=akf_tiny"])
    assert cfg.method.name == "akf" and cfg.method.variant == "tiny"
    assert cfg.method.options.measurement in ("position", "acceleration")
    assert cfg.method.options.rd > 0 and len(cfg.method.options.p0_frequency_var) == 4
    # resuming the same study runs no new trial and rewrites the same options
    tune.main()
    assert len(seeds) == 2      # the cells are simulated again, nothing else changes
    assert out.read_text().split("defaults:")[1] == text.split("defaults:")[1]


@pytest.mark.slow
def test_sweep_with_a_failing_trial_finishes(tmp_path):
    """`identify -m` over rd = -1 (bad input) and 0.1: the bad job leaves error.txt, the sweep goes on,
    the good job writes its table and prints its objective."""
    write_cell(DatasetConfig(noise_ug=1000, n_samples=32, replicates=2, seed=5, out=str(tmp_path / "cell.npz")))
    proc = run("experiments.jobs.identify", "-m", "method=akf", "method.options.rd=-1,0.1",
               f"data.dataset={tmp_path / 'cell.npz'}", "runlog.enabled=false", "progress=false",
               f"hydra.sweep.dir={tmp_path / 'sweep'}")
    assert proc.returncode == 0, proc.stderr
    assert "rd = -1" in (tmp_path / "sweep" / "0" / "error.txt").read_text()
    assert (tmp_path / "sweep" / "1" / "results.csv").exists()
    assert "objective" in proc.stdout
