import os

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
