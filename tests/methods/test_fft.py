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


def test_fft_keeps_a_mode_well_above_the_noise_floor(noisy_record, plant):
    """The detection test (peak ≥ ln(K/α) × the noise floor) must not reject real modes: at 0.01 g on 256
    samples modes 1 and 4 stand orders of magnitude above the floor."""
    est = methods.get("fft")(noisy_record(256, noise_ug=1e4, seed=3), 0.02, [3.8, 16.0, 26.0, 46.0])
    assert est.converged and est.converged_per_mode.all(), est.message
    assert np.all(est.extra["peak_to_floor"] > 10 * est.extra["detection_threshold"])
    np.testing.assert_allclose(est.frequencies[[0, 3]], plant.freq_rad_s[[0, 3]], rtol=0.02)


def test_fft_pure_noise_rarely_passes_the_detection_test():
    """For white noise each ordinate is exponential about its mean μ and the largest of K = n/2 exceeds
    μ·ln(K/α) with probability ≈ α; the zero-padded (continuous) maximum and the estimated floor raise the
    realised rate to 2–4 × α over the whole spectrum. The search bands cover 40 % of it: at the default
    α = 1 %, fewer than 5 % of pure-noise records may show any peak above the threshold (measured 1.75 %)."""
    fft = methods.get("fft")
    alarms = 0
    for seed in range(400):
        est = fft(np.random.default_rng(seed).standard_normal(256), 0.02, [3.8, 16.0, 26.0, 46.0])
        alarms += bool(np.any(est.extra["peak_to_floor"] >= est.extra["detection_threshold"]))
    assert 0 < alarms / 400 < 0.05


def test_fft_long_record_gives_the_full_zero_padded_answer_in_linear_memory():
    """Beyond max_fft_length the FFT is computed at max_fft_length points and each peak is refined on the
    zero-padded grid by the chirp z-transform: the same interpolated peak as the full 16×-padded FFT."""
    n = 2**17
    t = np.arange(n) * 0.02
    y = (np.exp(-0.0005 * t) * (np.cos(3.23 * t) + np.cos(20.24 * t) + 0.5 * np.cos(22.0 * t) + np.cos(56.67 * t))
         + 0.3 * np.random.default_rng(4).standard_normal(n))
    fft = methods.get("fft")
    capped = fft(y, 0.02, [3.8, 16.0, 26.0, 46.0])
    full = fft(y, 0.02, [3.8, 16.0, 26.0, 46.0], max_fft_length=2**22)
    assert capped.extra["nfft"] == 2**20 and full.extra["nfft"] == capped.extra["nfft_padded"] == 2**21
    np.testing.assert_allclose(capped.frequencies, full.frequencies, rtol=0, atol=1e-9)
    assert capped.converged and full.converged


@pytest.mark.parametrize("n, nfft", [(20, 4096), (2048, 32768), (65536, 2**20), (10**6, 2**20), (3 * 10**6, 2**22)])
def test_fft_length_rule(n, nfft):
    """16× zero padding up to 65 536 samples (every grid; results unchanged), then the cap, but never below n."""
    from methods.fft import Options, fft_length

    assert fft_length(n, Options())[0] == nfft


@pytest.mark.parametrize("option, value", [("window", "bogus"), ("zero_pad_factor", 0), ("max_fft_length", 5000),
                                           ("search_halfwidth", 1.5), ("false_alarm", 0.0)])
def test_fft_check_options_rejects_impossible_values(option, value):
    with pytest.raises(ValueError, match=option):
        methods.check_options("fft", [3.8, 16.0], 0.02, {option: value})
