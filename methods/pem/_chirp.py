"""The small-amplitude frequency of a drifting mode from one fit of the whole record: the backbone chirp.

A mode whose frequency depends on its amplitude (a Duffing spring: ω(A) ≈ ω₀(1 + δA²) for small shifts)
and whose envelope decays as e^{−σt} has the instantaneous frequency ω₀ + κe^{−2σt}, κ the shift at the
record's start. Its phase is then ω_d t + κ g(t), g(t) = (1 − e^{−2σt})/(2σ) (t for σ = 0), so

    ŷ(t) = Σᵢ e^{−σᵢt} [Aᵢ cos(ω_dᵢ t + κᵢ gᵢ(t)) + Bᵢ sin(ω_dᵢ t + κᵢ gᵢ(t))] + b,

with σ = ζω, ω_d = ω√(1 − ζ²) and ω the frequency as the amplitude goes to zero: the same number whatever
window of the record is fitted. The amplitudes (A, B, b) enter linearly and are projected out (variable
projection); (ω, ζ, κ) per mode are found by ``scipy.optimize.least_squares`` (trust-region reflective,
finite-difference Jacobian) from the constant-frequency fit (κ = 0), within bounds (ω within ×1.5^±1 of
that fit's, ζ in ±0.8, |κ| ≤ 0.2ω; a mode that ends on a bound is not determined: NaN). Unlike the segments' line
(:mod:`methods.pem._drift`), the fit sees the whole window at once: a close pair whose beat period is as
long as a segment is resolved. The std is the robust one (:func:`methods.pem._residual.sandwich_std` and
:func:`~methods.pem._residual.spectral_sandwich_std`, the larger) on the Jacobian of the projected residual.
For a mode whose envelope hardly decays over the window, κ and ω are nearly the same direction (g(t) ≈ t)
and ω's std is large: the record does not tell the frequency at another amplitude.
"""

from __future__ import annotations

import numpy as np
import scipy.optimize

from methods.pem import _residual

MAX_SHIFT = 0.2          # |κ| ≤ 0.2ω: a frequency shift at the record's start of at most 20 %


def basis(theta: np.ndarray, dt: float, n: int) -> np.ndarray:
    """Φ (n × 2m + 1): e^{−σᵢt} cos/sin(ω_dᵢt + κᵢgᵢ(t)) per mode, then 1; θ = (ω, ζ, κ), m each."""
    m = theta.size // 3
    w, z, k = theta[:m], theta[m:2 * m], theta[2 * m:]
    t = dt * np.arange(n)
    s = z * w
    wd = w * np.sqrt(np.clip(1.0 - z * z, 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where(np.abs(s[:, None]) > 1e-12, -np.expm1(-2.0 * s[:, None] * t) / (2.0 * s[:, None]), t)
    phase = wd[:, None] * t + k[:, None] * g
    env = np.exp(-s[:, None] * t)
    phi = np.empty((n, 2 * m + 1))
    phi[:, 0:2 * m:2] = (env * np.cos(phase)).T
    phi[:, 1:2 * m:2] = (env * np.sin(phase)).T
    phi[:, 2 * m] = 1.0
    return phi


def _residual_of(theta, y, dt):
    phi = basis(theta, dt, y.size)
    c = np.linalg.lstsq(phi, y, rcond=None)[0]
    return y - phi @ c


def fit(y, dt: float, w: np.ndarray, z: np.ndarray) -> dict:
    """The backbone-chirp fit of ``y`` from the constant-frequency one (ω, ζ per mode, κ = 0).

    Returns
    -------
    dict
        ``frequencies`` ω (rad/s, the small-amplitude ones), ``std`` (robust), ``kappa`` κ (rad/s, the shift
        at the record's start), ``kappa_std``, ``success``; NaN where the fit failed.
    """
    y = np.asarray(y, float)
    w, z = np.asarray(w, float), np.asarray(z, float)
    m = w.size
    nan = np.full(m, np.nan)
    out = {"frequencies": nan, "std": nan, "kappa": nan, "kappa_std": nan, "success": False}
    if not (np.isfinite(w).all() and np.isfinite(z).all()) or y.size < 3 * m + 2 * m + 2:
        return out
    if np.any(w <= 0):
        return out
    # bounds: ω within the record's ×1.5^±1, ζ as pem's, |κ| ≤ MAX_SHIFT·ω (a weak nonlinearity); a mode
    # whose ω or κ ends on a bound is not determined (a slow mode in heavy noise otherwise let ω → 0 and κ
    # carry its whole frequency: the phase of a mode that hardly decays is (ω + κ)t)
    lo = np.concatenate([w / 1.5, np.full(m, -0.8), -MAX_SHIFT * w])
    hi = np.concatenate([w * 1.5, np.full(m, 0.8), MAX_SHIFT * w])
    theta0 = np.clip(np.concatenate([w, z, np.zeros(m)]), lo, hi)
    scale = np.concatenate([np.maximum(1e-3 * w, 1e-6), np.full(m, 1e-3), np.maximum(1e-3 * w, 1e-6)])
    try:
        res = scipy.optimize.least_squares(_residual_of, theta0, args=(y, dt), bounds=(lo, hi), method="trf",
                                           x_scale=scale, diff_step=1e-7, max_nfev=200 * (3 * m + 1))
    except (ValueError, np.linalg.LinAlgError):
        return out
    e = res.fun
    p = 3 * m + 2 * m + 1
    hac = _residual.sandwich_std(res.jac, e, p)[0]
    spec = _residual.spectral_sandwich_std(res.jac, e, p)
    std = np.fmax(hac, spec)
    free = (res.active_mask[:m] == 0) & (res.active_mask[2 * m:] == 0)
    return {"frequencies": np.where(free, res.x[:m], np.nan), "std": np.where(free, std[:m], np.nan),
            "kappa": np.where(free, res.x[2 * m:], np.nan), "kappa_std": np.where(free, std[2 * m:], np.nan),
            "success": bool(res.success)}
