"""Frequency-weighted augmented Kalman filter (paper §3.2, §4.2, eqs. 25–29 and 38).

The measurement is passed through a weighting filter H(s) = K ω0² / (s² + 2ξω0 s + ω0²) (eq. 38),
discretised with a zero-order hold, and the filter's model is the augmented model of ``akf`` followed by
the same discrete weighting filter (eq. 27). Its states start at zero with zero covariance (§4.2), the
weighting filter's input noise enters as Δ_f R_d Δ_fᵀ (eq. 28) and R_f is the measurement variance of
the weighted output (eq. 29).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy.signal import cont2discrete

from methods.estimate import Estimate, make_options, relative_option
from methods.kalman import akf
from methods.kalman._filter import Weighting, identify_record, settings_from
from methods.kalman._lockstep import identify_each

__all__ = ["Options", "weighting_filter", "identify", "identify_batch", "check_options"]


@dataclass
class Options(akf.Options):
    """Options of the frequency-weighted Kalman filter: those of :class:`methods.kalman.akf.Options` (same
    meaning, same defaults — including P0 of the frequencies derived from the prior, (0.27·ω̄_n)² —, §4.2
    "The initial conditions are as for the augmented Kalman filter") plus the weighting filter of
    eq. (38) and R_f of eq. (29).

    Attributes
    ----------
    weight_gain : float
        K of eq. (38), the DC gain of the weighting filter (§4.2: 10).
    weight_omega0_rad_s : float
        ω0 of eq. (38) (§4.2: 3 rad/s).
    weight_omega0_rel : float or None
        ω0 in units of the slowest prior frequency, ω0 = weight_omega0_rel · ω_min, so that a time-scaled
        record gets the same weighting in samples. Given, it sets ω0 (``weight_omega0_rad_s`` then left at its
        default; giving both is refused). None: ``weight_omega0_rad_s``.
    weight_damping : float
        ξ of eq. (38) (§4.2: 0.2).
    r_f : float
        R_f of eq. (29), variance of the weighted measurement (§4.2: 0.005).
    """

    weight_gain: float = 10.0
    weight_omega0_rad_s: float = 3.0
    weight_omega0_rel: float | None = None
    weight_damping: float = 0.2
    r_f: float = 0.005


def weighting_filter(gain: float, omega0_rad_s: float, damping: float, dt: float) -> Weighting:
    """Eq. (38) in controllable canonical form, discretised with a zero-order hold (eq. 26).

    H(s) = K ω0² / (s² + 2ξω0 s + ω0²): ẋ_f = [[0, 1], [−ω0², −2ξω0]] x_f + [0, 1]ᵀ u,
    y_f = [K ω0², 0] x_f. The zero-order hold keeps the filter strictly proper (no feedthrough, as in
    eq. 26, so y_f(k) depends on the states only) and keeps the DC gain K exactly; the bilinear
    transform would add a feedthrough term that eq. (26) has no room for.
    """
    a = np.array([[0.0, 1.0], [-omega0_rad_s**2, -2.0 * damping * omega0_rad_s]])
    b = np.array([[0.0], [1.0]])
    c = np.array([[gain * omega0_rad_s**2, 0.0]])
    phi_f, delta_f, c_f, _, _ = cont2discrete((a, b, c, np.zeros((1, 1))), dt, method="zoh")
    return Weighting(phi_f=phi_f, delta_f=delta_f[:, 0], c_f=c_f[0])


def identify(y, dt, prior, **options) -> Estimate:
    """Identify the modal frequencies with the frequency-weighted Kalman filter of §3.2.

    Parameters
    ----------
    y : array_like, shape (n,)
        Tip acceleration in m/s², sampled at t_k = kΔt.
    dt : float
        Sample interval Δt in s.
    prior : array_like, shape (m,)
        A-priori frequencies in rad/s (Table 3); the initial frequency states.
    **options
        Fields of :class:`Options`.

    Returns
    -------
    Estimate
        As :func:`methods.kalman.akf.identify`: last frequency states, their filter std, the per-sample history.

    Examples
    --------
    One mode at 20.3 rad/s, started from 19 rad/s, the acceleration fed to the filter as measured:

    >>> import numpy as np
    >>> from methods.kalman import wkf
    >>> t = 0.02 * np.arange(512)
    >>> est = wkf.identify(4.0 * np.cos(20.3 * t), 0.02, [19.0], measurement="acceleration")
    >>> bool(abs(est.frequencies[0] - 20.3) < 0.05)
    True
    """
    return identify_record(y, dt, prior, functools.partial(_settings, options=options))


def identify_batch(y, dt, priors, **options) -> list[Estimate]:
    """As :func:`methods.kalman.akf.identify_batch`, for this filter: :func:`identify` on every row of ``y``, the
    R filters in lock-step."""
    return identify_each(y, dt, priors, functools.partial(_settings, options=options))


def _settings(prior, dt, options: dict):
    """The checked filter settings for a prior, with the discretised weighting filter of eq. (38)."""
    opts = check_options(prior, dt, **options)
    wf = weighting_filter(opts.weight_gain, weight_omega0(opts, prior), opts.weight_damping, dt)
    return settings_from(opts, prior, "wkf", dt=dt, weighting=wf, r_f=float(opts.r_f))


def weight_omega0(opts: Options, prior) -> float:
    """ω0 of eq. (38), rad/s: ``weight_omega0_rel`` · ω_min when given, else ``weight_omega0_rad_s``."""
    if opts.weight_omega0_rel is None:
        return float(opts.weight_omega0_rad_s)
    return float(opts.weight_omega0_rel * np.min(prior))


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods` (validated without a record, before any work)."""
    opts = make_options(Options, options, "wkf")
    for name in ("weight_gain", "weight_omega0_rad_s", "weight_damping"):
        val = getattr(opts, name)
        if not (np.isfinite(val) and val > 0):
            raise ValueError(f"wkf: {name} = {val} must be a positive number")
    if not (np.isfinite(opts.r_f) and opts.r_f >= 0):
        raise ValueError(f"wkf: r_f = {opts.r_f} must be a non-negative number")
    relative_option("wkf", "weight_omega0_rel", opts.weight_omega0_rel, "weight_omega0_rad_s",
                    opts.weight_omega0_rad_s, Options.weight_omega0_rad_s)
    settings_from(opts, prior, "wkf", dt=dt)
    return opts
