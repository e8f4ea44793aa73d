"""Any batch method of the registry as a tracker: ``identify`` on a sliding window.

Window j holds the W samples y[e_j − W + 1 … e_j], e_j = W − 1 + jH, and its estimate is stamped at its last
sample, t = e_j Δt: it uses no later sample (causal by construction).

Warm start (``warm_start=True``). The prior of window j is the last estimate of each mode that a window
determined (``converged_per_mode``), the caller's prior for a mode never determined yet (a mix that is not a
valid prior — crossing, above Nyquist — falls back to the caller's prior). Every method reads its prior as
the centre of its search (pem: the start and the band ``frequency_band`` around it; the peers and fft: the
band in which a pole or peak is assigned to a mode), so the search follows a drifting mode. When the previous
window determined at least one mode, a method with a cheaper warm setting (:data:`WARM_OPTIONS`) takes it:
pem runs one Gauss–Newton search from that prior (``n_starts=1``, no matrix-pencil start) instead of its cold
multi-start (its repair restarts still re-seed a mode the search leaves undetermined, from the prior's
ratios); after a window that determined no mode it pays the cold fit again. The other methods have no
iterative search to seed: their cost is the same warm or cold.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

import methods
from methods.estimate import make_options
from methods.tracking import _defaults, _trend
from methods.tracking._track import Track, usable_prior, window_ends

# The window's options: None = from Δt and the prior (methods/tracking/_defaults.py: 5 periods of the slowest
# mode, at least two beats of the closest pair; 486 samples = 9.7 s on the tracking grid's records).
WINDOW_OPTIONS = (("window_samples", int | None, None), ("hop_samples", int | None, None),
                  ("window_s", float | None, None), ("hop_s", float | None, None),
                  ("hop_fraction", float | None, None))
WINDOW_FIELDS = tuple(k for k, _, _ in WINDOW_OPTIONS) + ("warm_start",) + _trend.TREND_FIELDS

# A method's defaults on a window (the caller's options win): pem answers a window's own frequency, not the
# small-amplitude ω₀ it reports for a whole record whose residual is not white (a tracked frequency drifts
# in time, which the amplitude backbone would extrapolate; methods/pem/_chirp.py).
WINDOW_DEFAULTS: dict[str, dict] = {
    "pem": {"drift_frequency": "record"},
}

# A method's options on a window whose prior is the previous window's determined estimate.
WARM_OPTIONS: dict[str, dict] = {
    "pem": {"n_starts": 1, "data_driven_start": False},
}


@functools.cache
def options_class(name: str):
    """The tracking options of batch method ``name``: its own ``Options`` plus the window W and hop H (in
    samples, ``window_samples``/``hop_samples``, or in s, ``window_s``/``hop_s``, or the hop as a fraction of
    the window, ``hop_fraction``; None: from Δt and the prior),
    ``warm_start`` and the trend stage's (:mod:`methods.tracking._trend`)."""
    base = methods.options_class(name)
    return dataclasses.make_dataclass(
        f"{base.__name__}Windowed",
        list(WINDOW_OPTIONS) + [("warm_start", bool, True)]
        + [(k, _trend.TYPES[k], v) for k, v in _trend.DEFAULTS.items()],
        bases=(base,))


def resolve(opts, name: str, prior, dt: float, n_samples: int | None = None, minimum: int | None = None):
    """``opts`` with ``window_samples``/``hop_samples`` in samples (the user's, in s or samples, or the rule's
    of :mod:`methods.tracking._defaults`) and ``window_s``/``hop_s`` None; ``ValueError`` (one line) for a pair
    given twice or a window too short for the prior's modes (``minimum``: 12m samples) or longer than the
    record."""
    W, H = _defaults.window_hop(name, prior, dt, window_s_=opts.window_s, window_samples=opts.window_samples,
                                hop_s=opts.hop_s, hop_samples=opts.hop_samples, hop_fraction=opts.hop_fraction,
                                n_samples=n_samples,
                                minimum=_defaults.min_window_samples(np.size(prior)) if minimum is None else minimum)
    return dataclasses.replace(opts, window_samples=W, hop_samples=H, window_s=None, hop_s=None, hop_fraction=None)


def split(options: dict) -> tuple[dict, dict]:
    """(window options, the method's own options)."""
    return ({k: v for k, v in options.items() if k in WINDOW_FIELDS},
            {k: v for k, v in options.items() if k not in WINDOW_FIELDS})


def check_options(name: str, prior, dt: float, options: dict, n_samples: int | None = None):
    """Check the window options and, through :func:`methods.check_options`, the method's; return the
    tracking options dataclass."""
    methods.require(name)
    window, own = split(options)
    opts = resolve(make_options(options_class(name), options, name), name, prior, dt, n_samples)
    if not isinstance(opts.warm_start, bool):
        raise ValueError(f"{name}: warm_start = {opts.warm_start!r} must be true or false")
    _trend.check(opts, name)
    methods.check_options(name, prior, dt, own)
    if opts.warm_start and name in WARM_OPTIONS:
        methods.check_options(name, prior, dt, own | WARM_OPTIONS[name])
    return opts


def run(name: str, y: np.ndarray, dt: float, prior: np.ndarray, options: dict) -> Track:
    """Track with method ``name`` on sliding windows (module docstring). ``options``: the checked keywords."""
    window, own = split(options)
    own = {**WINDOW_DEFAULTS.get(name, {}), **own}
    opts = resolve(make_options(options_class(name), options, name), name, prior, dt)
    identify = methods.get(name)
    W, H = opts.window_samples, opts.hop_samples
    ends = window_ends(y.size, W, H)
    m = prior.size
    freq = np.full((ends.size, m), np.nan)
    std = np.full((ends.size, m), np.nan)
    conv = np.zeros((ends.size, m), dtype=bool)
    warm_used = np.zeros(ends.size, dtype=bool)
    last_good = np.full(m, np.nan)
    any_determined = False
    failures: list[str] = []
    nyquist = np.pi / dt
    for j, e in enumerate(ends.tolist()):
        seg = y[e - W + 1: e + 1]
        kw = own
        p = prior
        if opts.warm_start:
            p = usable_prior(last_good, prior, nyquist)
            if any_determined and name in WARM_OPTIONS:
                kw = own | WARM_OPTIONS[name]
                warm_used[j] = True
        try:
            est = identify(seg, dt, p, **kw)
        except Exception as exc:        # a library failing on one window loses that window, not the track
            failures.append(f"window ending at sample {e}: {type(exc).__name__}: {exc}")
            any_determined = False
            continue
        freq[j] = est.frequencies
        std[j] = est.std
        conv[j] = est.converged_per_mode & np.isfinite(est.frequencies)
        last_good = np.where(conv[j], est.frequencies, last_good)
        any_determined = bool(conv[j].any())
    message = (f"{ends.size} windows of {W} samples every {H}; {int(conv.all(axis=1).sum())} determined "
               f"every mode; {int(warm_used.sum())} warm-started")
    if failures:
        message += f"; {len(failures)} windows failed (first: {failures[0]})"
    extra = {"window_end_sample": ends, "warm_started": warm_used, "window_failures": len(failures)}
    freq, std, conv, restarts = _trend.apply(opts, ends * dt, freq, std, conv, (W - 1) * dt, extra,
                                                  prior=prior)
    if restarts is not None:
        message += f"; trend stage (centre-stamped, carried to the window's end): {restarts.tolist()} restarts"
    return Track(ends * dt, freq, std, conv, message=message, extra=extra)
