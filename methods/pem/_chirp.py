"""The small-amplitude frequency of a drifting mode from one fit of the whole record: the backbone chirp.

A mode whose frequency depends on its amplitude (a Duffing spring: ω(A) ≈ ω₀(1 + δA²) for small shifts)
and whose envelope decays as e^{−σt} has the instantaneous frequency ω₀ + κe^{−2σt}, κ the shift at the
record's start. Its phase is then ω_d t + κ g(t), g(t) = (1 − e^{−2σt})/(2σ) (t for σ = 0), so

    ŷ(t) = Σᵢ e^{−σᵢt} [Aᵢ cos(ω_dᵢ t + κᵢ gᵢ(t)) + Bᵢ sin(ω_dᵢ t + κᵢ gᵢ(t))] + b,

with σ = ζω, ω_d = ω√(1 − ζ²) and ω the frequency as the amplitude goes to zero: the same number whatever
window of the record is fitted. The amplitudes (A, B, b) enter linearly and are projected out (variable
projection); (ω, ζ, κ) per mode are found by ``scipy.optimize.least_squares`` (trust-region reflective, the
projected residual's analytic Jacobian, :func:`_projected`) from the constant-frequency fit (κ = 0), within
bounds (ω within ×1.5^±1 of that fit's, ζ in ±0.8, |κ| ≤ 0.2ω; a mode that ends on a bound is not determined:
NaN). Unlike the segments' line (:mod:`methods.pem._drift`), the fit sees the whole window at once: a close pair
whose beat period is as long as a segment is resolved. The std is the robust one
(:func:`methods.pem._residual.sandwich_std` and :func:`~methods.pem._residual.spectral_sandwich_std`, the
larger) on the Jacobian of the projected residual. For a mode whose envelope hardly decays over the window, κ
and ω are nearly the same direction (g(t) ≈ t) and ω's std is large: the record does not tell the frequency at
another amplitude.
"""

from __future__ import annotations

import numpy as np
import scipy.optimize

from methods.pem import _residual

MAX_SHIFT = 0.2          # |κ| ≤ 0.2ω: a frequency shift at the record's start of at most 20 %


def _columns(theta: np.ndarray, dt: float, n: int):
    """The modal columns and what their derivatives need: t, g(t), ∂g/∂σ, e^{−σt}, the phase (rows: modes).

    g = (1 − e^{−2σt})/(2σ) and ∂g/∂σ = (t e^{−2σt} − g)/σ; where 2σt stays below 10⁻⁴ over the record their
    series, g = t − σt² + ⅔σ²t³ and ∂g/∂σ = −t² + (4/3)σt³, which the closed forms lose to cancellation."""
    m = theta.size // 3
    w, z, k = theta[:m], theta[m:2 * m], theta[2 * m:]
    t = dt * np.arange(n)
    s = (z * w)[:, None]
    wd = w * np.sqrt(np.clip(1.0 - z * z, 0.0, None))
    small = np.abs(2.0 * s * t[-1]) < 1e-4
    safe = np.where(small, 1.0, s)
    e2 = np.exp(-2.0 * safe * t)
    g = np.where(small, t - s * t**2 + (2.0 / 3.0) * s**2 * t**3, -np.expm1(-2.0 * safe * t) / (2.0 * safe))
    dg = np.where(small, -t**2 + (4.0 / 3.0) * s * t**3, (t * e2 - g) / safe)
    phase = wd[:, None] * t + k[:, None] * g
    env = np.exp(-s * t)
    return t, g, dg, env * np.cos(phase), env * np.sin(phase)


def basis(theta: np.ndarray, dt: float, n: int) -> np.ndarray:
    """Φ (n × 2m + 1): e^{−σᵢt} cos/sin(ω_dᵢt + κᵢgᵢ(t)) per mode, then 1; θ = (ω, ζ, κ), m each."""
    m = theta.size // 3
    _, _, _, c, s = _columns(theta, dt, n)
    phi = np.empty((n, 2 * m + 1))
    phi[:, 0:2 * m:2] = c.T
    phi[:, 1:2 * m:2] = s.T
    phi[:, 2 * m] = 1.0
    return phi


def _projected(theta, y, dt):
    """The variable-projection residual r = y − ΦΦ⁺y and its Jacobian (Golub & Pereyra 1973, the full form):

        ∂r/∂θⱼ = −(I − ΦΦ⁺)(∂Φ/∂θⱼ)c − Φ⁺ᵀ(∂Φ/∂θⱼ)ᵀr,    c = Φ⁺y,

    with Φ = QR (its thin QR), Φ⁺ = R⁻¹Qᵀ. θⱼ moves the two columns of its mode only: with σ = ζω,
    ω_d = ω√(1 − ζ²) and the phase φ = ω_d t + κg(t), ∂(cos, sin)/∂φ = (−sin, cos), ∂φ/∂ω_d = t, ∂φ/∂κ = g,
    ∂φ/∂σ = κ ∂g/∂σ, and the envelope adds −t per unit of σ; the chain to (ω, ζ) is ∂σ/∂ω = ζ, ∂σ/∂ζ = ω,
    ∂ω_d/∂ω = √(1 − ζ²), ∂ω_d/∂ζ = −ωζ/√(1 − ζ²). Written by hand: least_squares' finite differences
    solved one least-squares problem per unknown and step (13 for 4 modes), most of the drift test's cost."""
    n = y.size
    m = theta.size // 3
    w, z, k = theta[:m], theta[m:2 * m], theta[2 * m:]
    t, g, dg, cos_, sin_ = _columns(theta, dt, n)
    phi = np.empty((n, 2 * m + 1))
    phi[:, 0:2 * m:2], phi[:, 1:2 * m:2], phi[:, 2 * m] = cos_.T, sin_.T, 1.0
    q, rr = np.linalg.qr(phi)
    c = np.linalg.solve(rr, q.T @ y)            # R is (2m + 1)²: a general solve is as cheap here
    r = y - phi @ c
    a, b = c[0:2 * m:2, None], c[1:2 * m:2, None]
    # per mode, the derivative of its column pair along σ, ω_d and κ: (∂cos, ∂sin)
    d_cos = {"s": -t * cos_ - sin_ * k[:, None] * dg, "wd": -sin_ * t, "k": -sin_ * g}
    d_sin = {"s": -t * sin_ + cos_ * k[:, None] * dg, "wd": cos_ * t, "k": cos_ * g}
    root = np.sqrt(np.clip(1.0 - z * z, 1e-12, None))[:, None]
    chain = {"w": (("s", z[:, None]), ("wd", root)), "z": (("s", w[:, None]), ("wd", -w[:, None] * z[:, None] / root)),
             "k": (("k", 1.0),)}
    dphi_c, e = np.empty((n, 3 * m)), np.zeros((2 * m + 1, 3 * m))
    for block, name in enumerate(("w", "z", "k")):
        dc = sum(f * d_cos[key] for key, f in chain[name])              # (m, n): ∂cos/∂θ of each mode
        ds = sum(f * d_sin[key] for key, f in chain[name])
        cols = block * m + np.arange(m)
        dphi_c[:, cols] = (a * dc + b * ds).T                           # (∂Φ/∂θⱼ)c
        e[2 * np.arange(m), cols] = dc @ r                              # (∂Φ/∂θⱼ)ᵀr
        e[2 * np.arange(m) + 1, cols] = ds @ r
    jac = -(dphi_c - q @ (q.T @ dphi_c)) - q @ np.linalg.solve(rr.T, e)
    return r, jac


def fit(y, dt: float, w: np.ndarray, z: np.ndarray) -> dict:
    """The backbone-chirp fit of ``y`` from the constant-frequency one (ω, ζ per mode, κ = 0).

    Returns
    -------
    dict
        ``frequencies`` ω (rad/s, the small-amplitude ones), ``std`` (robust), ``kappa`` κ (rad/s, the shift
        at the record's start), ``kappa_std``, ``damping`` ζ, ``success``, ``record_average`` ω + k̄κ (the
        frequency a constant-frequency fit of this mode alone would return, :func:`record_weight`) and its
        ``record_average_std``; NaN where the fit failed.
    """
    y = np.asarray(y, float)
    w, z = np.asarray(w, float), np.asarray(z, float)
    m = w.size
    nan = np.full(m, np.nan)
    out = {"frequencies": nan, "std": nan, "kappa": nan, "kappa_std": nan, "damping": nan, "success": False,
           "record_average": nan, "record_average_std": nan}
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
    last = {}

    def evaluate(theta):            # least_squares asks for r and J at the same θ in turn: one QR for both
        if "theta" not in last or not np.array_equal(last["theta"], theta):
            last["theta"], (last["r"], last["jac"]) = theta.copy(), _projected(theta, y, dt)
        return last

    try:
        res = scipy.optimize.least_squares(lambda th: evaluate(th)["r"], theta0, jac=lambda th: evaluate(th)["jac"],
                                           bounds=(lo, hi), method="trf", x_scale=scale, max_nfev=200 * (3 * m + 1))
    except (ValueError, np.linalg.LinAlgError):
        return out
    e = res.fun
    p = 3 * m + 2 * m + 1
    std = _robust_std(res.jac, e, p)
    # the record average ω̄ = ω + k̄κ (:func:`record_weight`) is a linear function of θ: its std is the
    # sandwich's of the first column after the change of unknowns (ω, ζ, κ) → (ω̄, ζ, κ), whose Jacobian is
    # (J_ω, J_ζ, J_κ − k̄J_ω) (the sandwich is covariant under a linear change of unknowns)
    kbar = record_weight(res.x[:m] * res.x[m:2 * m], y.size, dt)
    # ζ may go negative within its bounds: a mode whose fitted envelope grows over the record has k̄ > 1, and
    # one that grows by more than e^14 (k̄ ≥ 1e6, or no finite k̄ at all) is no free decay — no record
    # average for it, and its column must not poison the sandwich of the others (an overflowing Jacobian
    # stops the Gram's eigendecomposition: a stationary forced record fitted with the Kalman predictor)
    finite = np.isfinite(kbar) & (np.abs(kbar) < MAX_RECORD_WEIGHT)
    kbar = np.where(finite, kbar, 0.0)
    std_bar = _robust_std(np.hstack([res.jac[:, :2 * m], res.jac[:, 2 * m:] - kbar * res.jac[:, :m]]), e, p)
    free = (res.active_mask[:m] == 0) & (res.active_mask[2 * m:] == 0)
    return {"frequencies": np.where(free, res.x[:m], np.nan), "std": np.where(free, std[:m], np.nan),
            "kappa": np.where(free, res.x[2 * m:], np.nan), "kappa_std": np.where(free, std[2 * m:], np.nan),
            "damping": np.where(free, res.x[m:2 * m], np.nan), "success": bool(res.success),
            "record_average": np.where(free & finite, res.x[:m] + kbar * res.x[2 * m:], np.nan),
            "record_average_std": np.where(free & finite, std_bar[:m], np.nan)}


MAX_RECORD_WEIGHT = 1e6     # k̄ beyond which a fitted envelope grew too much to be a free decay (:func:`fit`)


def _robust_std(jac, e, p):
    """The larger of the Newey–West and spectral sandwich stds (:mod:`methods.pem._residual`)."""
    return np.fmax(_residual.sandwich_std(jac, e, p)[0], _residual.spectral_sandwich_std(jac, e, p))


def record_weight(sigma, n: int, dt: float) -> np.ndarray:
    """k̄ per mode: the frequency a constant-frequency fit of n samples of the backbone chirp
    ω(t) = ω₀ + κe^{−2σt} returns is ω₀ + k̄κ. Such a fit weighs the phase error by the envelope²,
    w = e^{−2σt}, so its frequency is the w-weighted regression slope of the phase ∫ω on t; by parts

        k̄ = Σ w(t)K(t) / Σ K(t),   K(t) = Σ_{s ≥ t} w(s)(s − t̄),

    t̄ the w-weighted mean time (:func:`methods.pem._drift.chirp_segment_frequencies`, one segment)."""
    t = dt * np.arange(int(n))
    with np.errstate(over="ignore", invalid="ignore"):
        w = np.exp(-2.0 * np.outer(np.asarray(sigma, float), t))
        tbar = (w @ t) / w.sum(axis=1)
        kern = np.cumsum((w * (t - tbar[:, None]))[:, ::-1], axis=1)[:, ::-1]
        return np.sum(kern * w, axis=1) / kern.sum(axis=1)
