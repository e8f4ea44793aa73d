"""``pll`` as a tracker: the VCO frequency of each loop after every sample (paper §3.4, Fig. 2).

The loop bank of :mod:`methods.pll` is a tracker by design: ω(k) = ω₀ + v(k), v the loop filter's output
(eq. 37), is the estimate at sample k. Two of the batch run's conveniences look ahead, and are changed:

* ``remove_mean`` (the whole record's mean subtracted) is off by default and refused: the Chebyshev band-pass
  input filters already block a bias.
* the AGC starts at √2 × the RMS of the first max(T_AGC, 2 periods of ω₀) of the filtered input; the track
  starts after the longest of these lead-ins (``extra["lead_in_samples"]``), so no estimate uses a later sample.

``converged``: the loop's lock indicator 2i/Â (≈ cos φₑ, low-passed) is at least ``lock_threshold``.
``std``: NaN (a loop reports no uncertainty).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

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
    lock = est.extra["lock_history"][k]
    return Track(k * dt, est.history[k], np.nan, lock >= opts.lock_threshold,
                 message=f"{prior.size} loops over {y.size} samples; lock indicator ≥ {opts.lock_threshold} in "
                         f"{float(np.mean(lock >= opts.lock_threshold)):.0%} of the samples",
                 extra={"lead_in_samples": lead, "lock_indicator": lock})
