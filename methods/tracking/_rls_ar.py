"""``rls_ar``: recursive least squares on an autoregressive model of the record, modes from its poles.

Model (order p): y(k) = α₁ y(k−1) + … + α_p y(k−p) + e(k), i.e. A(z) y = e with
A(z) = 1 − α₁z⁻¹ − … − α_p z⁻ᵖ. For this model structure Ljung's recursive prediction-error method is exactly
recursive least squares (Ljung & Söderström, *Theory and Practice of Recursive Identification*, 1983, §3.4):
the prediction ŷ(k) = φ(k)ᵀθ is linear in θ and its gradient is the regressor φ(k) = [y(k−1), …, y(k−p)]ᵀ.
With exponential forgetting λ (memory ≈ 1/(1 − λ) samples), for k = p, p + 1, …:

    ε(k) = y(k) − φ(k)ᵀ θ(k−1)
    K(k) = P(k−1) φ(k) / (λ + φ(k)ᵀ P(k−1) φ(k))
    θ(k) = θ(k−1) + K(k) ε(k)
    P(k) = (P(k−1) − K(k) φ(k)ᵀ P(k−1)) / λ,            θ(p−1) = 0, P(p−1) = δ I

which is the minimiser of λ^(k−p+1) θᵀθ/δ + Σ_{j=p..k} λ^(k−j) (y(j) − φ(j)ᵀθ)² (the tests check it against
``numpy.linalg.lstsq`` on that weighted regression). Guard against wind-up: when the signal dies out, P/λ
grows without bound; the division by λ is skipped while tr P exceeds ten times its initial value.

The poles z of A (eigenvalues of its companion matrix, numpy.linalg.eigvals on all samples at once) become
s = log(z)/Δt; the physical ones (ω_d > 0, |s| below Nyquist, damping ratio in [min_damping, max_damping])
are assigned to the modes by ``scipy.optimize.linear_sum_assignment`` on |log ω − log ω_ref| + c|ζ|, ω_ref
the mode's previous estimate (the prior at the start), no farther than ``band``. The p − 2m spare poles take up
the noise and the colour of the excitation (the response to a force is ARMA, not AR).

Why by hand: the recursion is eight lines, and the poles and the per-sample P are needed; padasip's
``FilterRLS`` (the library that has RLS) holds no regularised start to compare with the batch solution and
returns no covariance.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pandas as pd
import scipy.optimize

from methods.estimate import make_options
from methods.tracking import _defaults
from methods.tracking._track import Track

# Wind-up guard: P/λ is skipped while tr P exceeds this multiple of its initial trace (p + q)·δ.
WINDUP_TRACE_FACTOR = 10.0


@dataclass
class Options:
    """Options of ``rls_ar``.

    Attributes
    ----------
    extra_order : int
        AR order p = 2m + extra_order (m modes); the spare poles absorb noise and excitation colour.
    ma_order : int or None
        q of the ARMA(p, q) model fitted by pseudo-linear regression; None: 2m (the response of m modes to a
        white force, seen by an accelerometer with white noise, is ARMA(2m, 2m)); 0: the plain AR model.
    forgetting : float or None
        λ in (0, 1]; memory ≈ 1/(1 − λ) samples. None: 1 − 1/W, a memory as long as the windowed trackers'
        default window W (:mod:`methods.tracking._defaults`; 0.998, 486 samples = 9.7 s on the tracking grid).
    p0 : float
        δ, the initial P = δ I (a weak regularisation of θ towards 0).
    band : float
        A pole may be assigned to a mode when |log(ω/ω_ref)| ≤ log(1 + band).
    damping_weight : float
        Assignment cost |log(ω/ω_ref)| + damping_weight·|ζ|: of two poles near a mode, the lightly damped one
        (a structural mode) wins over a broad one that fits noise.
    converged_max_damping : float
        A mode counts as converged only when its pole's |damping ratio| is at most this: a structural mode is
        lightly damped (ζ ≈ 0.005 here), a pole that only fits noise is mostly broad.
    converged_spread : float
        ... and when its log-frequency has varied by at most this standard deviation over the last memory
        length (1/(1 − λ) samples): a pole fitting noise wanders.
    min_damping, max_damping : float
        Accepted damping ratios of a physical pole.
    """

    extra_order: int = 16
    ma_order: int | None = None
    forgetting: float | None = None
    p0: float = 1e4
    band: float = 0.3
    damping_weight: float = 1.0
    converged_max_damping: float = 0.05
    converged_spread: float = 0.02
    min_damping: float = -0.05
    max_damping: float = 0.3


def check_options(name: str, prior, dt: float, options: dict, n_samples: int | None = None) -> Options:
    opts = make_options(Options, options, name)
    if opts.forgetting is not None and (isinstance(opts.forgetting, bool)
                                        or not isinstance(opts.forgetting, (int, float))):
        raise ValueError(f"{name}: forgetting = {opts.forgetting!r} must be a number in (0, 1]")
    if isinstance(opts.extra_order, bool) or not isinstance(opts.extra_order, int) or opts.extra_order < 0:
        raise ValueError(f"{name}: extra_order = {opts.extra_order!r} must be an integer ≥ 0")
    if opts.ma_order is not None and (isinstance(opts.ma_order, bool) or not isinstance(opts.ma_order, int)
                                      or opts.ma_order < 0):
        raise ValueError(f"{name}: ma_order = {opts.ma_order!r} must be an integer ≥ 0 (or None: 2m)")
    if opts.forgetting is not None and not 0 < opts.forgetting <= 1:
        raise ValueError(f"{name}: forgetting = {opts.forgetting} must be in (0, 1]")
    if not (np.isfinite(opts.p0) and opts.p0 > 0):
        raise ValueError(f"{name}: p0 = {opts.p0} must be a positive number")
    if not opts.band > 0:
        raise ValueError(f"{name}: band = {opts.band} must be positive")
    if not opts.converged_spread > 0:
        raise ValueError(f"{name}: converged_spread = {opts.converged_spread} must be positive")
    if not opts.converged_max_damping > 0:
        raise ValueError(f"{name}: converged_max_damping = {opts.converged_max_damping} must be positive")
    if not opts.min_damping < opts.max_damping:
        raise ValueError(f"{name}: min_damping = {opts.min_damping} must be below max_damping = {opts.max_damping}")
    order = 2 * np.size(prior) + opts.extra_order
    if n_samples is not None and n_samples <= order:
        raise ValueError(f"{name}: the record ({n_samples} samples) is not longer than the AR order {order}")
    return resolve(opts, prior, dt)


def rls(y: np.ndarray, order: int, forgetting: float, p0: float, ma_order: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """θ(k) of the AR(``order``) model after every sample k ≥ order − 1 (module docstring), and the
    prediction errors ε(k). Returns (theta (n, p + q), eps (n,)), rows before the first update: θ = 0,
    ε = NaN. ``ma_order`` q > 0: the pseudo-linear regression (extended least squares) of an ARMA(p, q)
    model, φ(k) extended by the past residuals y(j) − φ(j)ᵀθ(j), j = k − 1 … k − q (Ljung & Söderström §3.7);
    only the first p entries of θ (the AR part) give the poles."""
    n, p = y.size, order
    npar = p + ma_order
    theta = np.zeros(npar)
    P = p0 * np.eye(npar)
    trace_max = WINDUP_TRACE_FACTOR * npar * p0
    out = np.zeros((n, npar))
    eps = np.full(n, np.nan)
    resid = np.zeros(n)
    for k in range(p, n):
        past = y[k - 1::-1][:p] if k - 1 - p < 0 else y[k - 1:k - 1 - p:-1]
        phi = np.concatenate((past, resid[k - 1::-1][:ma_order])) if ma_order else past
        if phi.size < npar:
            phi = np.concatenate((phi, np.zeros(npar - phi.size)))
        Pphi = P @ phi
        gain = Pphi / (forgetting + phi @ Pphi)
        e = y[k] - phi @ theta
        theta = theta + gain * e
        P = P - np.outer(gain, Pphi)
        P = 0.5 * (P + P.T)                   # keep P symmetric: round-off otherwise grows with 1/λ
        if forgetting < 1.0 and np.trace(P) < trace_max:
            P /= forgetting
        out[k] = theta
        eps[k] = e
        if ma_order:
            resid[k] = y[k] - phi @ theta
    return out, eps


def ar_poles(theta: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """Roots of z^p − α₁z^(p−1) − … − α_p for every row of ``theta`` (n × p): eigenvalues of the companion
    matrices, (n, p) complex."""
    n, p = theta.shape
    roots = np.empty((n, p), dtype=complex)
    for a in range(0, n, chunk):
        th = theta[a:a + chunk]
        comp = np.zeros((th.shape[0], p, p))
        comp[:, 0, :] = th
        comp[:, np.arange(1, p), np.arange(p - 1)] = 1.0
        roots[a:a + chunk] = np.linalg.eigvals(comp)
    return roots


def resolve(opts: Options, prior, dt: float) -> Options:
    """``opts`` with ``forgetting`` set: the user's, or 1 − 1/W for the default window W."""
    if opts.forgetting is not None:
        return opts
    W = max(int(round(_defaults.window_s(prior) / dt)), _defaults.min_window_samples(np.size(prior)))
    return dataclasses.replace(opts, forgetting=_defaults.forgetting(W))


def run(name: str, y: np.ndarray, dt: float, prior: np.ndarray, options: dict) -> Track:
    opts = resolve(make_options(Options, options, name), prior, dt)
    m = prior.size
    order = 2 * m + opts.extra_order
    q = 2 * m if opts.ma_order is None else opts.ma_order
    theta, eps = rls(y, order, opts.forgetting, opts.p0, q)
    k = np.arange(order, y.size)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.log(ar_poles(theta[k, :order])) / dt
        w = np.abs(s)
        zeta = -s.real / w                    # θ = 0 (a zero record): poles at z = 0, s = −∞, no mode
    ok = (s.imag > 0) & (w < np.pi / dt) & (zeta >= opts.min_damping) & (zeta <= opts.max_damping)
    freq, damping, found = _assign(w, np.where(ok, zeta, np.inf), ok, prior, np.log1p(opts.band),
                                   opts.damping_weight)
    memory = order if opts.forgetting == 1.0 else min(order + int(round(1.0 / (1.0 - opts.forgetting))), y.size)
    conv = found & (k >= memory)[:, None] & (np.abs(damping) <= opts.converged_max_damping)
    conv &= _steady(freq, memory - order, opts.converged_spread)
    return Track(k * dt, freq, np.nan, conv,
                 message=f"RLS on ARMA({order}, {q}), λ = {opts.forgetting}: every mode found in "
                         f"{float(np.mean(found.all(axis=1))):.0%} of the samples",
                 extra={"order": order, "ma_order": q, "memory_samples": memory, "damping": damping})


def _steady(freq: np.ndarray, n_trail: int, spread: float) -> np.ndarray:
    """(K, m): the standard deviation of log ω over the trailing ``n_trail`` estimates is at most ``spread``
    (a pole that fits noise wanders; a mode's stays put within its drift). pandas' trailing rolling std."""
    n_trail = max(2, n_trail)
    sd = np.column_stack([pd.Series(np.log(freq[:, j])).rolling(n_trail, min_periods=n_trail).std().to_numpy()
                          for j in range(freq.shape[1])])
    return sd <= spread


def _assign(w: np.ndarray, zeta: np.ndarray, ok: np.ndarray, prior: np.ndarray, limit: float,
            damping_weight: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per sample, the physical poles matched to the modes' previous estimates (module docstring): cost
    |log ω − log ω_ref| + damping_weight·|ζ| within the band."""
    n, m = w.shape[0], prior.size
    freq = np.full((n, m), np.nan)
    damping = np.full((n, m), np.nan)
    found = np.zeros((n, m), dtype=bool)
    ref = np.log(prior)
    logw = np.log(np.where(ok, w, 1.0))
    for i in range(n):
        cand = logw[i, ok[i]]
        if cand.size == 0:
            continue
        dist = np.abs(cand[:, None] - ref[None, :])
        cost = np.where(dist <= limit, dist + damping_weight * np.abs(zeta[i, ok[i]])[:, None], 1e6)
        rows, cols = scipy.optimize.linear_sum_assignment(cost)
        hit = cost[rows, cols] < 1e6
        rows, cols = rows[hit], cols[hit]
        freq[i, cols] = np.exp(cand[rows])
        damping[i, cols] = zeta[i, ok[i]][rows]
        found[i, cols] = True
        ref = ref.copy()
        ref[cols] = cand[rows]
    return freq, damping, found
