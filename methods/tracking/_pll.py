"""``pll`` as a tracker: the VCO frequency of each loop after every sample (paper §3.4, Fig. 2).

The loop bank of :mod:`methods.pll` is a tracker by design: ω(k) = ω₀ + v(k), v the loop filter's output
(eq. 37), is the estimate at sample k. Two of the batch run's conveniences look ahead, and are changed:

* ``remove_mean`` (the whole record's mean subtracted) is off by default and refused: the Chebyshev band-pass
  input filters already block a bias.
* the AGC starts at √2 × the RMS of the first max(T_AGC, 2 periods of ω₀) of the filtered input; the track
  starts after the longest of these lead-ins (``extra["lead_in_samples"]``), so no estimate uses a later sample.

``converged``: the batch run's lock test on a trailing window instead of the record's end: over the last
acquisition time 4π/ω_L of the loop (§3.4), the mean of its lock indicator 2i/Â (≈ cos φₑ, low-passed) is at
least ``lock_threshold``, the indicator never fell below 0 (no cycle slip), and the mean frequencies of the
window's two halves agree within ``steady_tolerance`` (not still acquiring); pandas' trailing rolling
statistics, so the test at sample k sees samples ≤ k only.
``std``: NaN (a loop reports no uncertainty).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from methods import pll
from methods.estimate import make_options
from methods.pll import design
from methods.tracking._track import Track


@dataclass
class PllOptions(pll.Options):
    """Tracking options of ``pll``: :class:`methods.pll.Options` (the loop gains and bandwidths, per loop),
    with ``remove_mean`` off (not causal). The batch's output-window options are unused."""

    remove_mean: bool = False


def check_options(name: str, prior, dt: float, options: dict, n_samples: int | None = None):
    opts = make_options(PllOptions, options, name)
    if opts.remove_mean:
        raise ValueError("pll: remove_mean = True subtracts the whole record's mean, which a causal tracker "
                         "cannot know; leave it False")
    pll.check_options(prior, dt, **_batch(options))
    lead = lead_in_samples(opts, prior, dt)
    if n_samples is not None and lead > n_samples:
        raise ValueError(f"pll: the AGC lead-in ({lead} samples) is longer than the record ({n_samples} samples)")
    return opts


def _batch(options: dict) -> dict:
    return {"remove_mean": False} | options


def lead_in_samples(opts, prior: np.ndarray, dt: float) -> int:
    """Samples the loops' initial AGC level is measured on (``methods.pll``'s loop: max(2, T_AGC/Δt,
    4π/(ω₀Δt)) per loop, T_AGC = agc_time_factor/ω_L); the track starts at the last of them."""
    if opts.loop_bandwidth_rad_s is not None:
        omega_l = np.broadcast_to(np.asarray(opts.loop_bandwidth_rad_s, float).reshape(-1), prior.shape)
    elif opts.loop_bandwidth_rel is not None:        # ω_L in units of each loop's ω₀
        omega_l = np.broadcast_to(np.asarray(opts.loop_bandwidth_rel, float).reshape(-1), prior.shape) * prior
    else:
        omega_l = design.default_loop_bandwidth(prior, dt)
    t_agc = opts.agc_time_factor / omega_l
    lead = [max(2, int(round(max(ta, 4.0 * math.pi / w0) / dt))) for ta, w0 in zip(t_agc, prior, strict=True)]
    return max(lead)


def run(name: str, y: np.ndarray, dt: float, prior: np.ndarray, options: dict) -> Track:
    opts = make_options(PllOptions, options, name)
    est = pll.identify(y, dt, prior, **_batch(options))
    lead = min(lead_in_samples(opts, prior, dt), y.size)
    k = np.arange(lead - 1, y.size)
    if est.history is None:            # a flat record: no loop ran
        nan = np.full((k.size, prior.size), np.nan)
        return Track(k * dt, nan, nan, False, message=est.message)
    locked = _locked(est.history, est.extra["lock_history"], est.extra["acquisition_time_s"], dt, opts)[k]
    lock = est.extra["lock_history"][k]
    return Track(k * dt, est.history[k], np.nan, locked,
                 message=f"{prior.size} loops over {y.size} samples; locked in {float(np.mean(locked)):.0%} of "
                         f"the loop-samples",
                 extra={"lead_in_samples": lead, "lock_indicator": lock})


def _locked(history: np.ndarray, lock: np.ndarray, acquisition_s: np.ndarray, dt: float, opts) -> np.ndarray:
    """(n, m): over each loop's trailing acquisition time, the mean lock indicator ≥ ``lock_threshold``, its
    minimum ≥ 0, and the mean frequencies of the window's two halves within ``steady_tolerance`` of each
    other (the batch run's three tests; windows not yet full: not locked)."""
    out = np.zeros(lock.shape, dtype=bool)
    for j in range(lock.shape[1]):
        n_acq = max(2, int(round(float(acquisition_s[j]) / dt)))
        half = n_acq // 2
        trail = pd.Series(lock[:, j]).rolling(n_acq, min_periods=n_acq)
        w_mean = pd.Series(history[:, j]).rolling(half, min_periods=half).mean().to_numpy()
        earlier = np.concatenate((np.full(half, np.nan), w_mean[:-half]))
        steady = np.abs(w_mean - earlier) <= opts.steady_tolerance * np.abs(w_mean)
        out[:, j] = ((trail.mean() >= opts.lock_threshold) & (trail.min() >= 0.0)).to_numpy() & steady
    return out
