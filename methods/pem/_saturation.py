"""A sensor that saturates: samples held at the record's extreme value, found and left out of the fit.

A clipped sensor writes every sample beyond its range as the range's end, so the record's largest (or
smallest) value repeats: a plateau at ±max. No model of damped sinusoids explains it, the residual check
fails, and the distortion (a deterministic one) moves the frequencies; the clipped stretch at high
amplitude also looks like a frequency that changes with amplitude to the drift test
(``methods.pem._drift``). :func:`detect` flags an extreme level held by at least :data:`MIN_PLATEAU`
samples and by more than :data:`PILE_UP` times as many samples as the next level inside it. A record of
continuous values never repeats its extreme. A quantised one does (rounding to a step of 10 noise std gave
two samples at the minimum in the mismatch grid), but its extreme level holds no more samples than the
level next to it, where a clipped one holds every sample beyond the range; when the rest of the record has
ties (quantised), a plateau needs twice :data:`MIN_PLATEAU` samples (at a step of 0.5–1 noise std in noise
10× the signal, 3 samples at the extreme against 1 inside happened by chance in 1–2 % of records). A level
holding more than half the record is not a sensor's range but a record that says nothing: not flagged.
:func:`methods.pem.identify` then fits the record after its last clipped sample (``Options.skip_clipped``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

MIN_PLATEAU = 3      # samples at one extreme value that make a plateau (two ties happen in quantised data)
PILE_UP = 2.0        # ... and more than this many times the count of the next level inside


def _side(y: np.ndarray, level: float) -> tuple[int, int]:
    """(samples at ``level``, samples at the nearest other value on the inner side)."""
    at = y == level
    n = int(np.count_nonzero(at))                    # (at.sum()'s value, without the bool → int reduction)
    if n < MIN_PLATEAU or at.all():
        return n, 0
    rest = y[~at]
    inner = rest.max() if level > rest.max() else rest.min()
    return n, int(np.count_nonzero(rest == inner))


def detect(y) -> dict | None:
    """Whether ``y`` is clipped: None when neither extreme is a plateau (module docstring), else a dict with
    ``levels_m_s2`` (the clipped extreme values), ``plateau_samples`` (samples at them, per level),
    ``inner_samples`` (samples at the next level inside, per level), ``clipped_samples`` (in all),
    ``fraction`` and ``last_clipped`` (index of the last sample at a clipped level). O(N)."""
    y = np.asarray(y, float)
    if y.size < 2 * MIN_PLATEAU or not np.isfinite(y).all():
        return None
    levels, plateau, inner = [], [], []
    for level in (float(y.max()), float(y.min())):
        n, n_in = _side(y, level)
        if n < MIN_PLATEAU or not n > PILE_UP * n_in or level in levels or n > y.size / 2:
            continue
        rest = y[(y != y.max()) & (y != y.min())]
        if n >= 2 * MIN_PLATEAU or np.unique(rest).size == rest.size:      # quantised: a longer plateau
            levels.append(level)
            plateau.append(n)
            inner.append(n_in)
    if not levels or np.isin(y, levels).sum() > y.size / 2:
        return None
    clipped = np.flatnonzero(np.isin(y, levels))
    return {"levels_m_s2": levels, "plateau_samples": plateau, "inner_samples": inner,
            "clipped_samples": int(clipped.size), "fraction": float(clipped.size / y.size),
            "last_clipped": int(clipped[-1])}


def attach(est, clip: dict, start: int):
    """The estimate with ``extra["saturation"]`` (:func:`detect`'s dict and ``fit_start``, the first sample
    the fit used: 0 when too few samples follow the last clipped one) and a note in its message."""

    levels = ", ".join(f"{v:.4g}" for v in clip["levels_m_s2"])
    note = (f"the sensor clipped: {clip['clipped_samples']} samples at {levels} m/s² (plateaus of "
            f"{', '.join(map(str, clip['plateau_samples']))} samples), "
            + (f"fitted from sample {start}, after the last clipped one" if start else
               "too few samples follow the last clipped one: fitted as it is, the distortion included"))
    return dataclasses.replace(est, extra={**est.extra, "saturation": {**clip, "fit_start": int(start)}},
                               message=f"{est.message}; {note}")
