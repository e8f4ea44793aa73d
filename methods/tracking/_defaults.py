"""Every tracker's sizes from the record's Δt and the prior, in physical terms: the one place of the rule.

A tracker's window, hop, Hankel rows, model orders, minimum segment, memory and trend noises are counted in
samples or in s⁻ᵏ, but what they must cover is physical: periods of the slowest mode, the resolution of the
closest pair of modes, the number of modes. So each default is a number of periods (or of model parameters),
turned into samples with Δt here, and a record time-scaled by a (Δt → aΔt, every ω → ω/a: the same samples)
gets the same defaults in samples and the same relative track. The numbers were chosen so that on the tracking
grid's records (Δt = 0.02 s, prior ≈ [3.23, 20.24, 22.0, 56.67] rad/s) the defaults are the sizes tuned there
(W = 512, H = 50, L = 60, AR 24, min segment 20, trend noises 1e-4 s^-1.5 and 0.002 s⁻¹) to within a few %.

Symbols: ω_min the slowest prior frequency, T = 2π/ω_min its period, g = min ω_{i+1} − ω_i the smallest gap
between prior frequencies (rad/s; none for one mode), m the number of modes, Δt the sample interval.

Window (s)
    W_s = max(``PERIODS`` · T, min(``GAP_CYCLES`` · 2π/g, ``GAP_CAP_PERIODS`` · T))
    — five periods of the slowest mode (a window fit that sees fewer confuses a decaying mode with a drifting
    one) and two cycles of the closest pair's beat 2π/g (its Fourier resolution: a window much shorter than
    the beat cannot separate the pair; parametric fits resolve down to about half of it at good SNR), the beat
    term capped at 20 periods (a prior with two nearly equal frequencies must not ask for a window that no
    drift holds still over). W = round(W_s/Δt), and at least the model's minimum below.
Hop
    H = max(1, round(``HOP_FRACTION`` · W)): ten estimates per window span (a step is seen within a tenth of a
    window of the first window that carries it).
Minimum window (samples) for m modes
    generic (a batch method on a window): 12m — three samples per parameter of m damped sinusoids (ω, ζ,
    amplitude, phase); ``gated_pencil``: 3(n + 1), n = 2m + ``extra_order`` the pencil's order (the Hankel
    matrix needs L ≥ n rows and ≥ 2L columns). After a detected change (:mod:`methods.tracking._memory`)
    the window restarts and estimates again from max(this minimum, ``RESTART_PERIODS`` · T) samples.
Pencil order (``gated_pencil``)
    n = 2m + e, the spare poles e (for the noise's colour) = clip(⌊W/4⌋ − 1 − 2m, 2, 8): at most eight, and
    no more than a window of W samples affords with room for one pulse, W ≥ 4(n + 1) (a window of a few
    samples per period — five periods of 6 samples — would otherwise be held at the 3(2m + 9) minimum by
    spare poles it cannot fit, and lose most windows to one flagged sample). The tracking grid: e = 8.
Hankel rows (``gated_pencil``)
    L = clip(round(W/8), n, W/3 − 1): an eighth of the window (so that a column seldom straddles a pulse and
    ≥ 2L columns survive), never fewer than the order.
Pulse detector's AR order
    p = clip(round(W/20), 2m + 2, 2m + 16): the modes plus spare poles for the noise colour, at most one
    coefficient per 20 samples of the robust regression.
Minimum segment
    max(2(2m + 1), round(W/25)): a segment carries 2m amplitudes and an offset of its own.
RLS memory (``rls_ar``)
    λ = 1 − 1/W: the exponential memory equals the window the others use.
Trend noises
    ``trend_rate_noise`` = 2.7e-4 · T^(−3/2) (s^−3/2) and ``trend_rate0`` = 0.0039 / T (s⁻¹): the frequency's
    acceleration noise and the initial rate's std in units of the slowest period (time-scaling by a
    multiplies them by a^(−3/2) and a⁻¹, as their units ask); ``trend_meas_rel``, ``trend_gate`` and
    ``trend_restart_after`` are dimensionless and stay.
    ``gated_pencil``'s ``trend_memory`` (window spans; :func:`trend_rate_noise_memory`) instead sets the rate
    noise from the window: the filter's own time constant is ``trend_memory`` window spans.

Options a user gives win: ``window_s``/``hop_s`` (s) or ``window_samples``/``hop_samples``, or the hop as a
fraction of the window (``hop_fraction``, what a grid uses to thin the costliest trackers' windows on records
of any Δt); giving a window or a hop twice is refused. A user's window is honoured: the sizes above scale to
it, and it is refused only when it is shorter than the minimum for m modes (the message gives it in s and
samples).
"""

from __future__ import annotations

import numpy as np

PERIODS = 5.0                 # window: periods of the slowest mode
GAP_CYCLES = 2.0              # window: cycles of the closest pair's beat 2π/g
GAP_CAP_PERIODS = 20.0        # ... capped at this many periods of the slowest mode
HOP_FRACTION = 0.1            # hop: this fraction of the window
RESTART_PERIODS = 2.0         # shortest window after a detected change, periods of the slowest mode
ROWS_FRACTION = 1.0 / 8.0     # Hankel rows: this fraction of the window
AR_SAMPLES_PER_COEF = 20      # pulse detector: at most one AR coefficient per this many samples
AR_EXTRA_MAX = 16             # ... and at most 2m + this
MIN_SEGMENT_FRACTION = 1.0 / 25.0
RATE_NOISE_PER_PERIOD = 2.7e-4     # trend_rate_noise · T^1.5
RATE0_PER_PERIOD = 0.0039          # trend_rate0 · T


def slowest_period_s(prior) -> float:
    """T = 2π/ω_min, s."""
    return float(2.0 * np.pi / np.min(prior))


def window_s(prior) -> float:
    """The default window span W_s in s (module docstring)."""
    prior = np.sort(np.asarray(prior, dtype=float))
    T = slowest_period_s(prior)
    span = PERIODS * T
    if prior.size > 1:
        gap = float(np.min(np.diff(prior)))
        span = max(span, min(GAP_CYCLES * 2.0 * np.pi / gap, GAP_CAP_PERIODS * T))
    return span


def min_window_samples(m: int, order: int | None = None) -> int:
    """The shortest window for m modes: 12m samples, or 3(n + 1) for a pencil of order n."""
    return max(8, 12 * m) if order is None else max(8, 3 * (order + 1))


def restart_samples(prior, dt: float, minimum: int) -> int:
    """Samples a window needs after a restart: max(``minimum``, ``RESTART_PERIODS`` periods)."""
    return max(minimum, int(round(RESTART_PERIODS * slowest_period_s(prior) / dt)))


def _pair(tracker: str, s_name: str, s_value, n_name: str, n_value, dt: float, low: int):
    """Samples from a value given in s or in samples (not both); None when neither is given."""
    if s_value is not None and n_value is not None:
        raise ValueError(f"{tracker}: give {s_name} or {n_name}, not both ({s_name} = {s_value!r}, "
                         f"{n_name} = {n_value!r})")
    if s_value is not None:
        if isinstance(s_value, bool) or not isinstance(s_value, (int, float, np.integer, np.floating)) \
                or not (np.isfinite(s_value) and s_value > 0):
            raise ValueError(f"{tracker}: {s_name} = {s_value!r} must be a positive number of seconds")
        return max(int(round(s_value / dt)), 1 if low <= 1 else 0)
    if n_value is not None:
        if isinstance(n_value, bool) or not isinstance(n_value, (int, np.integer)) or n_value < low:
            raise ValueError(f"{tracker}: {n_name} = {n_value!r} must be an integer number of samples ≥ {low}")
        return int(n_value)
    return None


def window_hop(tracker: str, prior, dt: float, *, window_s_=None, window_samples=None, hop_s=None,
               hop_samples=None, hop_fraction=None, minimum: int, n_samples: int | None = None) -> tuple[int, int]:
    """(W, H) in samples: the user's (in s or samples) or the rule's; the hop may also be given as a fraction
    of the window, H = max(1, round(``hop_fraction`` · W)) (a grid's coarser hop that follows the prior: it
    counts no samples). ``ValueError`` (one line) for a window or a hop given twice, a ``hop_fraction``
    outside (0, 1], a window shorter than ``minimum`` samples (the minimum for the prior's modes) or longer
    than the record."""
    W = _pair(tracker, "window_s", window_s_, "window_samples", window_samples, dt, 8)
    given = W is not None
    if W is None:
        W = max(int(round(window_s(prior) / dt)), minimum)
    if W < minimum:
        raise ValueError(f"{tracker}: a window of {W} samples ({W * dt:.4g} s) is too short for "
                         f"{np.size(prior)} mode(s): needs at least {minimum} samples ({minimum * dt:.4g} s)")
    H = _pair(tracker, "hop_s", hop_s, "hop_samples", hop_samples, dt, 1)
    if hop_fraction is not None:
        if H is not None:
            given_hop = "hop_s" if hop_s is not None else "hop_samples"
            raise ValueError(f"{tracker}: give hop_fraction or {given_hop}, not both (hop_fraction = "
                             f"{hop_fraction!r}, {given_hop} = {hop_s if hop_s is not None else hop_samples!r})")
        if isinstance(hop_fraction, bool) or not isinstance(hop_fraction, (int, float, np.integer, np.floating)) \
                or not (0 < hop_fraction <= 1):
            raise ValueError(f"{tracker}: hop_fraction = {hop_fraction!r} must be a number in (0, 1] (the hop "
                             "as a fraction of the window)")
    if H is None:
        H = max(1, int(round((HOP_FRACTION if hop_fraction is None else hop_fraction) * W)))
    if n_samples is not None and W > n_samples:
        what = "window_samples" if given else "the default window (5 periods of the slowest mode)"
        raise ValueError(f"{tracker}: {what} = {W} is longer than the record ({n_samples} samples; the window "
                         f"is {W * dt:.4g} s)")
    return W, H


EXTRA_ORDER_MIN, EXTRA_ORDER_MAX = 2, 8


def pencil_extra_order(W: int, m: int) -> int:
    """The pencil's spare poles e for a window of W samples and m modes (module docstring)."""
    return int(np.clip(W // 4 - 1 - 2 * m, EXTRA_ORDER_MIN, EXTRA_ORDER_MAX))


def pencil_sizes(W: int, m: int, order: int, rows=None, ar_order=None, min_segment=None) -> tuple[int, int, int]:
    """(L, p, min segment) of ``gated_pencil`` for a window of W samples (module docstring); a value the user
    gave is kept."""
    if rows is None:
        rows = int(np.clip(round(ROWS_FRACTION * W), order, max(order, W // 3 - 1)))
    if ar_order is None:
        ar_order = int(np.clip(round(W / AR_SAMPLES_PER_COEF), 2 * m + 2, 2 * m + AR_EXTRA_MAX))
        ar_order = min(ar_order, max(2, (W - 1) // 2))
    if min_segment is None:
        min_segment = max(2 * (2 * m + 1), int(round(MIN_SEGMENT_FRACTION * W)))
    return rows, ar_order, min_segment


def forgetting(W: int) -> float:
    """λ of an exponential memory as long as a window of W samples."""
    return 1.0 - 1.0 / W


def trend_noises(prior) -> dict:
    """``trend_rate_noise`` (s^−3/2) and ``trend_rate0`` (s⁻¹) in units of the slowest period."""
    T = slowest_period_s(prior)
    return {"trend_rate_noise": RATE_NOISE_PER_PERIOD * T ** -1.5, "trend_rate0": RATE0_PER_PERIOD / T}


def trend_rate_noise_memory(meas_rel: float, window_s: float, memory_windows: float) -> float:
    """The trend stage's ``trend_rate_noise`` (relative to ω) that gives its filter a time constant of
    ``memory_windows`` window spans.

    The local-linear-trend filter of :mod:`methods.tracking._trend` (process noise filterpy's
    ``Q_discrete_white_noise``: a piecewise-constant ω̈ of std q·ω over each step; measurement std r·ω,
    r = ``meas_rel``, the floor of its R) is, in steady state and with steps short against its memory, a
    second-order loop of damping 1/√2 and natural frequency ω_n = √(q/r), whatever the step. Setting
    1/ω_n = ``memory_windows`` · ``window_s`` gives

        q = r / (``memory_windows`` · ``window_s``)².

    With 1/ω_n shorter than a window the filter follows the errors of overlapping windows (correlated over a
    window's span) as a rate; the prior-based rule (:func:`trend_noises`, q ∝ T^−3/2) gives 1/ω_n ∝ T^3/4: 0.5–0.7
    of a five-period window at slowest periods of 2–8 s, two windows at 25 ms. Time-scaling by a multiplies q by
    a⁻², so the memory stays the same number of windows.
    """
    return float(meas_rel / (memory_windows * window_s) ** 2)
