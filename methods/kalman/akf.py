"""Augmented (extended) Kalman filter for the modal frequencies (paper §3.1, §4.1, eqs. 8–24).

The modal oscillators of eq. (8) (four in the paper; one per prior frequency here) and as many
random-walk frequency states (eq. 21) form one state vector; the filter is linearised about the current
estimate (eq. 24). The model and the filter loop are in :mod:`methods.kalman._filter`; this module is the
method's face and its options.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

from methods.estimate import Estimate, make_options
from methods.kalman._filter import identify_record, settings_from
from methods.kalman._lockstep import identify_each

__all__ = ["Options", "identify", "identify_batch", "check_options"]


@dataclass
class Options:
    """Options of the augmented Kalman filter; defaults are the paper's §4.1 tuning, generalised to any
    number of modes (the per-mode P0 of the frequencies is derived from the prior).

    Attributes
    ----------
    measurement : str
        ``"position"`` (eq. 9; the accelerometer integrated twice, the paper's choice) or
        ``"acceleration"`` (eq. 10, nonlinear in ω).
    damping_ratio : float
        ξ_n of eq. (8), assumed known and equal for all modes (the paper gives no value).
    qd_modal : float
        Qd on the modal states per step (§4.1: Qd = 1e-4, one number for all twelve states of eq. 8).
        Position: on q_n in m² and on q̇_n in (m/s)², as printed. Acceleration: read in the units of
        the measurement, (m/s²)², i.e. qd_modal/ω̄_n⁴ on q_n and qd_modal/ω̄_n² on q̇_n (ω̄: prior),
        because 1e-4 m² on a tip displacement would be ω⁴·1e-4 ≈ 1000 (m/s²)² of acceleration at mode 4.
    qd_frequency : float
        Qd on each frequency random walk, (rad/s)² per step (§4.1: Qd = 1e-4).
    qd_frequency_rel : float or None
        The same random walk in units of the prior that scale with the record: the variance of
        Δω/ω_min accumulated over one period T = 2π/ω_min of the slowest prior mode, so that
        qd_frequency = qd_frequency_rel · ω_min² · Δt/T (a walk of fixed physical rate: ∝ Δt). A record
        time-scaled by a (Δt × a, ω / a) then gets the same filter in samples. Given, it sets
        ``qd_frequency`` (then left at its default; giving both is refused). None: ``qd_frequency``.
    rd : float
        Rd, variance of the measurement fed to the filter: m² (position) or (m/s²)² (acceleration)
        (§4.1: Rd = 1e-2).
    p0_frequency_var : list[float] or None
        Initial variance of the frequency states, (rad/s)², one per mode or one for all. None (default):
        derived from the prior, (0.27·ω̄_n)² for each prior frequency ω̄_n — §4.1's "uncertainty of
        approximately 30 %", fitted to its P = diag(0,…,0, 1, 20, 40, 200) for the Table 3 priors, which it
        gives as 1.05, 18.7, 49.3, 154. The paper's explicit list is in ``configs/method/akf.yaml``.
    prior_std_rad_s : float or list[float] or None
        The prior as a distribution (the face pem shares): the 1σ spread of the prior frequencies, rad/s.
        The frequency states' P0 *is* that spread: P0 = diag(prior_std_rad_s²). Give it or
        ``p0_frequency_var``, not both; None: ``p0_frequency_var``'s rule.
    p0_modal_scale : float
        The modal states start at zero with standard deviation ``p0_modal_scale`` × the largest
        magnitude of the measurement (× ω_prior for the rates; ÷ ω_prior² for acceleration): any mode could
        carry the whole signal. The paper's zeros (§4.1) presume the initial displacement known.
    estimate_bias : bool
        Estimate an accelerometer bias as a state (with the integration constants for position).
    max_variance_growth : float
        Divergence ("covariance blow-up") when the trace of P exceeds this multiple of its initial trace.
    """

    measurement: str = "position"
    damping_ratio: float = 0.005
    qd_modal: float = 1e-4
    qd_frequency: float = 1e-4
    qd_frequency_rel: float | None = None
    rd: float = 1e-2
    p0_frequency_var: list[float] | None = None
    prior_std_rad_s: Any = None          # P0 of the frequencies = prior_std_rad_s² (Any: a number or a list)
    p0_modal_scale: float = 1.0
    estimate_bias: bool = True
    max_variance_growth: float = 1e8


def identify(y, dt, prior, **options) -> Estimate:
    """Identify the modal frequencies with the augmented Kalman filter of §3.1.

    Parameters
    ----------
    y : array_like, shape (n,)
        Tip acceleration in m/s², sampled at t_k = kΔt.
    dt : float
        Sample interval Δt in s.
    prior : array_like, shape (m,)
        A-priori frequencies in rad/s (Table 3: 3.80, 16.00, 26.00, 46.00); the initial frequency states.
    **options
        Fields of :class:`Options`.

    Returns
    -------
    Estimate
        ``frequencies``: the frequency states after the last sample; ``std``: √ of their filter
        variances; ``history``: (n, m) frequency states after every sample (Fig. 3);
        ``converged=False`` with the reason when the filter diverges.
    """
    return identify_record(y, dt, prior, functools.partial(_settings, options=options))


def identify_batch(y, dt, priors, **options) -> list[Estimate]:
    """:func:`identify` on every row of ``y`` (R records × n samples), row r with ``priors[r]`` (or one
    prior for all): the same Estimates, computed with the R filters in lock-step
    (:mod:`methods.kalman._lockstep`, checked against this module's filterpy run)."""
    return identify_each(y, dt, priors, functools.partial(_settings, options=options))


def _settings(prior, dt, options: dict):
    """The checked filter settings for a prior (options checked by :func:`check_options`)."""
    return settings_from(check_options(prior, dt, **options), prior, "akf", dt=dt)


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods` (validated without a record, before any work)."""
    opts = make_options(Options, options, "akf")
    settings_from(opts, prior, "akf", dt=dt)
    return opts
