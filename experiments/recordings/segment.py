"""The part of a measurement to identify: the free decay after the impact, in the band of interest.

A hammer test or a thruster firing records some noise before the blow, the blow itself (a force the
methods' free-decay model does not contain) and then the free decay, a sum of damped sinusoids. Chosen
here:

- **span**: ``start_s``/``stop_s`` (file time, s) when given; otherwise from just after the largest impulse
  (the sample of largest |y − median y|, plus the anti-alias filter's half-length, so that neither the
  blow nor the filter's response to it is in the record) to where the decay has sunk into the noise
  (:func:`_decay_end`); a record with no quiet stretch before its largest sample (:func:`_quiet_before`)
  starts in its decay, and all of it is used;
- **band**: ``band_hz`` = hi or [lo, hi] when given; otherwise up to 1.25 × the highest frequency whose
  Welch power stands 30 dB above the median (noise) level of the decay's spectrum
  (``scipy.signal.welch``'s estimate, :mod:`experiments.recordings.spectral`);
- **decimation** by q = ⌊f_s / (2.5 f_hi)⌋ (new Nyquist 1.25 f_hi, inside the anti-alias filter's pass
  band), never below :data:`KEEP_SAMPLES` samples of the span, with ``scipy.signal.resample_poly``'s
  filter (a Kaiser-windowed FIR, zero phase; computed by :mod:`experiments.recordings.spectral`, which
  says why); applied to the whole record before the span is cut, so its edge transients fall outside the
  decay.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

MIN_SEGMENT_SAMPLES = 64          # fewer leave the stabilisation diagram and the fit nothing to work with
AUTO_BAND_DB = 30.0               # a spectral line this far above the median level is signal
AUTO_BAND_MARGIN = 1.25           # the band's top: this × the highest such line
OVERSAMPLING = 2.5                # new sampling rate ≥ this × the band's top (Nyquist 1.25 × top)
NOISE_MARGIN = 1.2               # the decay has ended where the moving rms is within 20 % of the noise's
KEEP_SAMPLES = 512               # decimation leaves at least this many samples of the span (or all it has)
FILTER_HALF_LENGTH = 10           # resample_poly's FIR half-length in output samples (10 × q input samples)


@dataclass(frozen=True)
class Segment:
    """The record to identify and how it was chosen.

    Attributes
    ----------
    y : ndarray, shape (n,)
        Acceleration, m/s², at the (decimated) interval ``dt``.
    dt : float
        Sample interval, s.
    t0 : float
        File time of ``y[0]``, s.
    decimation : int
        q: every q-th sample of the anti-alias filtered record (1: none).
    band_hz : (float, float)
        The band searched for modes, Hz.
    impulse_s : float or None
        File time of the largest impulse, when the start was chosen automatically.
    notes : list of str
        What was chosen, to be printed.
    """

    y: np.ndarray
    dt: float
    t0: float
    decimation: int
    band_hz: tuple[float, float]
    impulse_s: float | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def stop_s(self) -> float:
        return self.t0 + (self.y.size - 1) * self.dt


def parse_band(band_hz, dt: float, where: str) -> tuple[float, float] | None:
    """``band_hz`` (None, hi, or [lo, hi]) as (lo, hi) in Hz, checked against the Nyquist frequency."""
    if band_hz is None:
        return None
    try:
        vals = [float(v) for v in (band_hz if isinstance(band_hz, list | tuple) else [band_hz])]
    except (TypeError, ValueError):
        raise ValueError(f"{where}: data.band_hz = {band_hz!r} must be hi or [lo, hi] in Hz") from None
    if len(vals) == 1:
        vals = [0.0, vals[0]]
    if len(vals) != 2 or not all(math.isfinite(v) for v in vals) or not 0 <= vals[0] < vals[1]:
        raise ValueError(f"{where}: data.band_hz = {band_hz} must be hi or [lo, hi] with 0 ≤ lo < hi (Hz)")
    nyquist = 0.5 / dt
    if vals[1] > nyquist * (1 + 1e-9):          # the fitted step: Nyquist to rounding
        raise ValueError(f"{where}: data.band_hz = {band_hz} reaches above the Nyquist frequency {nyquist:.6g} Hz "
                         f"of the record (sampled at {1 / dt:.6g} Hz)")
    return vals[0], vals[1]


def choose_segment(y: np.ndarray, dt: float, t0: float = 0.0, *, start_s: float | None = None,
                   stop_s: float | None = None, band_hz=None, cover_hz: float = 0.0,
                   where: str = "record") -> Segment:
    """The free decay to identify, decimated to its band (module docstring).

    Parameters
    ----------
    y : ndarray, shape (N,)
        The whole record, m/s².
    dt, t0 : float
        Sample interval and file time of ``y[0]``, s.
    start_s, stop_s : float, optional
        The span in file time; default: from just after the largest impulse to the end.
    band_hz : float or [float, float], optional
        The band of interest, Hz; default: from the spectrum.
    cover_hz : float
        The automatic band reaches at least this high (a prior's highest mode with margin).
    where : str
        Names the record in an error (the file).

    Raises
    ------
    ValueError
        A span outside the record, a band above Nyquist, or fewer than :data:`MIN_SEGMENT_SAMPLES` samples
        left after segmentation.
    """
    n = y.size
    end_s = t0 + (n - 1) * dt
    band = parse_band(band_hz, dt, where)
    for name, v in (("start_s", start_s), ("stop_s", stop_s)):
        if v is not None and not t0 <= v <= end_s:
            raise ValueError(f"{where}: data.{name} = {v} s is outside the record ({t0:.6g} s to {end_s:.6g} s)")
    impulse = None
    notes = []
    if start_s is None:
        impulse = int(np.argmax(np.abs(y - np.median(y))))
        if not _quiet_before(y, impulse):
            impulse = None         # a record that starts in its free decay: all of it is the decay
            notes.append("the record starts in its decay (no quiet stretch before its largest sample): "
                         "from its first sample")
        i0 = impulse or 0
    else:
        i0 = int(math.ceil((start_s - t0) / dt - 1e-9))
    if stop_s is None and impulse is not None:      # the noise level is known from before the blow
        i1, why = _decay_end(y, i0, impulse)
        if why:
            notes.append(why + " (set data.stop_s= to choose)")
    elif stop_s is None:
        i1 = n
    else:
        i1 = int(math.floor((stop_s - t0) / dt + 1e-9)) + 1
    if band is None:
        band, why = _auto_band(y[i0:i1], dt)
        if cover_hz > band[1]:
            band, why = (0.0, min(cover_hz, 0.5 / dt)), "to cover the prior"
        notes.append(f"band {band[0]:.4g}–{band[1]:.4g} Hz ({why}; set data.band_hz= to choose)")
    else:
        notes.append(f"band {band[0]:.4g}–{band[1]:.4g} Hz (data.band_hz)")
    q = max(1, int(math.floor(1.0 / (dt * OVERSAMPLING * band[1]))))
    q = min(q, max(1, (i1 - i0) // KEEP_SAMPLES))         # a short record is not decimated below this
    yd = _decimate(y, q)
    guard = FILTER_HALF_LENGTH if q > 1 else 0
    # after the impulse: one sample more, and the filter's half-length (its response to the blow)
    j0 = int(math.ceil(i0 / q)) + (guard + 1 if impulse is not None else 0)
    j1 = min((i1 - 1) // q + 1, yd.size - guard)
    seg = yd[j0:j1]
    dtd = dt * q
    if q > 1:
        notes.append(f"decimated by {q} to {1 / dtd:.6g} Hz (anti-alias FIR, as scipy.signal.resample_poly)")
    start = t0 + j0 * dtd
    if impulse is not None:
        notes.insert(0, f"free decay from {start:.6g} s, after the largest impulse at {t0 + impulse * dt:.6g} s "
                        f"(set data.start_s= to choose)")
    elif start_s is not None:
        notes.insert(0, f"span from {start:.6g} s (data.start_s)")
    else:
        notes.insert(0, f"span from {start:.6g} s")
    if seg.size < MIN_SEGMENT_SAMPLES:
        raise ValueError(f"{where}: {seg.size} samples from {start:.6g} s to {t0 + (j1 - 1) * dtd:.6g} s after "
                         f"segmentation and decimation (by {q}); at least {MIN_SEGMENT_SAMPLES} are needed")
    notes[0] += f" to {start + (seg.size - 1) * dtd:.6g} s: {seg.size} samples"
    return Segment(seg, dtd, start, q, band, None if impulse is None else t0 + impulse * dt, notes)


def _quiet_before(y: np.ndarray, k: int) -> bool:
    """Whether the record is quiet before sample k (a pre-trigger stretch): at least 32 samples before it
    whose robust spread (1.4826 × median absolute deviation: the rise of the blow itself does not count)
    is under a tenth of the rms of the 16 samples from k."""
    if k < 32:
        return False
    before = y[:k]
    level = np.median(before)
    spread = 1.4826 * np.median(np.abs(before - level))
    return bool(spread < 0.1 * np.sqrt(np.mean((y[k:k + 16] - level) ** 2)))


def _decay_end(y: np.ndarray, i0: int, impulse: int) -> tuple[int, str]:
    """Where the decay sinks into the noise: the first sample after ``i0`` whose moving rms (window W =
    max(64, N/200) samples) is within :data:`NOISE_MARGIN` of the noise level, plus W; the noise level is
    the robust std (1.4826 × MAD) of the record before the impulse. The record beyond holds no information
    on the modes, and costs time."""
    n = y.size
    w = max(64, n // 200)
    quiet = y[:impulse]
    sigma = 1.4826 * float(np.median(np.abs(quiet - np.median(quiet))))
    rms = np.sqrt(_moving_mean((y - np.median(quiet)) ** 2, w))
    below = np.flatnonzero(rms[i0:] < NOISE_MARGIN * sigma)
    if sigma <= 0 or below.size == 0 or i0 + below[0] + w >= n:
        return n, ""
    end = i0 + int(below[0]) + w
    return end, (f"decay into the noise ({sigma:.3g} m/s² rms) by sample {end} of {n}: the rest is left out")


def _moving_mean(x: np.ndarray, w: int) -> np.ndarray:
    """Mean of x over a centred window of w samples (shorter at the ends), by a cumulative sum: written
    here because scipy.ndimage.uniform_filter1d costs 0.4 s of import for one moving average."""
    c = np.concatenate([[0.0], np.cumsum(x)])
    k = np.arange(x.size)
    lo, hi = np.maximum(k - w // 2, 0), np.minimum(k + (w - w // 2), x.size)
    return (c[hi] - c[lo]) / (hi - lo)


def _auto_band(y: np.ndarray, dt: float) -> tuple[tuple[float, float], str]:
    from experiments.recordings.spectral import welch

    nyquist = 0.5 / dt
    if y.size < 16:
        return (0.0, nyquist), "record too short for a spectrum: the whole band"
    f, p = welch(y - y.mean(), 1.0 / dt, min(4096, y.size))
    floor = np.median(p)
    lines = np.flatnonzero(p > floor * 10 ** (AUTO_BAND_DB / 10))
    if floor <= 0 or lines.size == 0:
        return (0.0, nyquist), f"no line {AUTO_BAND_DB:g} dB above the noise: the whole band"
    top = float(f[lines[-1]])
    return (0.0, min(AUTO_BAND_MARGIN * top, nyquist)), (f"highest line {AUTO_BAND_DB:g} dB above the noise "
                                                         f"at {top:.4g} Hz")


def _decimate(y: np.ndarray, q: int) -> np.ndarray:
    """Every q-th sample after an anti-alias low-pass (``scipy.signal.resample_poly``'s Kaiser FIR, cut-off
    at the new Nyquist, :func:`experiments.recordings.spectral.decimate`); the record's mean is taken out
    for the filter and put back, so its zero padding at the ends meets a record near zero."""
    if q == 1:
        return np.asarray(y, float)
    from experiments.recordings.spectral import decimate

    c = float(np.mean(y))
    return decimate(y - c, q) + c
