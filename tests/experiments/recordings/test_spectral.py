"""The numpy decimator and Welch estimate are scipy.signal's, to rounding."""

import numpy as np
import pytest
import scipy.signal

from experiments.recordings.spectral import decimate, flat_band, welch


@pytest.mark.parametrize("n, q", [(1000, 2), (1001, 3), (4097, 7), (600, 13)])
def test_decimate_is_resample_poly(n, q):
    x = np.random.default_rng(n).standard_normal(n) + 3.0
    ref = scipy.signal.resample_poly(x, 1, q)
    got = decimate(x, q)
    assert got.shape == ref.shape
    assert np.max(np.abs(got - ref)) <= 1e-12 * np.max(np.abs(ref))


@pytest.mark.parametrize("n, nperseg", [(5000, 256), (5001, 1024), (700, 700), (300, 255)])
def test_welch_is_scipys(n, nperseg):
    x = np.random.default_rng(n).standard_normal(n) + np.sin(0.3 * np.arange(n))
    f_ref, p_ref = scipy.signal.welch(x, fs=512.0, nperseg=nperseg)
    f, p = welch(x, 512.0, nperseg)
    np.testing.assert_allclose(f, f_ref, rtol=1e-12)
    np.testing.assert_allclose(p, p_ref, rtol=1e-9, atol=1e-12 * p_ref.max())


@pytest.mark.parametrize("q", [2, 5])
def test_flat_band_is_where_decimated_white_noise_stops_being_white(q):
    """Against a long simulation with scipy's own decimator: the Welch spectrum of decimated white noise is
    level (within its scatter) below flat_band and has lost power by the new Nyquist frequency."""
    rng = np.random.default_rng(30 + q)
    y = scipy.signal.resample_poly(rng.standard_normal(q * 2**20), 1, q)
    f, p = scipy.signal.welch(y, fs=1.0, nperseg=1024)        # f in cycles per output sample, 0 … 0.5
    level = np.median(p[(f > 0.05) & (f < 0.3)])
    edge = flat_band(q) * 0.5
    assert 0.7 < flat_band(q) < 0.95
    top = (f > edge - 0.04) & (f <= edge)                      # the band's top 40 bins, 2 % rms each
    assert np.mean(p[top]) / level == pytest.approx(1.0, abs=0.015)
    assert p[-2] / level < 0.7                                  # the roll-off: half the power at Nyquist
    assert flat_band(1) == 1.0
