import numpy as np
import pytest

from experiments.io import read_npz
from experiments.simulate.datasets import UG, DatasetConfig, make_cell, write_cell
from experiments.simulate.plant import PlantConfig, build_plant


def cfg(tmp_path, **kw):
    base = dict(noise_ug=1000.0, n_samples=256, replicates=4, seed=7, out=str(tmp_path / "cell.npz"))
    return DatasetConfig(**(base | kw))


def test_same_config_gives_same_bytes(tmp_path):
    a = write_cell(cfg(tmp_path, out=str(tmp_path / "a.npz"))).read_bytes()
    b = write_cell(cfg(tmp_path, out=str(tmp_path / "b.npz"))).read_bytes()
    assert a == b
    c = write_cell(cfg(tmp_path, seed=8, out=str(tmp_path / "c.npz"))).read_bytes()
    assert a != c


def test_noise_in_file_has_the_configured_sigma(tmp_path):
    # 200 x 256 residuals: the sample std of 51200 normal draws is within 1 % of sigma with > 99.9 % prob.
    cell = make_cell(cfg(tmp_path, noise_ug=100.0, replicates=200, seed=3))
    resid = cell["accel_m_s2"] - cell["accel_clean_m_s2"]
    assert np.std(resid) == pytest.approx(100 * UG, rel=0.01)
    assert abs(np.mean(resid)) < 4 * 100 * UG / np.sqrt(resid.size)
    # replicates are independent: correlation between two rows is small
    assert abs(np.corrcoef(resid[0], resid[1])[0, 1]) < 0.25


def test_bias_is_added_to_every_sample(tmp_path):
    cell = make_cell(cfg(tmp_path, noise_ug=0.1, bias_m_s2=0.05))
    resid = cell["accel_m_s2"] - cell["accel_clean_m_s2"]
    assert np.mean(resid) == pytest.approx(0.05, rel=1e-4)


def test_fewer_replicates_are_a_prefix_of_more(tmp_path):
    small = make_cell(cfg(tmp_path, replicates=3))
    large = make_cell(cfg(tmp_path, replicates=10))
    np.testing.assert_array_equal(small["accel_m_s2"], large["accel_m_s2"][:3])


def test_file_holds_truth_from_the_generating_model(tmp_path):
    path = write_cell(cfg(tmp_path, plant=PlantConfig(calibrate=False)))
    cell = read_npz(path)
    truth = build_plant(PlantConfig(calibrate=False))
    np.testing.assert_allclose(cell["truth_freq_rad_s"], truth.freq_rad_s)
    assert cell["accel_m_s2"].shape == (4, 256)
    assert cell["crlb_std_rad_s"].shape == (4,)
    assert "numpy" in str(cell["provenance_json"])


def test_file_loads_with_plain_numpy_without_pickle(tmp_path):
    path = write_cell(cfg(tmp_path))
    with np.load(path, allow_pickle=False) as f:
        assert float(f["noise_ug"]) == 1000.0


@pytest.mark.parametrize("bad, message", [(dict(noise_ug=0.0), "noise_ug = 0.0 must be positive"),
                                          (dict(noise_ug=-1.0), "must be positive"),
                                          (dict(n_samples=7), "n_samples = 7 is too short"),
                                          (dict(replicates=0), "replicates = 0")])
def test_impossible_cells_are_rejected(tmp_path, bad, message):
    with pytest.raises(ValueError, match=message):
        make_cell(cfg(tmp_path, **bad))
