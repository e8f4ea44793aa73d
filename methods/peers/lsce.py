"""Least-squares complex exponential (``sdypy-ema``: ``EMA.Model(...).get_poles(method="lsce")``).

LSCE fits the impulse response with a linear-prediction polynomial of order 2n by least squares and takes
its roots as poles. sdypy-EMA's LSCE takes frequency response functions and returns to the time domain by
an inverse real FFT; the adapter hands it the record's real FFT (the free decay is the impulse response of
the initial state), so the library's inverse FFT gives back the record itself. Two details of the
library's API: it drops the bin at its ``upper`` limit, so the adapter appends one empty bin above
Nyquist; and its inverse FFT has an even length, so an odd record loses its last sample.

sdypy-EMA computes every order 1…n (its stabilisation diagram); the adapter takes the poles of order n and
:func:`methods.peers._mode_picker.pick_modes` picks the m modes. Settings (methods/peers/README.md): n =
⌈(2m + 1 + ``extra_order``)/2⌉ pole pairs, capped by the library's requirement N > 4n; ``extra_order``
chosen on tuning seed 1 (never the scoring seed). No uncertainty: ``std`` is NaN.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from methods.peers._mode_picker import PeerOptions, check_peer_options, identify_peer, too_short

__all__ = ["Options", "check_options", "identify"]


@dataclass
class Options(PeerOptions):
    # order: the number of poles 2n; None: 2m + 1 + extra_order (rounded up to even)
    extra_order: int = 31            # spare poles beyond modes and offset (tuned on seed 1)


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods`: every check that needs no record, before any work."""
    return check_peer_options(Options, options, "lsce")


def _fit(y, dt, prior, opts: Options):
    from sdypy import EMA  # optional extra (.[peers])

    rec = y[: y.size - y.size % 2]                   # the library's irfft has an even length
    pairs = min(-(-opts.model_order(prior.size) // 2), (rec.size - 1) // 4)  # sdypy-EMA asserts N > 4n
    if 2 * pairs < 2 * prior.size:
        return too_short(prior, y.size, "LSCE")
    spectrum = np.append(np.fft.rfft(rec), 0.0)      # + one empty bin above Nyquist (dropped by the library)
    freq = np.arange(spectrum.size) / (rec.size * dt)
    model = EMA.Model(frf=spectrum, freq=freq, dt=dt, lower=0.0, upper=float(freq[-1]),
                      pol_order_high=int(pairs), frf_form="accelerance")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")              # numpy warnings on rejected poles
        model.get_poles(method="lsce", show_progress=False)
    s = np.asarray(model.all_poles[-1], dtype=complex)
    return opts.estimate(s, rec, dt, prior, order=2 * pairs)


def identify(y, dt, prior, **options):
    """Frequencies of the m most energetic physical poles of sdypy-EMA's LSCE fit of the record."""
    return identify_peer(check_options, _fit, y, dt, prior, options)
