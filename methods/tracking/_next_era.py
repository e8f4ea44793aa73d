"""``next_era``: the naive baseline — NExT (the window's autocorrelation) through ERA, modes matched in order.

On each window of W samples (every H samples, stamped at its last sample):

1. NExT (James, Carne & Lauffer, 1993): under white excitation the autocorrelation of the response,
   R(τ) = (1/W) Σ_k y(k) y(k + τ), τ = 0 … L − 1 with L = ``lags_fraction``·W, is a sum of decaying
   sinusoids at the structure's modes — a free decay (scipy.signal.correlate, the biased estimate);
2. ERA (python-control's ``control.era``, as :mod:`methods.peers.era`) realises R(1 …) with order 2m + 1 +
   ``extra_order``; poles z become s = log(z)/Δt;
3. the physical poles (ω_d > 0, below Nyquist, damping in [0, ``max_damping``]) are sorted by frequency and
   matched to the previous window's estimates (the prior at the start) by ``linear_sum_assignment`` on
   |log ω − log ω_prev|, within ``band``.

No energy test, no warm start of a search, no uncertainty (``std`` NaN): the naive tracker the others must beat.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.signal

import methods
from methods.estimate import flat_record, make_options
from methods.tracking import _defaults
from methods.tracking._track import Track, window_ends


@dataclass
class Options:
    """Options of ``next_era``: window W and hop H in samples or in s (None: the same rule as every windowed
    tracker's, :mod:`methods.tracking._defaults`, so that every ratio to this baseline compares equal windows),
    the correlation lags L = lags_fraction·W, the ERA order 2m + 1 + extra_order, and the matching band and
    damping limit."""

    window_samples: int | None = None
    hop_samples: int | None = None
    window_s: float | None = None
    hop_s: float | None = None
    hop_fraction: float | None = None
    lags_fraction: float = 0.5
    extra_order: int = 3
    band: float = 0.3
    max_damping: float = 0.2


def check_options(name: str, prior, dt: float, options: dict, n_samples: int | None = None) -> Options:
    methods.require("era")          # python-control, the optional extra .[peers]
    opts = resolve(make_options(Options, options, name), name, prior, dt, n_samples)
    if not 0 < opts.lags_fraction <= 1:
        raise ValueError(f"{name}: lags_fraction = {opts.lags_fraction} must be in (0, 1]")
    if isinstance(opts.extra_order, bool) or not isinstance(opts.extra_order, int) or opts.extra_order < 0:
        raise ValueError(f"{name}: extra_order = {opts.extra_order!r} must be an integer ≥ 0")
    if not opts.band > 0:
        raise ValueError(f"{name}: band = {opts.band} must be positive")
    if not opts.max_damping > 0:
        raise ValueError(f"{name}: max_damping = {opts.max_damping} must be positive")
    lags = int(opts.lags_fraction * opts.window_samples)
    if lags - 1 < 2 * (2 * np.size(prior) + 1 + opts.extra_order):
        raise ValueError(f"{name}: {lags} correlation lags (window_samples × lags_fraction) are too few for "
                         f"the ERA order {2 * np.size(prior) + 1 + opts.extra_order}")
    return opts


def resolve(opts: Options, name: str, prior, dt: float, n_samples: int | None = None) -> Options:
    """``opts`` with the window and hop in samples (the user's, or the rule's of every windowed tracker)."""
    if isinstance(opts.extra_order, bool) or not isinstance(opts.extra_order, int) or opts.extra_order < 0:
        raise ValueError(f"{name}: extra_order = {opts.extra_order!r} must be an integer ≥ 0")
    lags_fraction = opts.lags_fraction if 0 < opts.lags_fraction <= 1 else 0.5
    # the ERA needs 2(2m + 1 + extra_order) + 1 lags of the window
    minimum = int(np.ceil((2 * (2 * np.size(prior) + 1 + opts.extra_order) + 2) / lags_fraction))
    W, H = _defaults.window_hop(name, prior, dt, window_s_=opts.window_s, window_samples=opts.window_samples,
                                hop_s=opts.hop_s, hop_samples=opts.hop_samples, hop_fraction=opts.hop_fraction,
                                n_samples=n_samples,
                                minimum=max(minimum, _defaults.min_window_samples(np.size(prior))))
    return dataclasses.replace(opts, window_samples=W, hop_samples=H, window_s=None, hop_s=None, hop_fraction=None)


def era_poles(seg: np.ndarray, dt: float, lags: int, order: int, max_damping: float) -> np.ndarray:
    """NExT + ERA on one window: the physical modes' ω (rad/s, ascending) of an order-``order`` realisation of the
    window's biased autocorrelation R(0 … lags − 1) (steps 1–2 of the module docstring; ω_d > 0, below Nyquist,
    damping in [0, ``max_damping``])."""
    import control  # optional extra .[peers]

    W = seg.size
    seg = seg - seg.mean()
    r = scipy.signal.correlate(seg, seg, mode="full", method="fft")[W - 1: W - 1 + lags] / W
    usable = lags - 1                        # control.era drops the first Markov parameter (feedthrough)
    rows = usable // 2
    sysd, _ = control.era(r, order, m=rows, n=usable - rows, dt=dt)
    z = np.linalg.eigvals(sysd.A)
    z = z[np.abs(z) > 0]
    s = np.log(z) / dt
    w = np.abs(s)
    keep = (s.imag > 0) & (w < np.pi / dt) & (-s.real <= max_damping * w) & (s.real <= 0)
    return np.sort(w[keep])


def match(cand: np.ndarray, ref_log: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray]:
    """Candidates ``cand`` (rad/s) matched to the references ``ref_log`` (ln rad/s) by ``linear_sum_assignment`` on
    |ln ω − ln ω_ref| within ``limit``: (candidate indices, reference indices)."""
    if cand.size == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    dist = np.abs(np.log(cand)[:, None] - ref_log[None, :])
    cost = np.where(dist <= limit, dist, 1e6)
    rr, cc = scipy.optimize.linear_sum_assignment(cost)
    hit = cost[rr, cc] < 1e6
    return rr[hit], cc[hit]


def run(name: str, y: np.ndarray, dt: float, prior: np.ndarray, options: dict) -> Track:
    methods.require("era")          # python-control, the optional extra .[peers]
    opts = resolve(make_options(Options, options, name), name, prior, dt)
    W, H = opts.window_samples, opts.hop_samples
    ends = window_ends(y.size, W, H)
    m = prior.size
    lags = int(opts.lags_fraction * W)
    order = 2 * m + 1 + opts.extra_order
    freq = np.full((ends.size, m), np.nan)
    found = np.zeros((ends.size, m), dtype=bool)
    ref = np.log(prior)
    limit = np.log1p(opts.band)
    for j, e in enumerate(ends.tolist()):
        seg = y[e - W + 1: e + 1]
        if flat_record(seg):
            continue
        cand = era_poles(seg, dt, lags, order, opts.max_damping)
        rr, cc = match(cand, ref, limit)
        freq[j, cc] = cand[rr]
        found[j, cc] = True
        ref = ref.copy()
        ref[cc] = np.log(cand[rr])
    return Track(ends * dt, freq, np.nan, found,
                 message=f"NExT-ERA (order {order}, {lags} lags) on {ends.size} windows of {W} samples every {H}",
                 extra={"window_end_sample": ends, "order": order})
