import numpy as np
import pytest

from experiments.simulate.datasets import DatasetConfig, write_cell


@pytest.fixture(scope="session")
def cells(tmp_path_factory):
    """Two small cells with the same noise, length and seed, one with a sensor bias (seeds 1-99: tests)."""
    d = tmp_path_factory.mktemp("cells")
    a = write_cell(DatasetConfig(noise_ug=1000, n_samples=64, replicates=2, seed=7, out=str(d / "a.npz")))
    b = write_cell(DatasetConfig(noise_ug=1000, n_samples=64, replicates=2, seed=7, bias_m_s2=0.01,
                                 out=str(d / "b.npz")))
    return a, b


@pytest.fixture(scope="session")
def measurement(tmp_path_factory, plant):
    """A user's CSV measurement (columns t, accel)."""
    path = tmp_path_factory.mktemp("csv") / "my.csv"
    t = np.arange(256) * 0.02
    accel = plant.tip_acceleration(256, 0.02) + 1e-3 * np.random.default_rng(5).standard_normal(256)
    path.write_text("t,accel\n" + "".join(f"{ti:.6f},{ai:.9e}\n" for ti, ai in zip(t, accel, strict=True)))
    return path
