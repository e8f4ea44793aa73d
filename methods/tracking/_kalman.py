"""``akf`` and ``wkf`` as trackers: the filters' own per-sample frequency states (:mod:`methods.kalman.online`).

The random walk ω(k+1) = ω(k) + w₂(k), E w₂² = ``qd_frequency`` (eq. 21) is the tracking model: a frequency
that drifts by δ rad/s per sample is followed with a lag of about δ/K_ω samples, K_ω the steady gain, which
grows with √qd_frequency. P0 of the frequencies is the prior's, (0.27·ω̄)² (the paper's §4.1).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from methods.estimate import make_options, relative_option
from methods.kalman import akf, online, wkf
from methods.tracking._track import Track


@dataclass
class _Online:
    """The options an online filter adds to the batch filter's.

    Attributes
    ----------
    warmup_s : float
        The first ``warmup_s`` seconds scale P0 of the modal and drift states (the batch filter uses the
        whole record's largest magnitude); the track starts at the end of the warm-up.
    warmup_periods : float or None
        The warm-up in periods of the slowest prior mode, 2π/ω_min (a variant that scales with the record);
        given, it sets the warm-up (``warmup_s`` then left at its default; giving both is refused).
    max_restarts : int
        Restarts after a divergence (0: the track ends at the first divergence).
    """

    warmup_s: float = 1.0
    warmup_periods: float | None = None
    max_restarts: int = 20


@dataclass
class AkfOptions(akf.Options, _Online):
    """Tracking options of ``akf``: :class:`methods.kalman.akf.Options` (the paper's §4.1 tuning;
    ``qd_frequency`` the random-walk variance per step) plus :class:`_Online`."""


@dataclass
class WkfOptions(wkf.Options, _Online):
    """Tracking options of ``wkf``: :class:`methods.kalman.wkf.Options` plus :class:`_Online`."""


OPTIONS = {"akf": AkfOptions, "wkf": WkfOptions}
ONLINE_FIELDS = tuple(f.name for f in dataclasses.fields(_Online))


def check_options(name: str, prior, dt: float, options: dict, n_samples: int | None = None):
    opts = make_options(OPTIONS[name], options, name)
    if not (np.isfinite(opts.warmup_s) and dt <= opts.warmup_s):
        raise ValueError(f"{name}: warmup_s = {opts.warmup_s} s must be at least one sample ({dt} s)")
    relative_option(name, "warmup_periods", opts.warmup_periods, "warmup_s", opts.warmup_s, _Online.warmup_s)
    warmup = _warmup_samples(opts, dt, prior)
    if n_samples is not None and warmup > n_samples:
        raise ValueError(f"{name}: warmup_s = {opts.warmup_s} s is longer than the record ({n_samples} samples)")
    if isinstance(opts.max_restarts, bool) or not isinstance(opts.max_restarts, int) or opts.max_restarts < 0:
        raise ValueError(f"{name}: max_restarts = {opts.max_restarts!r} must be an integer ≥ 0")
    online.settings(name, prior, dt, _filter_options(options))
    return opts


def _filter_options(options: dict) -> dict:
    return {k: v for k, v in options.items() if k not in ONLINE_FIELDS}


def _warmup_samples(opts, dt: float, prior) -> int:
    if opts.warmup_periods is not None:
        return max(1, int(round(opts.warmup_periods * 2.0 * np.pi / float(np.min(prior)) / dt)))
    return max(1, int(round(opts.warmup_s / dt)))


def run(name: str, y: np.ndarray, dt: float, prior: np.ndarray, options: dict) -> Track:
    opts = make_options(OPTIONS[name], options, name)
    warmup = _warmup_samples(opts, dt, prior)
    out = online.track_filter(y, dt, prior, name, _filter_options(options), warmup_samples=warmup,
                              max_restarts=opts.max_restarts)
    k = np.arange(warmup - 1, y.size)
    message = f"{name} filter over {y.size} samples"
    if out.divergences:
        message += f"; {len(out.divergences)} divergences (restarted): " + "; ".join(out.divergences[:3])
    std = np.sqrt(np.clip(out.variance[k], 0.0, None))
    std[std == 0.0] = np.nan                 # a frequency held fixed (P0 = Qd = 0) has no 1σ to give
    return Track(k * dt, out.frequencies[k], std, out.determined[k], message=message,
                 extra={"n_divergences": len(out.divergences), "warmup_samples": warmup})
