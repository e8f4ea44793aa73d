import numpy as np
import pytest

import methods


def test_fft_finds_modes_1_and_4_on_noise_free_256_samples(plant):
    y = plant.tip_acceleration(256, 0.02)
    est = methods.get("fft")(y, 0.02, [3.8, 16.0, 26.0, 46.0])
    assert est.frequencies.shape == (4,)
    np.testing.assert_allclose(est.frequencies[[0, 3]], plant.freq_rad_s[[0, 3]], rtol=0.01)
    assert np.all(np.isnan(est.std))
    assert est.history is None


def test_fft_interpolation_beats_bin_spacing_on_a_single_tone():
    t = np.arange(512) * 0.02
    y = np.cos(12.345 * t + 0.4)
    est = methods.get("fft")(y, 0.02, [11.0])
    assert abs(est.frequencies[0] - 12.345) < 0.01 * (2 * np.pi / (512 * 0.02))


def test_fft_reports_failure_when_no_peak_near_prior():
    t = np.arange(256) * 0.02
    est = methods.get("fft")(np.cos(10 * t), 0.02, [10.0, 60.0])
    assert not est.converged
    assert np.isnan(est.frequencies[1])
    assert "60" in est.message


@pytest.mark.parametrize("prior, message", [([3.0, -1.0], r"prior\[1\] = -1.0 rad/s must be a positive"),
                                            ([3.0, 200.0], "above the Nyquist frequency"),
                                            ([], "non-empty")])
def test_fft_rejects_bad_prior(prior, message):
    with pytest.raises(ValueError, match=message):
        methods.get("fft")(np.ones(64), 0.02, prior)


def test_unknown_method_and_option_are_named():
    with pytest.raises(ValueError, match="unknown method 'nope'"):
        methods.get("nope")
    with pytest.raises(ValueError, match="unknown option 'windw'"):
        methods.get("fft")(np.ones(64), 0.02, [3.0], windw="hann")
