"""FFT baseline: windowed, zero-padded periodogram, peak picking near each prior, sub-bin interpolation.

The first thing a practitioner would try, and the yardstick the paper's methods must beat. Its resolution
is about 2π/(N·Δt) (1.23 rad/s at N = 256, Δt = 0.02 s): modes 2 and 3 (1.76 rad/s apart) merge below
N ≈ 256, and the window's main lobe biases nearby peaks towards each other. It gives no uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal

from methods.estimate import Estimate, check_inputs, make_options


@dataclass
class Options:
    window: str = "hann"                 # any scipy.signal.get_window name
    zero_pad_factor: int = 16            # FFT length = next power of two ≥ factor × N (at least 4096)
    search_halfwidth: float = 0.35       # band around each prior, relative (±35 %), cut at neighbours' midpoints
    dynamic_range_db: float = 60.0       # peaks this far below the strongest are window sidelobes, not modes


def identify(y, dt, prior, **options) -> Estimate:
    """Frequencies of the periodogram's largest local maxima near each prior frequency.

    The periodogram is |FFT(w·(y − ȳ))|² over an FFT zero-padded to ``nfft`` points; each peak is refined by
    a parabola through the log-power of the three bins around it (sub-bin interpolation).
    """
    y, dt, prior = check_inputs(y, dt, prior)
    opts = make_options(Options, options, "fft")
    if opts.zero_pad_factor < 1:
        raise ValueError(f"zero_pad_factor = {opts.zero_pad_factor} must be at least 1")
    if not 0 < opts.search_halfwidth < 1:
        raise ValueError(f"search_halfwidth = {opts.search_halfwidth} must be in (0, 1)")
    n = y.size
    nfft = max(4096, 1 << int(np.ceil(np.log2(n * opts.zero_pad_factor))))
    window = scipy.signal.get_window(opts.window, n)
    f_hz, power = scipy.signal.periodogram(y, fs=1.0 / dt, window=window, nfft=nfft, detrend="constant",
                                           scaling="spectrum")
    omega = 2 * np.pi * f_hz
    d_omega = omega[1] - omega[0]
    peaks, _ = scipy.signal.find_peaks(power, height=power.max() * 10 ** (-opts.dynamic_range_db / 10))
    log_p = np.log(np.maximum(power, np.finfo(float).tiny))

    order = np.argsort(prior)
    sorted_prior = prior[order]
    freq = np.full(prior.size, np.nan)
    taken: set[int] = set()
    for rank, i in enumerate(order):
        lo = prior[i] * (1 - opts.search_halfwidth)
        hi = prior[i] * (1 + opts.search_halfwidth)
        if rank > 0:
            lo = max(lo, 0.5 * (sorted_prior[rank - 1] + prior[i]))
        if rank < prior.size - 1:
            hi = min(hi, 0.5 * (sorted_prior[rank + 1] + prior[i]))
        inside = [k for k in peaks if lo <= omega[k] <= hi and k not in taken]
        if not inside:
            continue
        k = max(inside, key=lambda j: power[j])
        taken.add(k)
        a, b, c = log_p[k - 1], log_p[k], log_p[k + 1]
        denom = a - 2 * b + c
        delta = 0.5 * (a - c) / denom if denom < 0 else 0.0
        freq[i] = omega[k] + delta * d_omega
    missing = np.flatnonzero(np.isnan(freq))
    message = ("peaks found near every prior" if missing.size == 0 else
               "no spectral peak near prior " + ", ".join(f"{prior[i]:g}" for i in missing) + " rad/s")
    return Estimate(freq, np.full(prior.size, np.nan), converged=missing.size == 0, iterations=0,
                    message=message, extra={"nfft": nfft})
