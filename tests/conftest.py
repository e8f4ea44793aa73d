import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from experiments.simulate.datasets import UG
from experiments.simulate.plant import PlantConfig, build_plant

# Physics tests use seeds 1-99; the grids score on seed 20261121 and nothing is tuned on it.


@pytest.fixture(scope="session")
def plant():
    return build_plant(PlantConfig())


@pytest.fixture
def noisy_record(plant):
    def make(n_samples=256, noise_ug=1000.0, seed=1, dt=0.02):
        rng = np.random.default_rng(seed)
        return plant.tip_acceleration(n_samples, dt) + noise_ug * UG * rng.standard_normal(n_samples)
    return make


@pytest.fixture
def mlflow_uri(tmp_path, monkeypatch):
    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", uri)
    os.environ.setdefault("GIT_PYTHON_REFRESH", "quiet")
    return uri


ROOT = Path(__file__).resolve().parents[1]


def _run_snakemake(workdir, *args):
    bindir = Path(sys.executable).parent          # the rules call `python -m ...` of this environment
    env = os.environ | {"PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}"}
    env.pop("MLFLOW_TRACKING_URI", None)
    return subprocess.run([str(bindir / "snakemake"), "-s", str(ROOT / "Snakefile"), "--directory", str(workdir),
                           "--cores", "2", *args], capture_output=True, text=True, timeout=900, env=env)


@pytest.fixture(scope="session")
def snakemake():
    """``snakemake(workdir, *args)``: the project's workflow in a scratch working directory."""
    return _run_snakemake


@pytest.fixture(scope="session")
def smoke_workdir(tmp_path_factory):
    """A scratch directory holding the smoke grid run end to end (once per test session, shared by the
    workflow and the HTML report tests), with its own MLflow store; it neither needs nor touches results/."""
    workdir = tmp_path_factory.mktemp("smoke")
    proc = _run_snakemake(workdir, "smoke")
    assert proc.returncode == 0, proc.stderr[-3000:]
    return workdir
