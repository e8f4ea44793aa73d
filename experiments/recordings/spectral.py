"""scipy.signal's ``resample_poly(x, 1, q)`` and ``welch`` with their default settings, in numpy.

Written here for one reason, measured: importing ``scipy.signal`` pulls in scipy.stats, scipy.interpolate
and scipy.ndimage, 1.0 s of the identify job's 3 s of CPU on a 10⁵-sample file (``python -X importtime``,
experiments.benchmarks.measurement), for two functions of a few lines each. Both reproduce scipy's to
rounding (tests/experiments/recordings/test_spectral.py compares them with scipy.signal itself).
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["KAISER_BETA", "HALF_LENGTH", "FLAT_TOLERANCE", "antialias_taps", "decimate", "flat_band", "welch"]

KAISER_BETA = 5.0          # resample_poly's default window ('kaiser', 5.0)
HALF_LENGTH = 10           # resample_poly's half-length of the filter, in output samples (10 × q input)
FLAT_TOLERANCE = 0.01      # flat_band: the decimated noise's power within 1 % of its level at 0 Hz


def antialias_taps(q: int) -> np.ndarray:
    """The low-pass FIR of ``scipy.signal.resample_poly(x, 1, q)``: ``firwin(20q + 1, 1/q,
    window=('kaiser', 5.0))``,

        h[k] = (1/q) sinc((k − 10q)/q) · w_kaiser[k],   scaled to unit gain at 0 Hz.
    """
    n = 2 * HALF_LENGTH * q + 1
    m = np.arange(n) - (n - 1) / 2
    h = np.sinc(m / q) / q * np.kaiser(n, KAISER_BETA)
    return h / h.sum()


@functools.lru_cache(maxsize=16)
def flat_band(q: int, tolerance: float = FLAT_TOLERANCE) -> float:
    """The top of the band, as a fraction of the new Nyquist frequency, in which white noise decimated by
    :func:`decimate` (q) is still white: its power density there,

        S(ν) ∝ Σₖ |H((ν + k)/q)|²   (ν in cycles per output sample, H the filter's response, k over the aliases),

    stays within ``tolerance`` of S(0). Above it the filter's roll-off halves the noise power by the new
    Nyquist frequency (0.84 for q ≥ 2 at 1 %: the residual check of such a record judges below it)."""
    if q <= 1:
        return 1.0
    h = antialias_taps(q)
    nfft = 1 << max(14, int(np.ceil(np.log2(64 * h.size))))
    power = np.abs(np.fft.rfft(h, nfft)) ** 2                   # at f = i/nfft cycles per input sample
    nu = np.linspace(0.0, 0.5, 2001)
    f = np.abs(nu[:, None] + np.arange(-q, q + 1)[None, :]) / q
    s = np.interp(f, np.arange(power.size) / nfft, power, right=0.0).sum(axis=1)
    off = np.abs(s / s[0] - 1.0) > tolerance
    return float(nu[np.argmax(off) - 1] / 0.5) if off.any() else 1.0


def decimate(x: np.ndarray, q: int) -> np.ndarray:
    """Every q-th sample of ``x`` filtered by :func:`antialias_taps` (zero phase: output j is centred on
    input jq; zeros beyond the ends), as ``scipy.signal.resample_poly(x, 1, q)``:

        y[j] = Σₖ h[k] x[jq + 10q − k],   j = 0 … ⌈N/q⌉ − 1.

    Only the kept outputs are computed: ⌈N/q⌉ dot products of 20q + 1 taps (20N multiplications).
    """
    x = np.asarray(x, float)
    if q == 1:
        return x.copy()
    h = antialias_taps(q)
    half = HALF_LENGTH * q
    padded = np.concatenate([np.zeros(half), x, np.zeros(half)])
    n_out = -(-x.size // q)
    windows = np.lib.stride_tricks.sliding_window_view(padded, h.size)[::q][:n_out]
    return windows @ h[::-1]


def welch(x: np.ndarray, fs: float, nperseg: int) -> tuple[np.ndarray, np.ndarray]:
    """Welch's power spectral density as ``scipy.signal.welch(x, fs, nperseg=nperseg)``: periodic Hann
    window, half-overlapping segments, each segment's mean removed, one-sided density (units² / Hz):

        P(f) = c / (fs Σ w²) · mean over segments |Σₙ w[n] (x_s[n] − x̄_s) e^(−2πi f n / fs)|²,

    c = 2 except at 0 Hz and, for even ``nperseg``, at Nyquist (c = 1).
    """
    x = np.asarray(x, float)
    nperseg = min(int(nperseg), x.size)
    step = nperseg - nperseg // 2
    w = np.hanning(nperseg + 1)[:-1]                       # periodic Hann (scipy's get_window('hann'))
    segs = np.lib.stride_tricks.sliding_window_view(x, nperseg)[::step]
    segs = segs - segs.mean(axis=1, keepdims=True)
    p = np.abs(np.fft.rfft(segs * w, axis=1)) ** 2 / (fs * np.sum(w**2))
    p[:, 1:] *= 2
    if nperseg % 2 == 0:
        p[:, -1] /= 2
    return np.fft.rfftfreq(nperseg, 1.0 / fs), p.mean(axis=0)
