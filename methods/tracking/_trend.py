"""The trend stage of a sliding-window tracker: window estimates put at the window's centre, carried to the
present by a local-linear-trend Kalman filter per mode (``trend=True`` on every windowed tracker).

A window of W samples ending at sample e estimates (to first order, for a frequency linear in time) the
frequency at its centre, t_c = (e − (W − 1)/2)Δt, not at its end: stamped at its end it lags a drift of rate
ω̇ by (W − 1)Δt/2 · ω̇ (0.5 % of ω for W = 512, Δt = 0.02 s, ω̇/ω = 0.1 %/s). Here, per mode, the state
x = [ω, ω̇] at the window centres follows the local linear trend

    x(t + τ) = F(τ) x(t) + w,  F(τ) = [[1, τ], [0, 1]],  E wwᵀ = (ω₀ ``trend_rate_noise``)² [[τ³/3, τ²/2], [τ²/2, τ]]

(a white-noise acceleration of ω; filterpy's ``Q_discrete_white_noise``), measured by the window's estimate
z = ω(t_c) + v, E v² = (``trend_meas_rel`` · ω)². The estimate reported at the window's end is the filter's
state carried forward by half a window, ω(t_e) = ω + ω̇ (W − 1)Δt/2, and its std √(F P Fᵀ)₀₀: a linear drift
is followed with no lag once ω̇ is learnt.

**Gate and restart.** A window estimate whose normalised innovation ν²/S exceeds ``trend_gate`` (χ², one
degree of freedom) is not used; after ``trend_restart_after`` such windows in a row the mode is restarted at
the last window's estimate (the level's variance set to R, the rate kept): a step of the frequency is taken
as a new level in about W/2 + ``trend_restart_after``·H samples, and a single outlier (a window that
mislabels a mode) is ignored. A mode starts at its first window estimate the method calls determined
(``converged_per_mode``), rate 0 with std ``trend_rate0`` · ω per second; windows it does not determine are
skipped (the filter only predicts). Reported ``converged``: the mode is started and its last determined
window passed the gate.

Causal: the output at window j uses windows 0 … j only.
"""

from __future__ import annotations

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter

TREND_FIELDS = ("trend", "trend_rate_noise", "trend_meas_rel", "trend_gate", "trend_restart_after", "trend_rate0")
DEFAULTS = {"trend": False, "trend_rate_noise": 1e-4, "trend_meas_rel": 0.005, "trend_gate": 9.0,
            "trend_restart_after": 2, "trend_rate0": 0.002}


def check(opts, tracker: str) -> None:
    """``ValueError`` (one line, naming the option) for an impossible trend option of ``opts``."""
    if not isinstance(opts.trend, bool):
        raise ValueError(f"{tracker}: trend = {opts.trend!r} must be true or false")
    for name in ("trend_rate_noise", "trend_rate0"):
        value = getattr(opts, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{tracker}: {name} = {value!r} must be a finite number ≥ 0")
    for name in ("trend_meas_rel", "trend_gate"):
        value = getattr(opts, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (np.isfinite(value) and value > 0):
            raise ValueError(f"{tracker}: {name} = {value!r} must be a finite number > 0")
    n = opts.trend_restart_after
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"{tracker}: trend_restart_after = {n!r} must be an integer ≥ 1")


def smooth(t_end_s: np.ndarray, frequencies: np.ndarray, determined: np.ndarray, window_s: float, *,
           rate_noise: float, meas_rel: float, gate: float, restart_after: int, rate0: float,
           meas_std: np.ndarray | None = None):
    """Run the trend stage over a track's window estimates (module docstring).

    Parameters
    ----------
    t_end_s : (K,) the windows' last sample times; ``frequencies``, ``determined`` : (K, m) their estimates
    window_s : (W − 1)Δt, the span of a window.

    Returns
    -------
    (frequencies, std, converged, restarts): (K, m) at the windows' ends, and the restarts per mode.
    """
    t_end_s = np.asarray(t_end_s, dtype=float)
    K, m = frequencies.shape
    lead = window_s / 2.0
    t_c = t_end_s - lead
    ahead = np.array([[1.0, lead], [0.0, 1.0]])
    out = np.full((K, m), np.nan)
    std = np.full((K, m), np.nan)
    conv = np.zeros((K, m), dtype=bool)
    restarts = np.zeros(m, dtype=int)
    for i in range(m):
        kf = None
        t_last = w0 = 0.0
        misses = 0
        ok = False
        for j in range(K):
            z = frequencies[j, i]
            good = bool(determined[j, i]) and np.isfinite(z) and z > 0
            r_std = meas_rel * z
            if meas_std is not None and np.isfinite(meas_std[j, i]):
                r_std = float(np.hypot(meas_std[j, i], r_std))
            if kf is None:
                if not good:
                    continue
                kf = KalmanFilter(dim_x=2, dim_z=1)
                kf.H = np.array([[1.0, 0.0]])
                kf.x = np.array([z, 0.0])
                kf.P = np.diag([r_std ** 2, (rate0 * z) ** 2])
                t_last, w0, ok = t_c[j], z, True
            else:
                tau = t_c[j] - t_last
                t_last = t_c[j]
                kf.F = np.array([[1.0, tau], [0.0, 1.0]])
                kf.Q = Q_discrete_white_noise(dim=2, dt=tau, var=(rate_noise * w0) ** 2)
                kf.predict()
                if good:
                    kf.R = np.array([[r_std ** 2]])
                    nu = z - kf.x[0]
                    if nu * nu / (kf.P[0, 0] + kf.R[0, 0]) <= gate:
                        kf.update(np.array([z]))
                        misses, ok = 0, True
                    else:
                        misses += 1
                        ok = False
                        if misses >= restart_after:
                            kf.x = np.array([z, kf.x[1]])
                            kf.P = np.diag([kf.R[0, 0], kf.P[1, 1]])
                            misses, ok = 0, True
                            restarts[i] += 1
            x = ahead @ kf.x
            P = ahead @ kf.P @ ahead.T
            out[j, i] = x[0]
            std[j, i] = np.sqrt(max(P[0, 0], 0.0))
            conv[j, i] = ok
    return out, std, conv, restarts


def apply(opts, t_end_s: np.ndarray, frequencies: np.ndarray, std, determined: np.ndarray, window_s: float,
          extra: dict, meas_std: np.ndarray | None = None):
    """The trend stage as a windowed tracker runs it when ``opts.trend``: the raw window estimates kept in
    ``extra`` ("window_frequencies", "window_converged", and the restarts per mode), then :func:`smooth` with
    the ``trend_*`` options. Returns (frequencies, std, determined, restarts); ``opts.trend`` false: the
    window estimates unchanged, std NaN, restarts None."""
    if not opts.trend:
        return frequencies, np.nan, determined, None
    extra |= {"window_frequencies": frequencies, "window_converged": determined}
    freq, std, found, restarts = smooth(
        t_end_s, frequencies, determined, window_s, rate_noise=opts.trend_rate_noise,
        meas_rel=opts.trend_meas_rel, gate=opts.trend_gate, restart_after=opts.trend_restart_after,
        rate0=opts.trend_rate0, meas_std=meas_std)
    extra["trend_restarts"] = restarts
    return freq, std, found, restarts
