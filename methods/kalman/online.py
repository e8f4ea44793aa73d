"""The paper's filters as online trackers: the per-sample frequency states of ``akf``/``wkf`` over a long record.

The filter is the one of :func:`methods.kalman._filter.run_filter` (filterpy's EKF, the exact modal
transition, the random-walk frequency states of eq. 21, whose process noise ``qd_frequency`` sets how fast a
frequency may move), with two changes that an online run needs:

* **causal P0.** The batch filter scales the initial variances of the modal and drift states by the largest
  magnitude of the *whole* record; online, that is the largest magnitude of the first ``warmup_samples``
  samples only, so an estimate made after the warm-up depends on no later sample.
* **restart after divergence.** A batch run that diverges is a failed estimate; a tracker must go on. From the
  sample after a divergence the filter restarts, with P0 of the frequencies (0.27·ω̄)² about the last
  frequencies it held before it diverged (the prior where those are not a valid prior), up to
  ``max_restarts`` times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from methods.estimate import check_prior
from methods.kalman import akf, wkf
from methods.kalman._filter import DETERMINED_VARIANCE_SHARE, FilterSettings, double_integrate, run_filter


@dataclass(frozen=True)
class OnlineRun:
    """Per-sample output of :func:`track_filter` (n samples, m modes)."""

    frequencies: np.ndarray      # (n, m) frequency states after each sample's update, NaN where diverged
    variance: np.ndarray         # (n, m) their filter variances
    determined: np.ndarray       # (n, m) variance ≤ DETERMINED_VARIANCE_SHARE × the no-information variance
    divergences: list[str]       # one message per divergence


def settings(method: str, prior, dt: float, options: dict) -> FilterSettings:
    """The checked filter settings of ``akf`` or ``wkf`` for this prior (the options of that method)."""
    module = {"akf": akf, "wkf": wkf}[method]
    dt, prior = check_prior(dt, prior)
    return module._settings(prior, dt, options)


def causal_scale(y: np.ndarray, dt: float, warmup_samples: int) -> tuple[float, float]:
    """(max |y|, max |z|) over the first ``warmup_samples`` samples, z the twice-integrated record: the
    scale of P0 for the modal and drift states (``_initial_covariance``)."""
    head = y[:warmup_samples]
    return float(np.max(np.abs(head))), float(np.max(np.abs(double_integrate(head, dt))))


def track_filter(y: np.ndarray, dt: float, prior: np.ndarray, method: str, options: dict, *,
                 warmup_samples: int, max_restarts: int) -> OnlineRun:
    """Run filter ``method`` (``akf``/``wkf``, its ``options``) over ``y`` and keep every sample's estimate.

    The frequency is "determined" at sample k of a run started at k₀ when its variance P_ωω(k) is at most
    half of what it would be without measurements, P0 + (k − k₀)·Qd (the batch filter's rule, per sample).
    """
    n, m = y.size, prior.size
    scale = causal_scale(y, dt, warmup_samples)
    freq = np.full((n, m), np.nan)
    var = np.full((n, m), np.nan)
    determined = np.zeros((n, m), dtype=bool)
    w_index = np.arange(2 * m, 3 * m)            # the frequency states of the layout (q, q̇, ω, …)
    divergences: list[str] = []
    start, p = 0, prior
    while start < n:
        s = settings(method, p, dt, options)
        seg_var = np.empty((n - start, m))

        def observer(k, x, P, seg_var=seg_var):
            seg_var[k] = P[w_index, w_index]

        est = run_filter(y[start:], dt, p, s, observer=observer, scale=scale)
        done = est.history.shape[0]
        stop = start + done
        freq[start:stop] = est.history
        var[start:stop] = seg_var[:done]
        no_info = s.p0_frequency_var + np.arange(done)[:, None] * s.qd_frequency
        with np.errstate(divide="ignore", invalid="ignore"):
            determined[start:stop] = seg_var[:done] <= DETERMINED_VARIANCE_SHARE * no_info
        if est.converged:
            break
        divergences.append(est.message.replace(f"at sample {done - 1}", f"at sample {stop - 1}"))
        freq[stop - 1] = np.nan                       # the diverged state is no estimate
        determined[stop - 1] = False
        if len(divergences) > max_restarts:
            break
        last = est.history[-2] if done > 1 else p
        p = _restart_prior(last, prior, dt)
        start = stop
    return OnlineRun(freq, var, determined, divergences)


def _restart_prior(last: np.ndarray, prior: np.ndarray, dt: float) -> np.ndarray:
    """The last frequencies held, where they make a valid prior (positive, below Nyquist, increasing)."""
    ok = np.isfinite(last) & (last > 0) & (last < np.pi / dt)
    mix = np.where(ok, last, prior)
    return mix if np.all(np.diff(mix) > 0) else prior.copy()
