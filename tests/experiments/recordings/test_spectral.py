"""The numpy decimator and Welch estimate are scipy.signal's, to rounding."""

import numpy as np
import pytest
import scipy.signal

from experiments.recordings.spectral import decimate, welch


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
